// Particle rollouts through the learned model: the forward pass shared by
// every particle gradient estimator (pipps-spec.md 4).
//
//   x_0^i ~ N(mu0, diag(initial_std^2)),               i = 1..P
//   u_t^i = policy(x_t^i) (F controls);  z_t^i = [x_t^i, u_t^i]
//   x_{t+1}^i = x_t^i + mean(z_t^i) + sqrt(var(z_t^i)) .* eps_t^i
//   [GR only: a StepResampler replaces {x_{t+1}^i} by new particles]
//   J = (1/P) sum_i sum_{t=1..H} c(x_t^i)
//
// What the pass records is decided by RolloutRecording, so that a method
// never pays for what it does not use: an evaluation pass (predicted cost)
// records no Jacobians and no policy caches, and only GR resamples. Quantities
// that need the whole batch in the backward pass (importance weights, Gaussian
// fits for shaping and DEL) are not recorded here at all: the backward passes
// compute them from the recorded particles when the method needs them.
//
// Thread safety: functions are re-entrant; a Rollout is a plain value.
#ifndef TOTALGRAD_CORE_ESTIMATORS_ROLLOUT_H_
#define TOTALGRAD_CORE_ESTIMATORS_ROLLOUT_H_

#include <vector>

#include "absl/status/status.h"
#include "core/common/rng.h"
#include "core/common/types.h"
#include "core/estimators/gaussian_fit.h"
#include "core/estimators/particle_system.h"
#include "core/gp/gp.h"
#include "core/policy/rbf_policy.h"
#include "core/tasks/cost.h"

namespace totalgrad::estimators {

// The frozen problem an estimator differentiates: dynamics, policy, start
// distribution, cost and horizon. Non-owning: everything pointed to must
// outlive the problem. A trial's or a study's model and policy reach it
// through the adapters of particle_system.h (GpDynamics or FitcDynamics,
// RbfParticlePolicy, and the angle-feature wrappers), built and owned by
// learner::ModelProblem (core/learner/problem_builder.h); tests plug in
// other systems (a linear-Gaussian one with an exact gradient).
struct Problem {
  const ParticleDynamics* dynamics = nullptr;  // S state dims, inputs [x, u] (S + F)
  const ParticlePolicy* policy = nullptr;      // S state dims
  const tasks::StateCost* cost = nullptr;
  Vector mu0;          // S
  Vector initial_std;  // S
  int horizon = 30;
  double noise_variance_multiplier = 1.0;  // GTP+sigma_n uses 25
  // Threads for the per-particle work of the estimators' own passes (may be
  // null: the calling thread does everything). Never changes the numbers
  // (core/common/thread_pool.h). The dynamics and the policy bring their own.
  ThreadPool* pool = nullptr;

  // True when the problem has dynamics, a policy and a cost.
  bool complete() const { return dynamics != nullptr && policy != nullptr && cost != nullptr; }
};

struct StepRecord;

// A per-step hook of the forward pass that replaces the freshly sampled
// particles x_{t+1} by new ones (Gaussian resampling, GR), together with the
// reverse-mode map its backward pass needs.
class StepResampler {
 public:
  virtual ~StepResampler() = default;
  // Called after x_{t+1} has been sampled into step->next_state and before
  // its cost is evaluated. Must move the sampled particles to
  // step->pre_resample_state, write the new ones to step->next_state (same
  // shape) and keep in the resample_* fields what Backward needs. Draws its
  // random numbers from *rng.
  virtual void Resample(Rng* rng, StepRecord* step) const = 0;
  // gamma: dJ/dx_{t+1} (P x S) for the resampled particles; writes
  // dJ/dx'_{t+1} for the particles before resampling (P x S, overwritten).
  virtual void Backward(const StepRecord& step, const RowMatrix& gamma,
                        RowMatrix* gamma_pre) const = 0;
};

// Which quantities the forward pass keeps.
struct RolloutRecording {
  bool jacobians = false;     // model dmean/dz, dvar/dz, policy caches, cost gradients
  const StepResampler* resampler = nullptr;  // non-null: resample every step (GR)
};

// Everything recorded for one step t = 0..H-1 (the transition x_t -> x_{t+1}).
struct StepRecord {
  RowMatrix state;        // P x S, x_t
  Vector force;           // P F, u_t, particle-major (ParticlePolicy)
  RowMatrix mean;         // P x S, model mean difference
  RowMatrix variance;     // P x S, predictive variance (incl. noise x multiplier)
  RowMatrix noise;        // P x S, eps_t
  RowMatrix next_state;   // P x S, x_{t+1} (after resampling, if any)
  Vector cost;            // P, c(x_{t+1})
  // Recorded only with RolloutRecording::jacobians:
  PolicyCache policy_cache;
  RowMatrix dmean_dz;     // P x S*E, E = S + F
  RowMatrix dvar_dz;      // P x S*E
  RowMatrix cost_gradient;  // P x S, dc/dx at x_{t+1}
  // Recorded only with a resampler (empty otherwise):
  RowMatrix pre_resample_state;  // P x S, x_t + mean + sqrt(var) eps
  RowMatrix resample_noise;      // P x S, the resampler's standard normals
  GaussianFit resample_fit;      // the fit the particles were drawn from
};

struct Rollout {
  std::vector<StepRecord> steps;  // H entries
  double objective = 0;           // J, mean over particles of the summed costs
  bool finite = true;             // false if any recorded value was non-finite
};

// Runs the forward pass with P particles, drawing x_0 and every eps_t (and
// the resampler's numbers) from *rng, in that order per step. Errors:
// InvalidArgument for an incomplete problem, inconsistent dimensions or P < 1.
// A non-finite value does not abort the pass; it sets rollout->finite = false
// so the caller can record and skip the estimate.
absl::Status SimulateParticles(const Problem& problem, int particles,
                               const RolloutRecording& recording, Rng* rng, Rollout* rollout);

}  // namespace totalgrad::estimators

#endif  // TOTALGRAD_CORE_ESTIMATORS_ROLLOUT_H_
