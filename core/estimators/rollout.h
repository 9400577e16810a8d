// Particle rollouts through the learned model: the forward pass shared by
// every particle gradient estimator (pipps-spec.md 4).
//
//   x_0^i ~ N(mu0, diag(initial_std^2)),               i = 1..P
//   u_t^i = policy(x_t^i);  z_t^i = [x_t^i, u_t^i]
//   x_{t+1}^i = x_t^i + mean(z_t^i) + sqrt(var(z_t^i)) .* eps_t^i
//   J = (1/P) sum_i sum_{t=1..H} c(x_t^i)
//
// What the pass records is decided by RolloutRecording, so that a method
// never pays for what it does not use: an evaluation pass (predicted cost)
// records no Jacobians and no policy caches.
//
// Thread safety: functions are re-entrant; a Rollout is a plain value.
#ifndef TOTALGRAD_CORE_ESTIMATORS_ROLLOUT_H_
#define TOTALGRAD_CORE_ESTIMATORS_ROLLOUT_H_

#include <vector>

#include "absl/status/status.h"
#include "core/common/rng.h"
#include "core/common/types.h"
#include "core/gp/gp.h"
#include "core/policy/rbf_policy.h"
#include "core/tasks/cost.h"

namespace totalgrad::estimators {

// The frozen problem an estimator differentiates: model, policy, start
// distribution, cost and horizon. Non-owning: everything pointed to must
// outlive the problem.
struct Problem {
  const gp::GpModel* model = nullptr;
  const policy::RbfPolicy* policy = nullptr;
  const tasks::StateCost* cost = nullptr;
  Vector mu0;          // S
  Vector initial_std;  // S
  int horizon = 30;
  double noise_variance_multiplier = 1.0;  // GTP+sigma_n uses 25
};

// Which quantities the forward pass keeps.
struct RolloutRecording {
  bool jacobians = false;     // GP dmean/dz, dvar/dz, policy caches, cost gradients
};

// Everything recorded for one step t = 0..H-1 (the transition x_t -> x_{t+1}).
struct StepRecord {
  RowMatrix state;        // P x S, x_t
  Vector force;           // P, u_t
  RowMatrix mean;         // P x S, GP mean difference
  RowMatrix variance;     // P x S, GP predictive variance (incl. noise x multiplier)
  RowMatrix noise;        // P x S, eps_t
  RowMatrix next_state;   // P x S, x_{t+1}
  Vector cost;            // P, c(x_{t+1})
  // Recorded only with RolloutRecording::jacobians:
  policy::RbfPolicy::Cache policy_cache;
  RowMatrix dmean_dz;     // P x S*E
  RowMatrix dvar_dz;      // P x S*E
  RowMatrix cost_gradient;  // P x S, dc/dx at x_{t+1}
};

struct Rollout {
  std::vector<StepRecord> steps;  // H entries
  double objective = 0;           // J, mean over particles of the summed costs
  bool finite = true;             // false if any recorded value was non-finite
};

// Runs the forward pass with P particles, drawing x_0 and every eps_t from
// *rng. Errors: InvalidArgument for an incomplete problem or P < 1.
// A non-finite value does not abort the pass; it sets rollout->finite = false
// so the caller can record and skip the estimate.
absl::Status SimulateParticles(const Problem& problem, int particles,
                               const RolloutRecording& recording, Rng* rng, Rollout* rollout);

}  // namespace totalgrad::estimators

#endif  // TOTALGRAD_CORE_ESTIMATORS_ROLLOUT_H_
