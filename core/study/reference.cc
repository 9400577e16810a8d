#include "core/study/reference.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "core/study/replicates.h"

namespace totalgrad::study::internal {
namespace {

// The agreement test of the first two reference estimators (means and
// standard errors per coordinate): max |z| and mean z^2, the difference
// the test could detect, and the verdict, with notes in ref->note.
void CheckAgreement(const std::vector<Vector>& means, const std::vector<Vector>& ses,
                    const ReferenceOptions& ro, ReferenceGradient* out) {
  ReferenceGradient& ref = *out;
  double max_z = 0, sum_z2 = 0;
  int used = 0;
  for (Eigen::Index j = 0; j < means[0].size(); ++j) {
    const double denom = std::sqrt(ses[0](j) * ses[0](j) + ses[1](j) * ses[1](j));
    const double diff = means[0](j) - means[1](j);
    if (!(denom > 0)) {
      if (diff != 0) max_z = std::numeric_limits<double>::infinity();
      continue;
    }
    const double z = diff / denom;
    max_z = std::max(max_z, std::abs(z));
    sum_z2 += z * z;
    ++used;
  }
  ref.agreement_max_z = max_z;
  ref.agreement_mean_z2 = used > 0 ? sum_z2 / used : 0.0;
  if (ref.norm > 0) {
    ref.agreement_resolution =
        1.96 * (ses[0].cwiseAbs2() + ses[1].cwiseAbs2()).cwiseSqrt().norm() / ref.norm;
    if (ref.agreement_resolution > 1.0) {
      const double n0 = ses[0].norm(), n1 = ses[1].norm();
      const size_t precise = n0 <= n1 ? 0 : 1;
      absl::StrAppend(&ref.note, "the agreement check has no power: a difference of ",
                      absl::StrFormat("%.3g", ref.agreement_resolution), " |g*| between ",
                      ref.used[0], " and ", ref.used[1], " would pass (|SE| of ",
                      ref.used[1 - precise], " ",
                      absl::StrFormat("%.3g", precise == 0 ? n1 / std::max(n0, 1e-300)
                                                           : n0 / std::max(n1, 1e-300)),
                      " x ", ref.used[precise], "'s); g* rests on ", ref.used[precise], "; ");
    }
  }
  ref.agree = max_z <= ro.agreement_max_z && ref.agreement_mean_z2 <= ro.agreement_mean_z2;
  if (!ref.agree) {
    absl::StrAppend(&ref.note, ref.used[0], " and ", ref.used[1], " disagree (max |z| ",
                    absl::StrFormat("%.3g", max_z), ", mean z^2 ",
                    absl::StrFormat("%.3g", ref.agreement_mean_z2), ")");
  }
}

}  // namespace

ReferenceGradient ComputeReference(const estimators::Problem& problem, const StudyOptions& options,
                                   const StudyProgress& progress) {
  const ReferenceOptions& ro = options.reference;
  ReferenceGradient ref;
  ref.horizon = problem.horizon;
  const Clock::time_point start = Clock::now();
  std::vector<Vector> means, ses;
  double objective_sum = 0;
  int objective_count = 0;
  for (size_t k = 0; k < ro.estimators.size(); ++k) {
    const EstimatorSpec& spec = ro.estimators[k];
    absl::StatusOr<std::unique_ptr<estimators::Estimator>> estimator =
        estimators::MakeEstimator(spec.method, spec.options);
    if (!estimator.ok()) {  // Validate() rules this out; keep it visible anyway
      absl::StrAppend(&ref.note, spec.label, ": ", estimator.status().message(), "; ");
      continue;
    }
    const Replicates reps = RunReplicates(estimator->get(), problem, ro.particles, ro.replicates,
                                          ro.budget_seconds, options.seed, 1 + k);
    if (progress) {
      progress(absl::StrFormat("reference H=%d: %s %d x P=%d (%d non-finite, %d errors)",
                               problem.horizon, spec.label, static_cast<int>(reps.estimates.size()),
                               ro.particles, reps.nonfinite, reps.errors));
    }
    if (reps.estimates.size() < 2) {
      absl::StrAppend(&ref.note, spec.label, " left out (", reps.estimates.size(),
                      " finite estimates, ", reps.nonfinite, " non-finite, ", reps.errors,
                      " errors", reps.first_error.empty() ? "" : ": ", reps.first_error, "); ");
      continue;
    }
    if (reps.budget_hit) {
      absl::StrAppend(&ref.note, spec.label, " cut to ", reps.estimates.size(),
                      " replicates by the time budget; ");
    }
    Vector mean, se;
    MeanAndStandardError(reps.estimates, &mean, &se);
    means.push_back(mean);
    ses.push_back(se);
    ref.used.push_back(spec.label);
    ref.replicates.push_back(static_cast<int>(reps.estimates.size()));
    for (double j : reps.objectives) objective_sum += j;
    objective_count += static_cast<int>(reps.objectives.size());
  }
  ref.seconds = SecondsSince(start);
  if (means.empty()) {
    ref.agree = false;
    absl::StrAppend(&ref.note, "no reference estimator produced finite estimates");
    return ref;
  }
  PoolMeans(means, ses, &ref.gradient, &ref.standard_error);
  ref.norm = ref.gradient.norm();
  ref.objective = objective_sum / objective_count;
  if (ref.norm > 0) {
    ref.relative_error = ref.standard_error.norm() / ref.norm;
    ref.floor = 1.96 * ref.relative_error;
  } else {
    absl::StrAppend(&ref.note, "the reference gradient is exactly zero (saturated cost?); ");
  }
  if (means.size() < 2) {
    ref.agree = false;
    absl::StrAppend(&ref.note, "only one reference estimator: agreement not tested");
    return ref;
  }
  CheckAgreement(means, ses, ro, &ref);
  return ref;
}

}  // namespace totalgrad::study::internal
