// Problem assembly, written once: from a trial's data, the GP
// hyperparameters, the scene and the feature choice to the problem the
// particle estimators differentiate (ModelProblem) and to PILCO's problem
// (MakePilcoProblem). The trial's learners (trial.cc), the snapshot rebuild
// (core/study/frozen_problem.cc) and the study's PILCO cells
// (core/study/study.cc) all build here, so a rebuilt snapshot is the trial's
// model of that episode by construction, bit for bit.
//
// Features: the GP and the policy see phi(x), the raw state (no angle
// indices) or PILCO's [x without the angles, sin x_a1, cos x_a1, ...] (the
// scene's angle indices, pilco/angle_features.h); the particles, the start
// distribution and the cost stay in the raw state, and the adapters of
// estimators/particle_system.h chain-rule between the two.
//
// Thread safety: the functions are re-entrant; a ModelProblem is immutable
// once built (share it read-only; its problem() is safe to use from several
// threads as far as the adapters are, i.e. const calls).
#ifndef TOTALGRAD_CORE_LEARNER_PROBLEM_BUILDER_H_
#define TOTALGRAD_CORE_LEARNER_PROBLEM_BUILDER_H_

#include <memory>
#include <vector>

#include "absl/status/statusor.h"
#include "core/common/rng.h"
#include "core/common/thread_pool.h"
#include "core/common/types.h"
#include "core/estimators/particle_system.h"
#include "core/estimators/rollout.h"
#include "core/gp/fitc.h"
#include "core/gp/gp.h"
#include "core/pilco/pilco.h"
#include "core/learner/trial_policy.h"
#include "core/policy/policy_class.h"
#include "core/tasks/cost.h"
#include "core/tasks/scene.h"

namespace totalgrad::learner {

// The observed transitions (x_t, u_t, x_{t+1}) of a trial, in the order they
// were observed. Observations, not true states: what the model learns from.
struct Transitions {
  RowMatrix states;       // N x S, observed x_t
  Vector forces;          // N F, the F controls applied at x_t, transition-major
                          // (u_1^1..u_1^F, u_2^1, ...; one control: N)
  RowMatrix next_states;  // N x S, observed x_{t+1}

  int size() const { return static_cast<int>(states.rows()); }
  // F (1 while there are no transitions).
  int control_dim() const {
    return states.rows() == 0 ? 1 : static_cast<int>(forces.size() / states.rows());
  }
  // Appends the episode's H transitions (its observations and forces).
  void Append(const tasks::Episode& episode);
};

// The GP's training set: inputs [phi(x_t), u_t] (N x (Ef + F), Ef the
// feature dimension, F the controls) and targets x_{t+1} - x_t (N x S,
// raw-state differences).
struct GpTrainingSet {
  RowMatrix inputs;
  RowMatrix targets;
};
// angle_indices: empty (raw) or strictly increasing state indices of `data`.
// dynamics_inputs (tasks::Scene's; only with no angles): phi(x) is then
// x(dynamics_inputs), the state entries the GP sees.
GpTrainingSet MakeGpTrainingSet(const Transitions& data, const std::vector<int>& angle_indices,
                                const std::vector<int>& dynamics_inputs = {});

// The sparse alternative to the full GP: FITC with num_inducing inducing
// inputs once N > num_inducing (gp::FitFitcModel: a random subset of the
// inputs drawn from *rng the first time, then warm-started from *inducing).
struct SparseModelFit {
  int num_inducing = 0;           // 0: always the full GP
  RowMatrix* inducing = nullptr;  // in: warm start (empty: none); out: the trained inputs
  Rng* rng = nullptr;             // the first random subset's draws
};

// A particle problem that owns everything its estimators::Problem points
// into: the GP (full or FITC), its dynamics adapter, and the policy adapter
// over a policy the caller owns (the trial optimises it in place). Movable,
// not copyable (the problem points into heap objects that move with it).
class ModelProblem {
 public:
  // Builds the model on `data` with hyperparameters `hyperparameters` (the
  // full GP unless sparse.num_inducing > 0 and N > sparse.num_inducing; then
  // sparse.inducing and sparse.rng must be non-null), wraps model and policy
  // for angle_indices (empty: used directly), the model for the scene's
  // dynamics_inputs (non-empty only with no angles), and fills the problem's start
  // distribution, cost and horizon from `scene` and its noise multiplier.
  // `policy` (non-null) and `scene` must outlive the result; `pool` (may be
  // null) is given to the adapters and the problem.
  // `gp_options` go to the full GP (gp::GpModelOptions: the variance's
  // low-rank form); FITC ignores them.
  // Errors, prefixed "GP model: " or "FITC model: ": those of
  // gp::GpModel::Create (InvalidArgument for shapes or options,
  // FailedPrecondition if K cannot be factorised) and gp::FitFitcModel.
  static absl::StatusOr<ModelProblem> Build(const GpTrainingSet& data,
                                            const gp::GpHyperparameters& hyperparameters,
                                            const SparseModelFit& sparse,
                                            const std::vector<int>& angle_indices,
                                            const TrialPolicy* policy,
                                            const tasks::Scene& scene,
                                            double noise_variance_multiplier, ThreadPool* pool,
                                            const gp::GpModelOptions& gp_options = {});

  ModelProblem(ModelProblem&&) = default;
  ModelProblem& operator=(ModelProblem&&) = default;
  ModelProblem(const ModelProblem&) = delete;
  ModelProblem& operator=(const ModelProblem&) = delete;

  const estimators::Problem& problem() const { return problem_; }
  // The full GP, or null when the model is sparse.
  const gp::GpModel* full_model() const { return full_.get(); }
  bool sparse() const { return sparse_ != nullptr; }
  // Some output of the full GP needed jitter to factorise K.
  bool jitter() const;

 private:
  ModelProblem() = default;
  std::unique_ptr<gp::GpModel> full_;
  std::unique_ptr<gp::FitcModel> sparse_;
  std::unique_ptr<estimators::ParticleDynamics> model_dynamics_;    // over full_ or sparse_
  std::unique_ptr<estimators::ParticleDynamics> feature_dynamics_;  // angle wrapper, or null
  std::unique_ptr<estimators::ParticleDynamics> subset_dynamics_;   // dyni wrapper, or null
  std::unique_ptr<estimators::ParticlePolicy> raw_policy_;  // the policy on its own inputs
  std::unique_ptr<estimators::ParticlePolicy> feature_policy_;      // angle wrapper, or null
  estimators::Problem problem_;
};

// PILCO's problem for the same task: start N(mu0, diag(initial_std^2)),
// horizon, the cost's closed form (tasks::StateCost::GaussianExpectation),
// a policy of `policy_class` (RBF: num_basis basis functions), control j saturated at
// max_control(j) (F = max_control.size() controls), on the features of
// angle_indices (strictly increasing; empty: the raw state); the GP on
// [x(dynamics_inputs), u] when dynamics_inputs is non-empty (the scene's).
// prediction_includes_noise stays PILCO's false;
// the caller sets it where the particles' model includes the noise.
// Errors: the cost's InvalidArgument when it has no closed form.
absl::StatusOr<pilco::PilcoProblem> MakePilcoProblem(const tasks::StateCost& cost,
                                                     const Vector& mu0, const Vector& initial_std,
                                                     int horizon,
                                                     const std::vector<int>& angle_indices,
                                                     int num_basis, const Vector& max_control,
                                                     policy::PolicyClass policy_class =
                                                         policy::PolicyClass::kRbf,
                                                     const std::vector<int>& dynamics_inputs = {});

}  // namespace totalgrad::learner

#endif  // TOTALGRAD_CORE_LEARNER_PROBLEM_BUILDER_H_
