#include "core/estimators/rollout.h"

#include <cmath>

namespace totalgrad::estimators {

absl::Status SimulateParticles(const Problem& problem, int particles,
                               const RolloutRecording& recording, Rng* rng, Rollout* rollout) {
  if (!problem.complete())
    return absl::InvalidArgumentError("rollout problem needs a model, a policy and a cost");
  if (particles < 1) return absl::InvalidArgumentError("particles must be >= 1");
  if (problem.horizon < 1) return absl::InvalidArgumentError("horizon must be >= 1");
  const ParticleDynamics& dynamics = *problem.dynamics;
  const ParticlePolicy& policy = *problem.policy;
  const int s_dim = policy.state_dim();
  const int f_dim = policy.control_dim();
  if (problem.mu0.size() != s_dim || problem.initial_std.size() != s_dim ||
      dynamics.state_dim() != s_dim || dynamics.input_dim() != s_dim + f_dim)
    return absl::InvalidArgumentError("rollout problem: model, policy and start state dimensions disagree");

  const int e_dim = s_dim + f_dim;
  rollout->steps.resize(problem.horizon);
  rollout->finite = true;
  RowMatrix x(particles, s_dim);
  rng->FillNormal(&x);
  x = (x * problem.initial_std.asDiagonal()).rowwise() + problem.mu0.transpose();

  RowMatrix z(particles, e_dim);
  double total = 0;
  for (int t = 0; t < problem.horizon; ++t) {
    StepRecord& step = rollout->steps[t];
    step.state = x;
    policy.Evaluate(step.state, &step.force, recording.jacobians ? &step.policy_cache : nullptr);
    z.leftCols(s_dim) = step.state;
    if (f_dim == 1) {
      z.col(s_dim) = step.force;
    } else {
      z.rightCols(f_dim) = Eigen::Map<const RowMatrix>(step.force.data(), particles, f_dim);
    }
    dynamics.Predict(z, problem.noise_variance_multiplier, &step.mean, &step.variance,
                     recording.jacobians ? &step.dmean_dz : nullptr,
                     recording.jacobians ? &step.dvar_dz : nullptr);
    step.noise.resize(particles, s_dim);
    rng->FillNormal(&step.noise);
    step.next_state = step.state + step.mean;
    step.next_state.array() += step.variance.array().sqrt() * step.noise.array();
    if (recording.resampler != nullptr) {
      recording.resampler->Resample(rng, &step);
    } else {
      step.pre_resample_state.resize(0, 0);
      step.resample_noise.resize(0, 0);
    }
    problem.cost->Evaluate(step.next_state, &step.cost,
                           recording.jacobians ? &step.cost_gradient : nullptr);
    if (!step.next_state.allFinite() || !step.cost.allFinite()) rollout->finite = false;
    total += step.cost.sum();
    x = step.next_state;
  }
  rollout->objective = total / particles;
  return absl::OkStatus();
}

}  // namespace totalgrad::estimators
