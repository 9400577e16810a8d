#include "worker/study_runner.h"

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "io/study_file.h"
#include "core/common/blas.h"
#include "core/study/study.h"

namespace totalgrad::worker {

absl::StatusOr<StudyOutcome> CoreStudyRunner::Run(const std::string& spec_json,
                                                  TrialProgress* progress) {
  const nlohmann::json doc = nlohmann::json::parse(spec_json, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded() || !doc.is_object()) {
    return absl::InvalidArgumentError("study job: the spec is not a JSON object");
  }
  absl::StatusOr<io::StudySpec> spec = io::ParseStudySpec(doc, /*base_dir=*/"");
  if (!spec.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("study job: ", spec.status().message()));
  }
  if (!spec->snapshot_file.empty()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "study job: problem.snapshot names a file ('", spec->snapshot_file,
        "'); a study job carries its snapshot inline"));
  }
  absl::StatusOr<std::unique_ptr<study::FrozenProblem>> problem = io::LoadStudyProblem(*spec);
  if (!problem.ok()) {
    return absl::Status(problem.status().code(),
                        absl::StrCat("study job: ", problem.status().message()));
  }
  SetBlasThreads(1);  // timings are of single-threaded runs, as in `totalgrad study`
  absl::StatusOr<study::StudyResult> result = study::RunStudy(
      **problem, spec->options, /*progress=*/nullptr,
      [progress] { return progress != nullptr && progress->ShouldCancel(); });
  if (!result.ok()) return result.status();

  StudyOutcome outcome;
  for (size_t i = 0; i < result->references.size(); ++i) {
    const study::ReferenceGradient& ref = result->references[i];
    v1::StudyReferenceRow row;
    row.set_index(static_cast<int>(i));
    row.set_horizon(ref.horizon);
    row.set_norm(ref.norm);
    row.set_relative_error(ref.relative_error);
    row.set_floor(ref.floor);
    row.set_objective(ref.objective);
    for (const auto& label : ref.used) row.add_used(label);
    for (int n : ref.replicates) row.add_replicates(n);
    row.set_agreement_max_z(ref.agreement_max_z);
    row.set_agreement_mean_z2(ref.agreement_mean_z2);
    row.set_agree(ref.agree);
    row.set_seconds(ref.seconds);
    row.set_note(ref.note);
    for (Eigen::Index k = 0; k < ref.gradient.size(); ++k) row.add_gradient(ref.gradient(k));
    for (Eigen::Index k = 0; k < ref.standard_error.size(); ++k) {
      row.add_standard_error(ref.standard_error(k));
    }
    outcome.references.push_back(std::move(row));
  }
  for (size_t i = 0; i < result->cells.size(); ++i) {
    const study::CellResult& c = result->cells[i];
    v1::StudyCellRow row;
    row.set_index(static_cast<int>(i));
    row.set_estimator(c.estimator);
    row.set_method(c.method);
    row.set_particles(c.particles);
    row.set_horizon(c.horizon);
    row.set_replicates(c.replicates);
    row.set_nonfinite(c.nonfinite);
    row.set_errors(c.errors);
    row.set_time_min_s(c.time_min_s);
    row.set_time_median_s(c.time_median_s);
    row.set_rel_rmse(c.rel_rmse);
    row.set_rel_bias(c.rel_bias);
    row.set_rel_bias_noise(c.rel_bias_noise);
    row.set_total_variance(c.total_variance);
    row.set_cos_mean(c.cos_mean);
    row.set_objective_mean(c.objective_mean);
    row.set_ess_mean(c.ess_mean);
    row.set_ess_min(c.ess_min);
    row.set_k_lr_mean(c.k_lr_mean);
    row.set_reference_agrees(c.reference_agrees);
    double floor = study::CellResult::kNaN;
    for (const auto& ref : result->references) {
      if (ref.horizon == c.horizon) floor = ref.floor;
    }
    row.set_reference_floor(floor);
    row.set_budget_hit(c.budget_hit);
    row.set_omitted(c.omitted);
    row.set_note(io::StudyCellNote(c));
    row.set_error(c.error);
    row.set_omission_reason(c.omission_reason);
    for (double v : c.k_lr_per_step) row.add_k_lr_per_step(v);
    outcome.cells.push_back(std::move(row));
  }
  return outcome;
}

}  // namespace totalgrad::worker
