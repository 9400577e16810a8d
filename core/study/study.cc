// The gradient study (study.h): options, the error metrics and ESS, the
// cells of each estimator and RunStudy. Replicates of one cell are in
// replicates.cc, the reference gradient in reference.cc.
#include "core/study/study.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <set>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "core/common/rng.h"
#include "core/estimators/likelihood_ratio.h"
#include "core/estimators/total_propagation.h"
#include "core/pilco/gp_moments.h"
#include "core/pilco/pilco.h"
#include "core/study/pilco_problem.h"
#include "core/study/reference.h"
#include "core/study/replicates.h"

namespace totalgrad::study {
namespace {

using internal::Clock;
using internal::Median;
using internal::Replicates;
using internal::RunReplicates;
using internal::SecondsSince;
using internal::StreamIndex;

// The batch-importance-weighted LR part of a particle method, if it has one:
// returns the noise factor its forward pass uses.
bool UsesBiwWeights(const estimators::Estimator& estimator, double* noise_factor) {
  const auto* particle = dynamic_cast<const estimators::ParticleEstimator*>(&estimator);
  if (particle == nullptr) return false;
  const estimators::MethodRecipe& recipe = particle->recipe();
  if (recipe.backward.jump != estimators::JumpKind::kLikelihoodRatio ||
      recipe.backward.lr_weights != estimators::LrWeights::kBatchImportance) {
    return false;
  }
  *noise_factor = recipe.noise_variance_factor;
  return true;
}

// ESS of the BIW weights on the particles of the first `passes` replicates.
void BiwEss(const estimators::Problem& problem, double noise_factor, int particles, int passes,
            uint64_t seed, double* mean, double* min) {
  estimators::Problem local = problem;
  local.noise_variance_multiplier *= noise_factor;
  std::vector<double> per_step(problem.horizon, 0.0);
  int used = 0;
  estimators::Rollout rollout;
  for (int r = 0; r < passes; ++r) {
    Rng rng(seed, Stream::kStudy, StreamIndex(0, problem.horizon, particles, r));
    if (!estimators::SimulateParticles(local, particles, estimators::RolloutRecording{}, &rng,
                                       &rollout)
             .ok() ||
        !rollout.finite) {
      continue;
    }
    for (int t = 0; t < problem.horizon; ++t) per_step[t] += MeanBiwEss(rollout.steps[t]);
    ++used;
  }
  if (used == 0) return;
  double sum = 0, lowest = 1.0;
  for (double& v : per_step) {
    v /= used;
    sum += v;
    lowest = std::min(lowest, v);
  }
  *mean = sum / problem.horizon;
  *min = lowest;
}

void FillErrorMetrics(const std::vector<Vector>& estimates, const ReferenceGradient& reference,
                      CellResult* cell) {
  if (estimates.empty() || reference.gradient.size() == 0 || !(reference.norm > 0)) return;
  const ErrorMetrics m = ComputeErrorMetrics(estimates, reference.gradient);
  cell->rel_rmse = m.rel_rmse;
  cell->rel_bias = m.rel_bias;
  cell->rel_bias_noise = m.rel_bias_noise;
  cell->total_variance = m.total_variance;
  cell->cos_mean = m.cos_mean;
}

CellResult RunPilcoCell(const FrozenProblem& frozen, const pilco::GaussianInputGp& gp,
                        const estimators::Problem& problem, const StudyOptions& options,
                        const ReferenceGradient& reference) {
  CellResult cell;
  cell.method = estimators::MethodName(estimators::Method::kPilco);
  cell.particles = 0;
  cell.horizon = problem.horizon;
  cell.reference_agrees = reference.agree;
  // PILCO's problem on the model's and policy's features (the raw state, or
  // the angles as sin/cos), built as the trial builds it.
  std::string noise_note;
  absl::StatusOr<pilco::PilcoProblem> built = MakeStudyPilcoProblem(frozen, problem, &noise_note);
  if (!built.ok()) {
    cell.omitted = true;
    cell.omission_reason = absl::StrCat("no closed-form cost: ", built.status().message());
    return cell;
  }
  pilco::PilcoProblem& pp = *built;
  if (!noise_note.empty()) cell.error = noise_note;
  const Vector& theta = frozen.policy->parameters();
  std::vector<double> times;
  Vector gradient;
  const Clock::time_point cell_start = Clock::now();
  for (int r = 0; r < options.replicates; ++r) {
    if (r >= 2 && SecondsSince(cell_start) >= options.cell_budget_seconds) {
      cell.budget_hit = true;
      break;
    }
    Vector g;
    const Clock::time_point start = Clock::now();
    absl::StatusOr<pilco::Trajectory> tr = pilco::Propagate(gp, pp, theta, &g);
    times.push_back(SecondsSince(start));
    if (!tr.ok()) {
      ++cell.errors;
      cell.error = std::string(tr.status().message());
      cell.omitted = true;
      cell.omission_reason = absl::StrCat("PILCO failed: ", tr.status().message());
      return cell;
    }
    if (r == 0) {
      cell.objective_mean = tr->total_cost;
      gradient = g;
    }
  }
  cell.time_min_s = *std::min_element(times.begin(), times.end());
  cell.time_median_s = Median(times);
  if (!gradient.allFinite()) {
    cell.nonfinite = 1;
    cell.omitted = true;
    cell.omission_reason = "PILCO's gradient is not finite";
    return cell;
  }
  cell.replicates = 1;  // deterministic: one value, timed repeatedly
  FillErrorMetrics({gradient}, reference, &cell);
  cell.rel_bias_noise = 0;
  return cell;
}

// One cell of a particle estimator: R replicates at (particles, p.horizon)
// against the horizon's reference `ref`, with the BIW ESS when `biw`.
CellResult RunEstimatorCell(estimators::Estimator* estimator, const EstimatorSpec& spec,
                            bool biw, double noise_factor, int particles,
                            const estimators::Problem& p, const ReferenceGradient& ref,
                            const StudyOptions& options) {
  CellResult cell;
  cell.estimator = spec.label;
  cell.method = estimators::MethodName(spec.method);
  cell.particles = particles;
  cell.horizon = p.horizon;
  cell.reference_agrees = ref.agree;
  const Replicates reps = RunReplicates(estimator, p, particles, options.replicates,
                                        options.cell_budget_seconds, options.seed, 0);
  cell.replicates = static_cast<int>(reps.estimates.size());
  cell.nonfinite = reps.nonfinite;
  cell.errors = reps.errors;
  cell.error = reps.first_error;
  cell.budget_hit = reps.budget_hit;
  if (!reps.seconds.empty()) {
    cell.time_min_s = *std::min_element(reps.seconds.begin(), reps.seconds.end());
    cell.time_median_s = Median(reps.seconds);
  }
  if (reps.estimates.empty()) {
    cell.omitted = true;
    cell.omission_reason = reps.errors > 0 ? absl::StrCat("error: ", reps.first_error)
                                           : "every estimate was non-finite";
  } else {
    FillErrorMetrics(reps.estimates, ref, &cell);
    double j = 0;
    for (double v : reps.objectives) j += v;
    cell.objective_mean = j / static_cast<double>(reps.objectives.size());
    if (ref.gradient.size() == 0 || !(ref.norm > 0)) {
      cell.omission_reason = "no usable reference gradient at this horizon";
    }
  }
  if (reps.k_lr_count > 0) {
    cell.k_lr_per_step = reps.k_lr_sum;
    double sum = 0;
    for (double& v : cell.k_lr_per_step) {
      v /= reps.k_lr_count;
      sum += v;
    }
    cell.k_lr_mean = sum / static_cast<double>(cell.k_lr_per_step.size());
  }
  if (biw && options.ess_replicates > 0 && particles <= options.ess_max_particles) {
    BiwEss(p, noise_factor, particles, options.ess_replicates, options.seed, &cell.ess_mean,
           &cell.ess_min);
  }
  return cell;
}

}  // namespace

std::vector<EstimatorSpec> DefaultEstimators() {
  std::vector<EstimatorSpec> specs;
  for (const auto& [method, name] : estimators::MethodNames()) {
    specs.push_back({name, method, estimators::EstimatorOptions{}});
  }
  return specs;
}

std::vector<EstimatorSpec> DefaultReferenceEstimators() {
  estimators::EstimatorOptions plain_loo;
  plain_loo.lr_weights = estimators::LrWeights::kPlain;
  plain_loo.lr_baseline = estimators::LrBaseline::kLeaveOneOut;
  return {{"RP", estimators::Method::kRp, estimators::EstimatorOptions{}},
          {"LR(plain,loo)", estimators::Method::kLr, plain_loo}};
}

absl::Status StudyOptions::Validate() const {
  auto bad = [](const std::string& field, const std::string& why) {
    return absl::InvalidArgumentError(absl::StrCat("study option '", field, "' ", why));
  };
  if (estimators.empty()) return bad("estimators", "is empty");
  if (particles.empty()) return bad("particles", "is empty");
  if (horizons.empty()) return bad("horizons", "is empty");
  for (int p : particles) {
    if (p < 1 || p >= (1 << 24)) return bad("particles", absl::StrCat("has ", p, " (need 1 .. 2^24 - 1)"));
  }
  for (int h : horizons) {
    if (h < 1 || h >= (1 << 16)) return bad("horizons", absl::StrCat("has ", h, " (need 1 .. 65535)"));
  }
  if (replicates < 2 || replicates >= (1 << 20)) return bad("replicates", "must be in 2 .. 2^20 - 1");
  if (!(cell_budget_seconds > 0)) return bad("cell_budget_seconds", "must be > 0");
  if (ess_replicates < 0) return bad("ess_replicates", "must be >= 0");
  if (reference.estimators.empty()) return bad("reference.estimators", "is empty");
  if (reference.particles < 1 || reference.particles >= (1 << 24)) {
    return bad("reference.particles", "must be in 1 .. 2^24 - 1");
  }
  if (reference.replicates < 2 || reference.replicates >= (1 << 20)) {
    return bad("reference.replicates", "must be in 2 .. 2^20 - 1");
  }
  if (reference.estimators.size() > 14) return bad("reference.estimators", "has more than 14 entries");
  if (!(reference.budget_seconds > 0)) return bad("reference.budget_seconds", "must be > 0");
  std::set<std::string> labels;
  for (const EstimatorSpec& spec : estimators) {
    if (spec.label.empty()) return bad("estimators", "has an entry without a label");
    if (!labels.insert(spec.label).second) {
      return bad("estimators", absl::StrCat("has the label '", spec.label, "' twice"));
    }
    if (spec.method == estimators::Method::kPilco) {
      if (absl::Status st = spec.options.Validate(); !st.ok())
        return bad("estimators", absl::StrCat("'", spec.label, "': ", st.message()));
      continue;
    }
    absl::StatusOr<std::unique_ptr<estimators::Estimator>> e =
        estimators::MakeEstimator(spec.method, spec.options);
    if (!e.ok()) return bad("estimators", absl::StrCat("'", spec.label, "': ", e.status().message()));
  }
  for (const EstimatorSpec& spec : reference.estimators) {
    if (spec.method == estimators::Method::kPilco) {
      return bad("reference.estimators", "cannot use PILCO (another objective)");
    }
    absl::StatusOr<std::unique_ptr<estimators::Estimator>> e =
        estimators::MakeEstimator(spec.method, spec.options);
    if (!e.ok()) {
      return bad("reference.estimators", absl::StrCat("'", spec.label, "': ", e.status().message()));
    }
  }
  return absl::OkStatus();
}

ErrorMetrics ComputeErrorMetrics(const std::vector<Vector>& estimates, const Vector& reference) {
  ErrorMetrics m;
  const double r = static_cast<double>(estimates.size());
  const double ref_norm = reference.norm();
  Vector mean = Vector::Zero(reference.size());
  double mse = 0, cos_sum = 0;
  for (const Vector& g : estimates) {
    mean += g;
    mse += (g - reference).squaredNorm();
    const double gn = g.norm();
    cos_sum += gn > 0 ? g.dot(reference) / (gn * ref_norm) : 0.0;
  }
  mean /= r;
  double var = 0;
  for (const Vector& g : estimates) var += (g - mean).squaredNorm();
  m.total_variance = estimates.size() > 1 ? var / (r - 1) : 0.0;
  m.rel_rmse = std::sqrt(mse / r) / ref_norm;
  m.rel_bias = (mean - reference).norm() / ref_norm;
  m.rel_bias_noise = std::sqrt(m.total_variance / r) / ref_norm;
  m.cos_mean = cos_sum / r;
  return m;
}

double KishEss(const Eigen::Ref<const Eigen::RowVectorXd>& weights) {
  // Scale-free: divide by the largest weight first so that tiny weights do
  // not underflow when squared.
  const double top = weights.maxCoeff();
  if (!(top > 0)) return 0.0;
  const Eigen::RowVectorXd w = weights / top;
  return w.sum() * w.sum() / w.squaredNorm();
}

double MeanBiwEss(const estimators::StepRecord& step) {
  RowMatrix log_weights;
  estimators::BiwLogWeights(step, &log_weights);
  const Eigen::Index p = log_weights.rows();
  double total = 0;
  Eigen::RowVectorXd w(p);
  for (Eigen::Index i = 0; i < p; ++i) {
    // Kish ESS is scale-free: factor out the row's largest log weight so
    // that weights far below 1e-308 still count relative to each other.
    const double top = log_weights.row(i).maxCoeff();
    if (!std::isfinite(top)) continue;  // a non-finite particle contributes 0
    for (Eigen::Index j = 0; j < p; ++j) w(j) = std::exp(log_weights(i, j) - top);
    total += KishEss(w);
  }
  return total / (static_cast<double>(p) * static_cast<double>(p));
}

void PoolMeans(const std::vector<Vector>& means, const std::vector<Vector>& standard_errors,
               Vector* pooled, Vector* pooled_se) {
  const Eigen::Index n = means.front().size();
  pooled->setZero(n);
  pooled_se->setZero(n);
  for (Eigen::Index j = 0; j < n; ++j) {
    double weight_sum = 0, weighted = 0, plain = 0;
    bool any_zero_se = false;
    for (size_t k = 0; k < means.size(); ++k) {
      const double se = standard_errors[k](j);
      plain += means[k](j);
      if (se > 0) {
        weight_sum += 1.0 / (se * se);
        weighted += means[k](j) / (se * se);
      } else {
        any_zero_se = true;
      }
    }
    if (weight_sum > 0 && !any_zero_se) {
      (*pooled)(j) = weighted / weight_sum;
      (*pooled_se)(j) = std::sqrt(1.0 / weight_sum);
    } else if (any_zero_se) {
      // An exact value (SE 0) wins: the plain mean of the exact ones.
      double exact = 0;
      int count = 0;
      for (size_t k = 0; k < means.size(); ++k) {
        if (!(standard_errors[k](j) > 0)) {
          exact += means[k](j);
          ++count;
        }
      }
      (*pooled)(j) = exact / count;
    } else {
      (*pooled)(j) = plain / static_cast<double>(means.size());
    }
  }
}

absl::StatusOr<StudyResult> RunStudy(const FrozenProblem& problem, const StudyOptions& options,
                                     const StudyProgress& progress,
                                     const StudyShouldStop& should_stop) {
  const auto stopped = [&should_stop] { return should_stop && should_stop(); };
  const absl::Status kStopped = absl::CancelledError("study stopped before it finished");
  if (absl::Status st = options.Validate(); !st.ok()) return st;
  if (!problem.problem.complete() || problem.policy == nullptr) {
    return absl::InvalidArgumentError("study: the frozen problem needs a model, a policy and a cost");
  }
  const Clock::time_point start = Clock::now();
  StudyResult result;
  result.source = problem.source;
  result.scene = problem.scene;
  result.num_parameters = problem.policy->num_parameters();

  for (int h : options.horizons) {
    if (stopped()) return kStopped;
    estimators::Problem p = problem.problem;
    p.horizon = h;
    result.references.push_back(internal::ComputeReference(p, options, progress));
    const ReferenceGradient& ref = result.references.back();
    if (progress) {
      progress(absl::StrFormat("reference H=%d: |g*| %.4g, relative SE %.3g, agree %s (max |z| %.3g) %s",
                               h, ref.norm, ref.relative_error, ref.agree ? "yes" : "no",
                               ref.agreement_max_z, ref.note));
    }
  }

  std::unique_ptr<pilco::GaussianInputGp> pilco_gp;
  for (const EstimatorSpec& spec : options.estimators) {
    if (spec.method == estimators::Method::kPilco) {
      for (size_t hi = 0; hi < options.horizons.size(); ++hi) {
        if (stopped()) return kStopped;
        estimators::Problem p = problem.problem;
        p.horizon = options.horizons[hi];
        CellResult cell;
        if (problem.model == nullptr) {
          cell.method = estimators::MethodName(estimators::Method::kPilco);
          cell.horizon = p.horizon;
          cell.omitted = true;
          cell.omission_reason = "PILCO needs the problem's GP model";
        } else {
          if (!pilco_gp) {
            pilco_gp = std::make_unique<pilco::GaussianInputGp>(
                pilco::GaussianInputGpFromModel(*problem.model));
          }
          cell = RunPilcoCell(problem, *pilco_gp, p, options, result.references[hi]);
        }
        cell.estimator = spec.label;
        if (progress) {
          progress(absl::StrFormat("%s H=%d: %.3g s, rel_rmse %.3g%s", spec.label, p.horizon,
                                   cell.time_min_s, cell.rel_rmse,
                                   cell.omitted ? " (omitted: " + cell.omission_reason + ")" : std::string()));
        }
        result.cells.push_back(std::move(cell));
      }
      continue;
    }
    absl::StatusOr<std::unique_ptr<estimators::Estimator>> estimator =
        estimators::MakeEstimator(spec.method, spec.options);
    if (!estimator.ok()) return estimator.status();  // Validate() accepted it: cannot happen
    double noise_factor = 1.0;
    const bool biw = UsesBiwWeights(**estimator, &noise_factor);
    for (int particles : options.particles) {
      for (size_t hi = 0; hi < options.horizons.size(); ++hi) {
        if (stopped()) return kStopped;
        estimators::Problem p = problem.problem;
        p.horizon = options.horizons[hi];
        const ReferenceGradient& ref = result.references[hi];
        CellResult cell = RunEstimatorCell(estimator->get(), spec, biw, noise_factor, particles, p,
                                           ref, options);
        if (progress) {
          progress(absl::StrFormat(
              "%s P=%d H=%d: %d reps, %.3g s, rel_rmse %.3g, bias %.3g, cos %.3f%s%s", spec.label,
              particles, p.horizon, cell.replicates, cell.time_min_s, cell.rel_rmse, cell.rel_bias,
              cell.cos_mean, cell.nonfinite > 0 ? absl::StrCat(", ", cell.nonfinite, " non-finite") : "",
              cell.omitted ? " (omitted: " + cell.omission_reason + ")" : std::string()));
        }
        result.cells.push_back(std::move(cell));
      }
    }
  }
  // Every cell, the omitted ones too, carries its horizon's floor (the
  // plots' noise floor) so that a cell row stands on its own in a table.
  for (CellResult& cell : result.cells) {
    for (const ReferenceGradient& ref : result.references) {
      if (ref.horizon == cell.horizon) {
        cell.reference_floor = ref.floor;
        break;
      }
    }
  }
  result.seconds = SecondsSince(start);
  return result;
}

}  // namespace totalgrad::study
