// The particle methods' learner: per episode, the GP (full, or FITC past
// gp_inducing points) on the trial's data, policy_steps gradient steps of
// the method's estimator with the paper's RMSprop-like optimiser, and the
// model-predicted cost of the optimised policy. With sin/cos features the GP
// and the policy see PILCO's features while the particles stay in the raw
// state (ModelProblem wraps both); with raw features they are used
// directly, exactly as before the option existed.
#include <cmath>
#include <memory>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/common/rng.h"
#include "core/estimators/estimator.h"
#include "core/learner/optimisation_diagnostics.h"
#include "core/learner/optimizer.h"
#include "core/learner/policy_learner.h"
#include "core/gaussian/angle_features.h"

namespace totalgrad::learner {
namespace {

// Stream indices inside a trial. Part of the reproducibility contract.
uint64_t StepStreamIndex(int episode, int step) {
  return static_cast<uint64_t>(episode) * 1000000ULL + static_cast<uint64_t>(step);
}
constexpr int kPredictedCostStep = 999999;

// The particles' mean and sample standard deviation (divisor P - 1; 0 for
// one particle) per time step t = 0..H and state dimension.
void PredictedStates(const estimators::Rollout& rollout, EpisodeTrajectories* out) {
  const int steps = static_cast<int>(rollout.steps.size());
  if (steps == 0) return;
  const int d = static_cast<int>(rollout.steps[0].state.cols());
  out->predicted_mean.resize(steps + 1, d);
  out->predicted_std.resize(steps + 1, d);
  for (int t = 0; t <= steps; ++t) {
    const RowMatrix& x = t < steps ? rollout.steps[t].state : rollout.steps[steps - 1].next_state;
    const Eigen::RowVectorXd mean = x.colwise().mean();
    out->predicted_mean.row(t) = mean;
    const Eigen::Index p = x.rows();
    if (p > 1) {
      out->predicted_std.row(t) =
          ((x.rowwise() - mean).colwise().squaredNorm() / static_cast<double>(p - 1)).cwiseSqrt();
    } else {
      out->predicted_std.row(t).setZero();
    }
  }
}

class ParticleLearner final : public PolicyLearner {
 public:
  ParticleLearner(const TrialOptions& options, const tasks::Scene& scene,
                  std::unique_ptr<estimators::Estimator> estimator, std::vector<int> angles,
                  ThreadPool* pool)
      : PolicyLearner(options, scene, std::move(angles)),
        estimator_(std::move(estimator)),
        pool_(pool),
        optimiser_(options.optimizer, policy_.num_parameters()) {
    Rng init_rng(options.seed, Stream::kPolicyInit);
    if (options.policy == policy::PolicyClass::kLinear) {
      policy_.linear().Initialize(policy::kLinearPolicyInitStd, &init_rng);
      return;
    }
    const int s_dim = scene.state_dim();
    const Vector centre_std = Vector::Constant(s_dim, options.policy_centre_std);
    if (angles_.empty()) {
      policy_.rbf().Initialize(scene.mu0, centre_std, options.policy_init_lengthscale, &init_rng);
      return;
    }
    // The same draws as the raw policy (centres ~ N(mu0, centre_std^2 I) in
    // the raw state), the centres then mapped to features; every feature
    // length-scale = policy_init_lengthscale.
    policy::RbfPolicy raw(options.basis_functions, s_dim, scene.max_control);
    raw.Initialize(scene.mu0, centre_std, options.policy_init_lengthscale, &init_rng);
    RowMatrix centres;
    gaussian::StatesToFeatures(raw.centres(), angles_, &centres);
    const int c = options.basis_functions;
    const int feature_dim = policy_.input_dim();
    Vector params(policy_.num_parameters());
    Eigen::Map<RowMatrix>(params.data(), c, feature_dim) = centres;
    params.segment(c * feature_dim, feature_dim).setConstant(std::log(options.policy_init_lengthscale));
    params.tail(raw.weights().size()) = raw.weights();
    policy_.set_parameters(params);
  }

  absl::Status ImprovePolicy(const GpTrainingSet& training_set, int e, TrialObserver* observer,
                             PhaseClock* clock, EpisodeResult* result) override {
    EpisodeTiming& timing = result->timing;
    // The full GP, or FITC once the data exceed gp_inducing points. Inducing
    // inputs as PILCO: a random subset the first time, then warm-started
    // from the last episode.
    Rng inducing_rng(options_.seed, Stream::kGpInit, static_cast<uint64_t>(e));
    const SparseModelFit sparse{InducingInputs(options_), &inducing_, &inducing_rng};
    absl::StatusOr<ModelProblem> model =
        ModelProblem::Build(training_set, *hyperparameters_, sparse, angles_, &policy_, scene_,
                            options_.model_noise_multiplier, pool_, GpOptions(options_));
    if (!model.ok())
      return absl::Status(model.status().code(), absl::StrCat("episode ", e, ": ", model.status().message()));
    if (model->jitter()) result->flags.gp_jitter = true;
    clock->Lap(&timing.model_cpu, &timing.model_wall);
    const estimators::Problem& problem = model->problem();

    estimators::EstimateOptions estimate_options;
    estimate_options.particles = options_.particles;
    optimiser_.Reset();
    estimators::GradientEstimate estimate;
    OptimisationDiagnostics diagnostics(options_.policy_steps > 0 ? options_.policy_steps : 1,
                                        options_.particles);
    Vector theta = policy_.parameters();
    for (int step = 0; step < options_.policy_steps; ++step) {
      if (observer != nullptr && observer->ShouldCancel())
        return absl::CancelledError(absl::StrCat("trial cancelled in episode ", e, " at step ", step));
      Rng particle_rng(options_.seed, Stream::kParticleNoise, StepStreamIndex(e, step));
      absl::Status status = estimator_->Estimate(problem, estimate_options, &particle_rng, &estimate);
      if (!status.ok()) return status;
      if (!estimate.finite) {
        ++result->flags.non_finite_gradients;
        continue;
      }
      ++timing.policy_steps;
      if (estimate.gradient.isZero(0.0)) result->flags.zero_gradient = true;
      optimiser_.Step(estimate.gradient, estimate.per_particle_variance, options_.particles, &theta);
      const double step_norm = (theta - policy_.parameters()).norm();
      diagnostics.AddStep(step, estimate, step_norm);
      if (observer != nullptr) observer->OnPolicyStep(e, step, estimate.objective, step_norm);
      policy_.set_parameters(theta);
    }
    diagnostics.Fill(result);
    clock->Lap(&timing.policy_cpu, &timing.policy_wall);
    estimators::Rollout rollout;
    Rng predicted_rng(options_.seed, Stream::kParticleNoise, StepStreamIndex(e, kPredictedCostStep));
    if (absl::Status status = estimators::SimulateParticles(
            problem, options_.predicted_cost_particles, {}, &predicted_rng, &rollout);
        !status.ok()) {
      return status;
    }
    clock->Lap(&timing.prediction_cpu, &timing.prediction_wall);
    result->predicted_cost = rollout.objective;
    PredictedStates(rollout, &result->trajectories);
    result->policy_parameters = policy_.parameters();
    return absl::OkStatus();
  }

  void SaveState(TrialCheckpoint* checkpoint) const override {
    PolicyLearner::SaveState(checkpoint);
    checkpoint->optimizer = optimiser_.state();
  }
  absl::Status RestoreState(const TrialCheckpoint& checkpoint) override {
    absl::Status status = PolicyLearner::RestoreState(checkpoint);
    if (!status.ok()) return status;
    if (!checkpoint.optimizer || checkpoint.optimizer->v.size() != policy_.num_parameters() ||
        checkpoint.optimizer->m.size() != policy_.num_parameters())
      return absl::InvalidArgumentError("trial checkpoint: no optimiser state of this policy's size");
    optimiser_.set_state(*checkpoint.optimizer);
    return absl::OkStatus();
  }

 private:
  std::unique_ptr<estimators::Estimator> estimator_;
  ThreadPool* pool_;  // may be null
  RmspropLike optimiser_;
};

}  // namespace

absl::StatusOr<std::unique_ptr<PolicyLearner>> MakeParticleLearner(const TrialOptions& options,
                                                                   const tasks::Scene& scene,
                                                                   ThreadPool* pool) {
  absl::StatusOr<std::unique_ptr<estimators::Estimator>> estimator =
      estimators::MakeEstimator(options.method, options.estimator);
  if (!estimator.ok()) return estimator.status();
  return std::unique_ptr<PolicyLearner>(
      new ParticleLearner(options, scene, *std::move(estimator), FeatureAngles(options, scene), pool));
}

}  // namespace totalgrad::learner
