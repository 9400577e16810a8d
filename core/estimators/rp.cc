#include "core/estimators/rp.h"

#include <cmath>

#include "core/common/check.h"
#include "core/common/thread_pool.h"

namespace totalgrad::estimators {
namespace {
constexpr int kMaxInputs = 16;  // E = S + F; the cart-pole has 5
}  // namespace

void RpBackward(const Problem& problem, const Rollout& rollout, Vector* gradient,
                RowMatrix* per_particle) {
  TG_CHECK(problem.policy != nullptr);
  const ParticlePolicy& policy = *problem.policy;
  const int s_dim = policy.state_dim();
  const int f_dim = policy.control_dim();
  const int e_dim = s_dim + f_dim;
  const int n = policy.num_parameters();
  TG_CHECK(e_dim <= kMaxInputs);
  const Eigen::Index p = rollout.steps.front().state.rows();
  const double inv_p = 1.0 / static_cast<double>(p);

  RowMatrix contributions = RowMatrix::Zero(p, n);
  RowMatrix gamma = RowMatrix::Zero(p, s_dim);  // dJ/dx_{t+1}
  RowMatrix state_bar;
  Vector force_bar(p * f_dim);
  for (int t = static_cast<int>(rollout.steps.size()) - 1; t >= 0; --t) {
    const StepRecord& step = rollout.steps[t];
    gamma.noalias() += inv_p * step.cost_gradient;
    // x_{t+1} = x_t + mean(z) + sqrt(var(z)) eps: cotangents on mean and var.
    // mean_bar = gamma, var_bar = gamma eps / (2 sqrt(var)).
    ParallelForBlocks(problem.pool, p, kParticleBlock, [&](int64_t begin, int64_t end) {
      for (Eigen::Index i = begin; i < end; ++i) {
        double z_bar[kMaxInputs] = {};
        for (int a = 0; a < s_dim; ++a) {
          const double m_bar = gamma(i, a);
          // Zero predicted variance: no variance path (see RpZetaCotangent).
          const double v_bar = step.variance(i, a) > 0
                                   ? gamma(i, a) * step.noise(i, a) / (2.0 * std::sqrt(step.variance(i, a)))
                                   : 0.0;
          const double* dm = step.dmean_dz.row(i).data() + a * e_dim;
          const double* dv = step.dvar_dz.row(i).data() + a * e_dim;
          for (int m = 0; m < e_dim; ++m) z_bar[m] += m_bar * dm[m] + v_bar * dv[m];
        }
        // Direct path x_t -> x_{t+1} is the identity.
        for (int m = 0; m < s_dim; ++m) gamma(i, m) += z_bar[m];
        for (int j = 0; j < f_dim; ++j) force_bar(i * f_dim + j) = z_bar[s_dim + j];
      }
    });
    policy.Backward(step.policy_cache, force_bar, &state_bar, &contributions, nullptr);
    gamma += state_bar;
  }
  if (gradient != nullptr) *gradient = contributions.colwise().sum().transpose();
  if (per_particle != nullptr) *per_particle = std::move(contributions);
}

absl::Status RpEstimator::Estimate(const Problem& problem, const EstimateOptions& options, Rng* rng,
                                   GradientEstimate* estimate) {
  RolloutRecording recording;
  recording.jacobians = true;
  absl::Status status = SimulateParticles(problem, options.particles, recording, rng, &rollout_);
  if (!status.ok()) return status;
  estimate->objective = rollout_.objective;
  RowMatrix per_particle;
  RpBackward(problem, rollout_, &estimate->gradient, &per_particle);
  // g^(i) = P * contribution_i, so that mean_i g^(i) = gradient.
  per_particle *= static_cast<double>(options.particles);
  estimate->per_particle_variance = ColumnSampleVariance(per_particle);
  estimate->finite = rollout_.finite && estimate->gradient.allFinite() &&
                     estimate->per_particle_variance.allFinite();
  if (options.keep_per_particle) estimate->per_particle = std::move(per_particle);
  return absl::OkStatus();
}

}  // namespace totalgrad::estimators
