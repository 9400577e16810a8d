#include "core/estimators/total_propagation.h"

#include <cmath>
#include <optional>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/estimators/gaussian_fit.h"
#include "core/estimators/gaussian_shaping.h"
#include "core/estimators/likelihood_ratio.h"

namespace totalgrad::estimators {
namespace {

// k * jump + (1 - k) * pathwise, not touching a branch whose weight is 0 (it
// may hold Inf; 0 * Inf would be NaN).
template <typename T>
T Mix(double k, const T& jump, const T& pathwise) {
  if (k == 1.0) return jump;
  if (k == 0.0) return pathwise;
  return k * jump + (1.0 - k) * pathwise;
}

absl::Status ValidateConfig(const BackwardConfig& config) {
  if (!config.pathwise && config.jump == JumpKind::kNone)
    return absl::InvalidArgumentError("backward pass: neither a pathwise nor a jump branch");
  if (config.resampler != nullptr && config.jump != JumpKind::kNone)
    return absl::InvalidArgumentError("backward pass: resampling (GR) is pathwise only");
  return absl::OkStatus();
}

// The rollout must hold, at every step, this problem's P x S states with
// their Jacobians, and resampling noise exactly when the configuration
// resamples.
absl::Status CheckRollout(const Rollout& rollout, const BackwardConfig& config, Eigen::Index p,
                          int s_dim) {
  for (const StepRecord& step : rollout.steps) {
    if (step.state.rows() != p || step.state.cols() != s_dim ||
        step.dmean_dz.rows() != p || step.cost_gradient.rows() != p)
      return absl::InvalidArgumentError(
          "backward pass: rollout not recorded with Jacobians for this problem");
    if ((config.resampler != nullptr) != (step.resample_noise.rows() == p))
      return absl::InvalidArgumentError(
          "backward pass: the rollout's resampling does not match the configuration");
  }
  return absl::OkStatus();
}

// Exact Gaussian-shaping derivatives need the cost's closed-form expectation
// (into `exact_cost`); sampled ones need an Rng.
absl::Status PrepareShaping(const Problem& problem, const BackwardConfig& config, const Rng* rng,
                            std::optional<gaussian::GaussianCost>& exact_cost) {
  if (config.cost == CostNodeKind::kGaussianShaped && config.gs_derivative == GsDerivative::kExact) {
    absl::StatusOr<gaussian::GaussianCost> c = problem.cost->GaussianExpectation();
    if (!c.ok())
      return absl::InvalidArgumentError(absl::StrCat("exact Gaussian-shaping derivatives: ", c.status().message(),
                                                     " (use gs_derivative=sampled)"));
    exact_cost = *std::move(c);
  } else if (config.cost == CostNodeKind::kGaussianShaped && rng == nullptr) {
    return absl::InvalidArgumentError("backward pass: sampled shaping derivatives need an Rng");
  }
  return absl::OkStatus();
}

// 1. The cost node at x_{t+1}: each particle's cost into `local` and, with a
// pathwise branch, dJ/dx_{t+1} of the node into `rp_cost` (1/P inside).
void CostNode(const Problem& problem, const BackwardConfig& config, const StepRecord& step,
              const std::optional<gaussian::GaussianCost>& exact_cost, int s_dim, Eigen::Index p,
              double scale, Rng* rng, GaussianFit& fit, ExpectedCostGradient& expected,
              Vector& local, RowMatrix& rp_cost) {
  if (config.cost == CostNodeKind::kPlain) {
    local = step.cost;
    if (config.pathwise) rp_cost = scale * step.cost_gradient;
  } else {
    FitGaussian(step.next_state, kShapingJitter, &fit);
    if (exact_cost) {
      // Fails only on a non-finite fit (non-finite particles): that is a
      // non-finite estimate for the caller to skip, not an error.
      if (!ExactExpectedCostGradient(*exact_cost, fit, &expected).ok()) {
        const double nan = std::nan("");
        expected.value = nan;
        expected.dmean = Vector::Constant(s_dim, nan);
        expected.dcov = Matrix::Constant(s_dim, s_dim, nan);
      }
    } else {
      SampledExpectedCostGradient(*problem.cost, fit, static_cast<int>(p), rng, &expected);
    }
    ShapedValues(fit, expected, &local);
    if (config.pathwise) GaussianFitBackward(fit, expected.dmean, expected.dcov, &rp_cost);
  }
}

// 3. The jump branch at step t: the cotangent of the transition's output
// (`zeta_jump`) from the cost-to-go, by likelihood ratio (plain or BIW
// weights; BIW records its ESS in result->ess[t]) or density estimation.
// InvalidArgument when DEL's particles have collapsed.
absl::Status JumpCotangent(const BackwardConfig& config, const StepRecord& step, int t,
                           Eigen::Index p, double scale, const Vector& cost_to_go,
                           BackwardResult* result, RowMatrix& log_weights, RowMatrix& weights,
                           RowMatrix& pair_baseline, Vector& baseline, GaussianFit& fit,
                           RowMatrix& x_bar, ZetaCotangent& zeta_jump) {
  if (config.jump == JumpKind::kLikelihoodRatio) {
    if (config.lr_weights == LrWeights::kBatchImportance) {
      BiwLogWeights(step, &log_weights, &weights);
      result->ess[t] = MeanEffectiveSampleSize(weights);
      if (config.lr_baseline == LrBaseline::kBatchImportancePair) {
        BiwPairBaseline(log_weights, cost_to_go, &pair_baseline);
        WeightedLrCotangent(step, weights, cost_to_go, pair_baseline, scale, &zeta_jump);
      } else {
        switch (config.lr_baseline) {
          case LrBaseline::kBatchImportance: BiwBaseline(log_weights, weights, cost_to_go, &baseline); break;
          case LrBaseline::kLeaveOneOut: baseline = LeaveOneOutBaseline(cost_to_go); break;
          default: baseline.setZero(p); break;
        }
        WeightedLrCotangent(step, weights, cost_to_go, baseline, scale, &zeta_jump);
      }
    } else {
      if (config.lr_baseline == LrBaseline::kNone) baseline.setZero(p);
      else baseline = LeaveOneOutBaseline(cost_to_go);
      PlainLrCotangent(step, cost_to_go, baseline, scale, &zeta_jump);
    }
  } else if (config.jump == JumpKind::kDensityEstimation) {
    FitGaussian(step.next_state, kShapingJitter, &fit);
    // DEL's score is d_i / (cov + jitter). When every dimension's spread is
    // below the jitter, the fitted density is the jitter's, not the
    // particles', and the estimate shrinks towards zero by the ratio of the
    // two (measured ~1e-25 against a true 0.17): refuse rather than return
    // a silently wrong gradient.
    if (fit.covariance.diagonal().maxCoeff() < kShapingJitter) {
      return absl::InvalidArgumentError(absl::StrCat(
          "DEL: the ", p, " particles collapsed onto one point at step ", t + 1,
          " (largest fitted variance ", fit.covariance.diagonal().maxCoeff(), " < jitter ",
          kShapingJitter, "); density-estimation LR needs spread particles: use more "
          "particles, injected noise, or a pathwise method"));
    }
    if (config.lr_baseline == LrBaseline::kNone) baseline.setZero(p);
    else baseline = LeaveOneOutBaseline(cost_to_go);
    const Vector a = scale * (cost_to_go - baseline);
    DensityEstimationCotangent(fit, a, &x_bar);
    RpZetaCotangent(step, x_bar, &zeta_jump);  // one-step reparameterisation of the fit
  }
  return absl::OkStatus();
}

// 4-5 with both branches, several controls and k_LR by the rule: adds the
// combined rows to result->per_particle and, for t > 0, sets `gamma` to
// dJ/dx_t.
void CombineSeveralControls(const ParticlePolicy& policy, const StepRecord& step, int t,
                            Eigen::Index p, int n, const Vector& f_rp, const Vector& f_jump,
                            const RowMatrix& x_rp, const RowMatrix& x_jump, BackwardResult* result,
                            RowMatrix& rows_rp, RowMatrix& rows_jump, RowMatrix& state_bar,
                            RowMatrix& gamma) {
  // Several controls: a particle's two branch gradients, sum_j f_ij
  // du_ij/dtheta, no longer share one Jacobian row, so both are formed.
  rows_rp.setZero(p, n);
  policy.Backward(step.policy_cache, f_rp, nullptr, &rows_rp, nullptr);
  rows_jump.setZero(p, n);
  policy.Backward(step.policy_cache, f_jump, nullptr, &rows_jump, nullptr);
  const TraceVariance v_rp = RowTraceVariance(rows_rp);
  const TraceVariance v_jump = RowTraceVariance(rows_jump);
  const double k = CombinationWeight(v_rp, v_jump);
  result->k_lr[t] = k;
  result->var_pathwise[t] = v_rp;
  result->var_jump[t] = v_jump;
  result->per_particle.noalias() += Mix(k, rows_jump, rows_rp);
  if (t > 0) {
    policy.Backward(step.policy_cache, Mix(k, f_jump, f_rp), &state_bar, nullptr, nullptr);
    gamma = Mix(k, x_jump, x_rp);
    gamma += state_bar;
  }
}

}  // namespace

absl::Status BackwardPass(const Problem& problem, const Rollout& rollout,
                          const BackwardConfig& config, Rng* rng, BackwardResult* result) {
  if (absl::Status st = ValidateConfig(config); !st.ok()) return st;
  if (!problem.complete())
    return absl::InvalidArgumentError("backward pass: problem needs a model, a policy and a cost");
  if (rollout.steps.empty()) return absl::InvalidArgumentError("backward pass: empty rollout");
  const ParticlePolicy& policy = *problem.policy;
  const int s_dim = policy.state_dim();
  const int n = policy.num_parameters();
  const Eigen::Index p = rollout.steps.front().state.rows();
  if (absl::Status st = CheckRollout(rollout, config, p, s_dim); !st.ok()) return st;
  std::optional<gaussian::GaussianCost> exact_cost;
  if (absl::Status st = PrepareShaping(problem, config, rng, exact_cost); !st.ok()) return st;

  const bool combining = config.pathwise && config.jump != JumpKind::kNone;
  const bool forced = combining && config.forced_k_lr >= 0.0 && config.forced_k_lr <= 1.0;
  // Only a pathwise branch ever reads the message to x_t.
  const bool need_message = config.pathwise;
  const double scale = 1.0 / static_cast<double>(p);
  const int horizon = static_cast<int>(rollout.steps.size());

  result->per_particle.setZero(p, n);
  result->k_lr.clear();
  result->ess.clear();
  const bool biw = config.jump == JumpKind::kLikelihoodRatio &&
                   config.lr_weights == LrWeights::kBatchImportance;
  if (biw) result->ess.assign(horizon, std::nan(""));
  result->var_pathwise.clear();
  result->var_jump.clear();
  if (combining) {
    result->k_lr.assign(horizon, 0.0);
    result->var_pathwise.assign(horizon, TraceVariance());
    result->var_jump.assign(horizon, TraceVariance());
  }

  RowMatrix gamma = RowMatrix::Zero(p, s_dim);  // combined dJ/dx_{t+1}
  Vector cost_to_go = Vector::Zero(p);
  Vector local(p);
  RowMatrix pair_baseline, rp_cost, gamma_rp, resampled, x_rp, x_jump, x_bar, state_bar, log_weights, weights;
  RowMatrix dforce_dtheta, dforce_dx, rows_rp, rows_jump;
  Vector f_rp, f_jump, baseline, row_mean, row_mean_jump;
  const Vector ones = Vector::Ones(p);
  ZetaCotangent zeta_rp, zeta_jump;
  GaussianFit fit;
  ExpectedCostGradient expected;

  for (int t = horizon - 1; t >= 0; --t) {
    const StepRecord& step = rollout.steps[t];

    // 1. Cost node at x_{t+1}.
    CostNode(problem, config, step, exact_cost, s_dim, p, scale, rng, fit, expected, local, rp_cost);
    cost_to_go += local;

    // 2. Pathwise branch.
    if (config.pathwise) {
      gamma_rp = gamma + rp_cost;
      if (config.resampler != nullptr) {
        config.resampler->Backward(step, gamma_rp, &resampled);
        gamma_rp.swap(resampled);
      }
      RpZetaCotangent(step, gamma_rp, &zeta_rp);
      TransitionVjp(step, zeta_rp, &f_rp, need_message ? &x_rp : nullptr, problem.pool);
    }

    // 3. Jump branch.
    if (absl::Status st = JumpCotangent(config, step, t, p, scale, cost_to_go, result, log_weights,
                                        weights, pair_baseline, baseline, fit, x_bar, zeta_jump);
        !st.ok()) {
      return st;
    }
    if (config.jump != JumpKind::kNone)
      TransitionVjp(step, zeta_jump, &f_jump, combining && need_message ? &x_jump : nullptr,
                    problem.pool);

    // 4-5. Combine, then cross the policy.
    if (combining && !forced && policy.control_dim() > 1) {
      CombineSeveralControls(policy, step, t, p, n, f_rp, f_jump, x_rp, x_jump, result, rows_rp,
                             rows_jump, state_bar, gamma);
      continue;
    }
    if (combining && !forced) {
      // The policy's Jacobian rows (its adjoint is linear in force_bar), so
      // that both branches' per-particle gradients, f_i * dforce_i/dtheta,
      // exist for the variances; they are never formed, only their trace
      // variances and the combined rows.
      dforce_dtheta.setZero(p, n);
      policy.Backward(step.policy_cache, ones, &dforce_dx, &dforce_dtheta, nullptr);
      TraceVariance v_rp, v_jump;
      ScaledRowTraceVariances(f_rp, f_jump, dforce_dtheta, &row_mean, &row_mean_jump, &v_rp,
                              &v_jump);
      const double k = CombinationWeight(v_rp, v_jump);
      result->k_lr[t] = k;
      result->var_pathwise[t] = v_rp;
      result->var_jump[t] = v_jump;
      // Mix leaves out a branch whose weight is 0 (it may hold Inf).
      const Vector f = Mix(k, f_jump, f_rp);
      result->per_particle.noalias() += f.asDiagonal() * dforce_dtheta;
      if (t > 0) {
        gamma = Mix(k, x_jump, x_rp);
        gamma.noalias() += f.asDiagonal() * dforce_dx;
      }
      continue;
    }
    double k = config.pathwise ? 0.0 : 1.0;
    if (forced) {
      k = config.forced_k_lr;
      result->k_lr[t] = k;
    }
    const Vector f = combining ? Mix(k, f_jump, f_rp) : (config.pathwise ? f_rp : f_jump);
    if (need_message && t > 0) {
      policy.Backward(step.policy_cache, f, &state_bar, &result->per_particle, nullptr);
      gamma = combining ? Mix(k, x_jump, x_rp) : x_rp;
      gamma += state_bar;
    } else {
      policy.Backward(step.policy_cache, f, nullptr, &result->per_particle, nullptr);
    }
  }
  result->gradient = result->per_particle.colwise().sum().transpose();
  return absl::OkStatus();
}

absl::StatusOr<MethodRecipe> RecipeFor(Method method, const EstimatorOptions& options) {
  if (absl::Status st = options.Validate(); !st.ok()) return st;
  MethodRecipe r;
  BackwardConfig& b = r.backward;
  b.lr_weights = options.lr_weights;
  b.lr_baseline = options.lr_baseline;
  b.gs_derivative = options.gs_derivative;
  b.forced_k_lr = options.forced_k_lr;
  switch (method) {
    case Method::kRp:
      b.pathwise = true;
      return r;
    case Method::kGr:
      b.pathwise = true;
      r.resample = true;
      return r;
    case Method::kLr:
      b.pathwise = false;
      b.jump = JumpKind::kLikelihoodRatio;
      return r;
    case Method::kTp:
      b.pathwise = true;
      b.jump = JumpKind::kLikelihoodRatio;
      return r;
    case Method::kGlr:
      b.cost = CostNodeKind::kGaussianShaped;
      b.pathwise = false;
      b.jump = JumpKind::kLikelihoodRatio;
      return r;
    case Method::kGtp:
    case Method::kGtpSn:
      b.cost = CostNodeKind::kGaussianShaped;
      b.pathwise = true;
      b.jump = JumpKind::kLikelihoodRatio;
      if (method == Method::kGtpSn) r.noise_variance_factor = options.sn_noise_multiplier;
      return r;
    case Method::kDel:
      b.pathwise = false;
      b.jump = JumpKind::kDensityEstimation;
      return r;
    case Method::kPilco:
      break;
  }
  return absl::InvalidArgumentError(absl::StrCat("no particle recipe for method '", MethodName(method), "'"));
}

ParticleEstimator::ParticleEstimator(Method method, MethodRecipe recipe)
    : method_(method), recipe_(std::move(recipe)) {}

absl::Status ParticleEstimator::Estimate(const Problem& problem, const EstimateOptions& options,
                                         Rng* rng, GradientEstimate* estimate) {
  // GTP+sn changes the model only inside the estimator: the caller's problem
  // (the trial's predicted cost, the real plant) is untouched.
  Problem local = problem;
  local.noise_variance_multiplier *= recipe_.noise_variance_factor;
  BackwardConfig config = recipe_.backward;
  RolloutRecording recording;
  recording.jacobians = true;
  if (recipe_.resample) {
    recording.resampler = &resampler_;
    config.resampler = &resampler_;
  }
  absl::Status status = SimulateParticles(local, options.particles, recording, rng, &rollout_);
  if (!status.ok()) return status;
  status = BackwardPass(local, rollout_, config, rng, &backward_);
  if (!status.ok()) return status;
  estimate->objective = rollout_.objective;
  estimate->gradient = backward_.gradient;
  // g^(i) = P * contribution_i, so that mean_i g^(i) = gradient.
  RowMatrix per_particle = backward_.per_particle * static_cast<double>(options.particles);
  estimate->per_particle_variance = ColumnSampleVariance(per_particle);
  estimate->k_lr = backward_.k_lr;
  estimate->ess = backward_.ess;
  estimate->finite = rollout_.finite && estimate->gradient.allFinite() &&
                     estimate->per_particle_variance.allFinite();
  if (options.keep_per_particle) estimate->per_particle = std::move(per_particle);
  else estimate->per_particle.resize(0, 0);
  return absl::OkStatus();
}

}  // namespace totalgrad::estimators
