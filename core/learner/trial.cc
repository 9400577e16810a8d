#include "core/learner/trial.h"

#include <algorithm>
#include <chrono>
#include <optional>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "core/common/blas.h"
#include "core/common/thread_pool.h"
#include "core/learner/checkpoint.h"
#include "core/estimators/estimator.h"
#include "core/estimators/particle_system.h"
#include "core/estimators/rollout.h"
#include "core/gp/fitc.h"
#include "core/pilco/angle_features.h"
#include "core/pilco/pilco.h"
#include "core/policy/rbf_policy.h"

namespace totalgrad::learner {
namespace {

// ---------------------------------------------------------------- options

std::string FormatDouble(double v) {
  char buffer[40];
  std::snprintf(buffer, sizeof(buffer), "%.17g", v);
  return buffer;
}

absl::Status ParseDouble(const std::string& key, const std::string& text, double* out) {
  double v;
  if (!absl::SimpleAtod(text, &v) || !std::isfinite(v))
    return absl::InvalidArgumentError(absl::StrCat("option '", key, "': '", text, "' is not a finite number"));
  *out = v;
  return absl::OkStatus();
}

absl::Status ParseInt(const std::string& key, const std::string& text, int* out) {
  int v;
  if (!absl::SimpleAtoi(text, &v)) {
    // A whole number too large for an int ("1e12", "3000000000") is out of
    // range, not "not an integer".
    double d;
    if (absl::SimpleAtod(text, &d) && std::isfinite(d) && d == std::floor(d) &&
        std::fabs(d) > std::numeric_limits<int>::max())
      return absl::InvalidArgumentError(absl::StrCat("option '", key, "': ", text,
                                                     " is out of range; counts are at most ",
                                                     std::numeric_limits<int>::max()));
    return absl::InvalidArgumentError(absl::StrCat("option '", key, "': '", text, "' is not an integer"));
  }
  *out = v;
  return absl::OkStatus();
}

absl::Status ParseBool(const std::string& key, const std::string& text, bool* out) {
  if (text == "true" || text == "1") { *out = true; return absl::OkStatus(); }
  if (text == "false" || text == "0") { *out = false; return absl::OkStatus(); }
  return absl::InvalidArgumentError(absl::StrCat("option '", key, "': '", text, "' is not true/false"));
}

struct OptionField {
  std::string key;
  std::function<absl::Status(const std::string&, TrialOptions*)> set;
  std::function<std::string(const TrialOptions&)> get;
};

OptionField DoubleField(const std::string& key, std::function<double*(TrialOptions*)> ref) {
  return {key,
          [key, ref](const std::string& text, TrialOptions* o) { return ParseDouble(key, text, ref(o)); },
          [ref](const TrialOptions& o) { return FormatDouble(*ref(const_cast<TrialOptions*>(&o))); }};
}
OptionField IntField(const std::string& key, std::function<int*(TrialOptions*)> ref) {
  return {key,
          [key, ref](const std::string& text, TrialOptions* o) { return ParseInt(key, text, ref(o)); },
          [ref](const TrialOptions& o) { return std::to_string(*ref(const_cast<TrialOptions*>(&o))); }};
}
OptionField StringField(const std::string& key, std::function<std::string*(TrialOptions*)> ref) {
  return {key,
          [ref](const std::string& text, TrialOptions* o) {
            *ref(o) = text;
            return absl::OkStatus();
          },
          [ref](const TrialOptions& o) { return *ref(const_cast<TrialOptions*>(&o)); }};
}

constexpr char kPilco[] = "PILCO";

std::vector<std::string> AllMethods() {
  std::vector<std::string> methods = estimators::ParticleMethods();
  methods.push_back(kPilco);
  return methods;
}

const std::vector<OptionField>& Fields() {
  static const std::vector<OptionField>* fields = new std::vector<OptionField>{
      StringField("scene", [](TrialOptions* o) { return &o->scene.scene; }),
      StringField("cost", [](TrialOptions* o) { return &o->scene.cost; }),
      DoubleField("noise_k", [](TrialOptions* o) { return &o->scene.noise_k; }),
      IntField("horizon", [](TrialOptions* o) { return &o->scene.horizon; }),
      DoubleField("initial_std", [](TrialOptions* o) { return &o->scene.initial_std; }),
      DoubleField("cart_mass", [](TrialOptions* o) { return &o->scene.plant.cart_mass; }),
      DoubleField("pole_mass", [](TrialOptions* o) { return &o->scene.plant.pole_mass; }),
      DoubleField("pole_length", [](TrialOptions* o) { return &o->scene.plant.pole_length; }),
      DoubleField("friction", [](TrialOptions* o) { return &o->scene.plant.friction; }),
      DoubleField("dt", [](TrialOptions* o) { return &o->scene.plant.dt; }),
      DoubleField("max_force", [](TrialOptions* o) { return &o->scene.plant.max_force; }),
      {"method",
       [](const std::string& text, TrialOptions* o) {
         const auto methods = AllMethods();
         for (const auto& m : methods) {
           if (m == text) {
             o->method = text;
             return absl::OkStatus();
           }
         }
         return absl::InvalidArgumentError(absl::StrCat("option 'method': unknown method '", text,
                                                        "'; known: ", absl::StrJoin(methods, ", ")));
       },
       [](const TrialOptions& o) { return o.method; }},
      {"seed",
       [](const std::string& text, TrialOptions* o) {
         uint64_t v;
         if (!absl::SimpleAtoi(text, &v))
           return absl::InvalidArgumentError(absl::StrCat("option 'seed': '", text, "' is not a non-negative integer"));
         o->seed = v;
         return absl::OkStatus();
       },
       [](const TrialOptions& o) { return std::to_string(o.seed); }},
      IntField("episodes", [](TrialOptions* o) { return &o->episodes; }),
      IntField("policy_steps", [](TrialOptions* o) { return &o->policy_steps; }),
      IntField("particles", [](TrialOptions* o) { return &o->particles; }),
      IntField("eval_rollouts", [](TrialOptions* o) { return &o->eval_rollouts; }),
      DoubleField("threshold", [](TrialOptions* o) { return &o->success_threshold; }),
      IntField("basis_functions", [](TrialOptions* o) { return &o->basis_functions; }),
      DoubleField("model_noise_multiplier", [](TrialOptions* o) { return &o->model_noise_multiplier; }),
      IntField("predicted_cost_particles", [](TrialOptions* o) { return &o->predicted_cost_particles; }),
      DoubleField("policy_init_lengthscale", [](TrialOptions* o) { return &o->policy_init_lengthscale; }),
      DoubleField("policy_centre_std", [](TrialOptions* o) { return &o->policy_centre_std; }),
      DoubleField("learning_rate", [](TrialOptions* o) { return &o->optimizer.learning_rate; }),
      DoubleField("momentum", [](TrialOptions* o) { return &o->optimizer.momentum; }),
      DoubleField("decay", [](TrialOptions* o) { return &o->optimizer.decay; }),
      DoubleField("epsilon", [](TrialOptions* o) { return &o->optimizer.epsilon; }),
      {"normalisation",
       [](const std::string& text, TrialOptions* o) {
         if (text == "particle_std") o->optimizer.normalisation = Normalisation::kParticleStd;
         else if (text == "mean_std") o->optimizer.normalisation = Normalisation::kMeanStd;
         else if (text == "rmsprop") o->optimizer.normalisation = Normalisation::kRmsprop;
         else
           return absl::InvalidArgumentError(absl::StrCat(
               "option 'normalisation': '", text, "' is not one of particle_std, mean_std, rmsprop"));
         return absl::OkStatus();
       },
       [](const TrialOptions& o) {
         switch (o.optimizer.normalisation) {
           case Normalisation::kParticleStd: return std::string("particle_std");
           case Normalisation::kMeanStd: return std::string("mean_std");
           case Normalisation::kRmsprop: return std::string("rmsprop");
         }
         return std::string();
       }},
      IntField("gp_iterations", [](TrialOptions* o) { return &o->gp_training.max_iterations; }),
      {"angle_features",
       [](const std::string& text, TrialOptions* o) {
         if (text != "auto" && text != "raw" && text != "sincos")
           return absl::InvalidArgumentError(
               absl::StrCat("option 'angle_features': '", text, "' is not one of auto, raw, sincos"));
         o->angle_features = text;
         return absl::OkStatus();
       },
       [](const TrialOptions& o) { return o.angle_features; }},
      IntField("gp_inducing", [](TrialOptions* o) { return &o->gp_inducing; }),
      {"gp_penalty",
       [](const std::string& text, TrialOptions* o) {
         return ParseBool("gp_penalty", text, &o->gp_training.penalty.enabled);
       },
       [](const TrialOptions& o) { return std::string(o.gp_training.penalty.enabled ? "true" : "false"); }},
      // Particle-estimator knobs (estimators/estimator.h EstimatorOptions).
      {"lr_weights",
       [](const std::string& text, TrialOptions* o) {
         return estimators::ParseLrWeights(text, &o->estimator.lr_weights);
       },
       [](const TrialOptions& o) { return estimators::LrWeightsName(o.estimator.lr_weights); }},
      {"lr_baseline",
       [](const std::string& text, TrialOptions* o) {
         return estimators::ParseLrBaseline(text, &o->estimator.lr_baseline);
       },
       [](const TrialOptions& o) { return estimators::LrBaselineName(o.estimator.lr_baseline); }},
      {"gs_derivative",
       [](const std::string& text, TrialOptions* o) {
         return estimators::ParseGsDerivative(text, &o->estimator.gs_derivative);
       },
       [](const TrialOptions& o) { return estimators::GsDerivativeName(o.estimator.gs_derivative); }},
      DoubleField("sn_noise_multiplier", [](TrialOptions* o) { return &o->estimator.sn_noise_multiplier; }),
  };
  return *fields;
}

// ---------------------------------------------------------------- trial

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

// Splits a trial's time into consecutive phases: each Lap adds the CPU and
// wall seconds since the previous Lap (or construction) to a phase's totals.
// CPU time is the trial thread's plus its pool's worker threads'.
class PhaseClock {
 public:
  explicit PhaseClock(const ThreadPool* pool) : pool_(pool) { Restart(); }
  void Restart() {
    cpu_ = Cpu();
    wall_ = std::chrono::steady_clock::now();
  }
  void Lap(double* cpu, double* wall) {
    const double cpu_now = Cpu();
    const auto wall_now = std::chrono::steady_clock::now();
    *cpu += cpu_now - cpu_;
    *wall += std::chrono::duration<double>(wall_now - wall_).count();
    cpu_ = cpu_now;
    wall_ = wall_now;
  }

 private:
  double Cpu() const { return ThreadCpuSeconds() + (pool_ != nullptr ? pool_->WorkerCpuSeconds() : 0.0); }
  const ThreadPool* pool_;
  double cpu_ = 0;
  std::chrono::steady_clock::time_point wall_;
};

// Stream indices inside a trial. Part of the reproducibility contract.
uint64_t StepStreamIndex(int episode, int step) {
  return static_cast<uint64_t>(episode) * 1000000ULL + static_cast<uint64_t>(step);
}
constexpr int kPredictedCostStep = 999999;

}  // namespace

absl::Status TrialOptions::Validate() const {
  auto bad = [](const std::string& field, const std::string& why) {
    return absl::InvalidArgumentError(absl::StrCat("option '", field, "' ", why));
  };
  if (episodes < 1) return bad("episodes", "must be >= 1");
  if (policy_steps < 0) return bad("policy_steps", "must be >= 0");
  if (particles < 1) return bad("particles", "must be >= 1");
  if (eval_rollouts < 1) return bad("eval_rollouts", "must be >= 1");
  if (basis_functions < 1) return bad("basis_functions", "must be >= 1");
  if (!(model_noise_multiplier >= 0) || !std::isfinite(model_noise_multiplier))
    return bad("model_noise_multiplier", "must be finite and >= 0");
  if (predicted_cost_particles < 1) return bad("predicted_cost_particles", "must be >= 1");
  if (!(policy_init_lengthscale > 0)) return bad("policy_init_lengthscale", "must be > 0");
  if (!(policy_centre_std >= 0)) return bad("policy_centre_std", "must be >= 0");
  if (!(optimizer.learning_rate > 0)) return bad("learning_rate", "must be > 0");
  if (!(optimizer.momentum >= 0 && optimizer.momentum < 1)) return bad("momentum", "must be in [0, 1)");
  if (!(optimizer.decay >= 0 && optimizer.decay < 1)) return bad("decay", "must be in [0, 1)");
  if (!(optimizer.epsilon >= 0)) return bad("epsilon", "must be >= 0");
  if (gp_training.max_iterations < 0) return bad("gp_iterations", "must be >= 0");
  if (!std::isfinite(success_threshold)) return bad("threshold", "must be finite");
  if (gp_inducing < -1) return bad("gp_inducing", "must be -1 (auto), 0 (full GP) or a count");
  if (angle_features != "auto" && angle_features != "raw" && angle_features != "sincos")
    return bad("angle_features", absl::StrCat("'", angle_features, "' is not one of auto, raw, sincos"));
  const auto methods = AllMethods();
  if (std::find(methods.begin(), methods.end(), method) == methods.end())
    return bad("method", absl::StrCat("'", method, "' is unknown; known: ", absl::StrJoin(methods, ", ")));
  return tasks::MakeScene(scene).status();
}

absl::Status SetTrialOption(const std::string& key, const std::string& value, TrialOptions* options) {
  for (const OptionField& field : Fields())
    if (field.key == key) return field.set(value, options);
  return absl::InvalidArgumentError(
      absl::StrCat("unknown option '", key, "'; known: ", absl::StrJoin(TrialOptionKeys(), ", ")));
}

std::vector<std::pair<std::string, std::string>> TrialOptionPairs(const TrialOptions& options) {
  std::vector<std::pair<std::string, std::string>> pairs;
  for (const OptionField& field : Fields()) pairs.emplace_back(field.key, field.get(options));
  return pairs;
}

std::vector<std::string> TrialOptionKeys() {
  std::vector<std::string> keys;
  for (const OptionField& field : Fields()) keys.push_back(field.key);
  return keys;
}

namespace {

// All real data of a trial: observed states, forces and observed next states.
struct TrialData {
  std::vector<Eigen::Matrix<double, 1, 4>> states;
  std::vector<double> forces;
  std::vector<Eigen::Matrix<double, 1, 4>> next_states;

  void Append(const tasks::Episode& episode) {
    for (Eigen::Index t = 0; t < episode.forces.size(); ++t) {
      states.push_back(episode.observations.row(t));
      forces.push_back(episode.forces(t));
      next_states.push_back(episode.observations.row(t + 1));
    }
  }
  RowMatrix States() const {
    RowMatrix m(states.size(), 4);
    for (size_t r = 0; r < states.size(); ++r) m.row(r) = states[r];
    return m;
  }
  RowMatrix Targets() const {
    RowMatrix m(states.size(), 4);
    for (size_t r = 0; r < states.size(); ++r) m.row(r) = next_states[r] - states[r];
    return m;
  }
};

// Fits the GP hyperparameters (warm-started in *hyperparameters) and records
// what happened in *result.
absl::Status TrainModel(const RowMatrix& inputs, const RowMatrix& targets, const TrialOptions& options,
                        int episode, std::optional<gp::GpHyperparameters>* hyperparameters,
                        EpisodeResult* result) {
  if (!*hyperparameters) *hyperparameters = gp::InitialHyperparameters(inputs, targets);
  absl::StatusOr<gp::TrainingSummary> training =
      gp::TrainHyperparameters(inputs, targets, options.gp_training, &**hyperparameters);
  if (!training.ok())
    return absl::Status(training.status().code(),
                        absl::StrCat("episode ", episode, ": GP training: ", training.status().message()));
  result->flags.gp_line_search_failures = training->line_search_failures;
  result->flags.gp_non_finite_evaluations = training->non_finite_evaluations;
  result->hyperparameters = **hyperparameters;
  return absl::OkStatus();
}

// How a method turns the data into a policy. One object per trial; its
// policy persists across episodes (warm start).
class PolicyLearner {
 public:
  virtual ~PolicyLearner() = default;
  // Fits the model on `data`, optimises the policy, fills the model- and
  // optimisation-related fields of *result, timing its phases with `clock`
  // (model, policy, prediction laps into result->timing).
  virtual absl::Status Improve(const TrialData& data, int episode, TrialObserver* observer,
                               PhaseClock* clock, EpisodeResult* result) = 0;
  // The current policy as a controller of the real plant (force in N).
  virtual double Control(const tasks::State& observation) const = 0;
  // The current policy's parameters (for snapshots).
  virtual Vector Parameters() const = 0;
  // What carries over to the next episode (checkpoint.h), and back.
  virtual void SaveState(TrialCheckpoint* checkpoint) const = 0;
  virtual absl::Status RestoreState(const TrialCheckpoint& checkpoint) = 0;
};

// Restores the warm starts every learner keeps: policy, GP hyperparameters
// and FITC inducing inputs.
absl::Status RestoreCommonState(const TrialCheckpoint& checkpoint, policy::RbfPolicy* policy,
                                std::optional<gp::GpHyperparameters>* hyperparameters,
                                RowMatrix* inducing) {
  if (checkpoint.policy_parameters.size() != policy->num_parameters())
    return absl::InvalidArgumentError(absl::StrCat(
        "trial checkpoint: the policy has ", checkpoint.policy_parameters.size(),
        " parameters; this trial's has ", policy->num_parameters()));
  policy->set_parameters(checkpoint.policy_parameters);
  *hyperparameters = checkpoint.hyperparameters;
  *inducing = checkpoint.inducing_inputs;
  return absl::OkStatus();
}

// Particle methods. With angle_index >= 0 (angle_features = sincos) the GP
// and the RBF policy see the features [x without x_a, sin x_a, cos x_a]
// (pilco/angle_features.h) while the particles stay in the raw state:
// estimators::AngleFeatureDynamics / AngleFeaturePolicy map between the two.
// With angle_index = -1 (raw, the default) the model and policy are used
// directly, exactly as before the option existed.
class ParticleLearner final : public PolicyLearner {
 public:
  ParticleLearner(const TrialOptions& options, const tasks::Scene& scene,
                  std::unique_ptr<estimators::Estimator> estimator, int angle_index,
                  ThreadPool* pool)
      : options_(options), scene_(scene), estimator_(std::move(estimator)), pool_(pool),
        angle_index_(angle_index),
        feature_dim_(pilco::FeatureDim(tasks::kCartPoleStateDim, angle_index)),
        policy_(options.basis_functions, feature_dim_, scene.plant.params().max_force),
        optimiser_(options.optimizer, policy_.num_parameters()) {
    Rng init_rng(options.seed, Stream::kPolicyInit);
    const Vector centre_std = Vector::Constant(tasks::kCartPoleStateDim, options.policy_centre_std);
    if (angle_index_ < 0) {
      policy_.Initialize(scene.mu0, centre_std, options.policy_init_lengthscale, &init_rng);
    } else {
      // The same draws as the raw policy (centres ~ N(mu0, centre_std^2 I) in
      // the raw state), the centres then mapped to features; every feature
      // length-scale = policy_init_lengthscale.
      policy::RbfPolicy raw(options.basis_functions, tasks::kCartPoleStateDim,
                            scene.plant.params().max_force);
      raw.Initialize(scene.mu0, centre_std, options.policy_init_lengthscale, &init_rng);
      RowMatrix centres;
      pilco::StatesToFeatures(raw.centres(), angle_index_, &centres);
      const int c = options.basis_functions;
      Vector params(policy_.num_parameters());
      Eigen::Map<RowMatrix>(params.data(), c, feature_dim_) = centres;
      params.segment(c * feature_dim_, feature_dim_)
          .setConstant(std::log(options.policy_init_lengthscale));
      params.tail(c) = raw.weights();
      policy_.set_parameters(params);
    }
  }

  absl::Status Improve(const TrialData& data, int e, TrialObserver* observer,
                       PhaseClock* clock, EpisodeResult* result) override {
    EpisodeTiming& timing = result->timing;
    const int s_dim = tasks::kCartPoleStateDim;
    const RowMatrix states = data.States();
    // GP inputs [x, u], or [features, u] as PILCO's (angle_features = sincos).
    RowMatrix x(states.rows(), feature_dim_ + 1);
    if (angle_index_ < 0) {
      x.leftCols(s_dim) = states;
    } else {
      RowMatrix features;
      pilco::StatesToFeatures(states, angle_index_, &features);
      x.leftCols(feature_dim_) = features;
    }
    for (Eigen::Index r = 0; r < x.rows(); ++r) x(r, feature_dim_) = data.forces[r];
    const RowMatrix y = data.Targets();
    absl::Status status = TrainModel(x, y, options_, e, &hyperparameters_, result);
    if (!status.ok()) return status;
    // The full GP, or FITC once the data exceed gp_inducing points (auto = -1
    // means the full GP for particle methods). Inducing inputs as PILCO: a
    // random subset the first time, then warm-started from the last episode.
    estimators::Problem problem;
    std::optional<gp::GpModel> full_model;
    std::optional<gp::FitcModel> sparse_model;
    std::optional<estimators::FitcDynamics> sparse_dynamics;
    const int num_inducing = std::max(options_.gp_inducing, 0);
    if (num_inducing > 0 && x.rows() > num_inducing) {
      gp::FitcFitOptions fit;
      fit.num_inducing = num_inducing;
      Rng inducing_rng(options_.seed, Stream::kGpInit, static_cast<uint64_t>(e));
      absl::StatusOr<gp::FitcModel> model =
          gp::FitFitcModel(x, y, *hyperparameters_, fit, &inducing_, &inducing_rng, nullptr);
      if (!model.ok())
        return absl::Status(model.status().code(),
                            absl::StrCat("episode ", e, ": FITC model: ", model.status().message()));
      sparse_model.emplace(*std::move(model));
      sparse_dynamics.emplace(&*sparse_model, pool_);
      problem.dynamics = &*sparse_dynamics;
    } else {
      absl::StatusOr<gp::GpModel> model = gp::GpModel::Create(x, y, *hyperparameters_);
      if (!model.ok())
        return absl::Status(model.status().code(),
                            absl::StrCat("episode ", e, ": GP model: ", model.status().message()));
      for (int a = 0; a < model->num_outputs(); ++a)
        if (model->jitter(a) > 0) result->flags.gp_jitter = true;
      full_model.emplace(*std::move(model));
      problem.model = &*full_model;
    }
    clock->Lap(&timing.model_cpu, &timing.model_wall);
    problem.policy = &policy_;
    problem.pool = pool_;
    // sin/cos features: the model and the policy behind the angle adapters
    // (particles, start distribution and cost stay in the raw state).
    std::optional<estimators::GpDynamics> full_dynamics;
    std::optional<estimators::AngleFeatureDynamics> angle_dynamics;
    std::optional<estimators::RbfParticlePolicy> rbf_controller;
    std::optional<estimators::AngleFeaturePolicy> angle_controller;
    if (angle_index_ >= 0) {
      const estimators::ParticleDynamics* inner = problem.dynamics;
      if (inner == nullptr) {
        full_dynamics.emplace(&*full_model, pool_);
        inner = &*full_dynamics;
      }
      angle_dynamics.emplace(inner, angle_index_);
      problem.dynamics = &*angle_dynamics;
      problem.model = nullptr;
      rbf_controller.emplace(&policy_, pool_);
      angle_controller.emplace(&*rbf_controller, angle_index_);
      problem.controller = &*angle_controller;
    }
    problem.cost = scene_.cost.get();
    problem.mu0 = scene_.mu0;
    problem.initial_std = scene_.initial_std;
    problem.horizon = scene_.horizon;
    problem.noise_variance_multiplier = options_.model_noise_multiplier;
    estimators::EstimateOptions estimate_options;
    estimate_options.particles = options_.particles;
    optimiser_.Reset();
    estimators::GradientEstimate estimate;
    Vector theta = policy_.parameters();
    for (int step = 0; step < options_.policy_steps; ++step) {
      if (observer != nullptr && observer->ShouldCancel())
        return absl::CancelledError(absl::StrCat("trial cancelled in episode ", e, " at step ", step));
      Rng particle_rng(options_.seed, Stream::kParticleNoise, StepStreamIndex(e, step));
      status = estimator_->Estimate(problem, estimate_options, &particle_rng, &estimate);
      if (!status.ok()) return status;
      if (!estimate.finite) {
        ++result->flags.non_finite_gradients;
        continue;
      }
      ++timing.policy_steps;
      if (estimate.gradient.isZero(0.0)) result->flags.zero_gradient = true;
      optimiser_.Step(estimate.gradient, estimate.per_particle_variance, options_.particles, &theta);
      if (observer != nullptr)
        observer->OnPolicyStep(e, step, estimate.objective, (theta - policy_.parameters()).norm());
      policy_.set_parameters(theta);
    }
    clock->Lap(&timing.policy_cpu, &timing.policy_wall);
    estimators::Rollout rollout;
    Rng predicted_rng(options_.seed, Stream::kParticleNoise, StepStreamIndex(e, kPredictedCostStep));
    status = estimators::SimulateParticles(problem, options_.predicted_cost_particles, {},
                                           &predicted_rng, &rollout);
    if (!status.ok()) return status;
    clock->Lap(&timing.prediction_cpu, &timing.prediction_wall);
    result->predicted_cost = rollout.objective;
    result->policy_parameters = policy_.parameters();
    return absl::OkStatus();
  }

  double Control(const tasks::State& observation) const override {
    Vector force;
    if (angle_index_ < 0) {
      policy_.Evaluate(observation.transpose(), &force, nullptr);
    } else {
      const Vector features = pilco::StateFeatures(observation, angle_index_);
      policy_.Evaluate(features.transpose(), &force, nullptr);
    }
    return force(0);
  }
  Vector Parameters() const override { return policy_.parameters(); }
  void SaveState(TrialCheckpoint* checkpoint) const override {
    checkpoint->policy_parameters = policy_.parameters();
    checkpoint->hyperparameters = hyperparameters_;
    checkpoint->inducing_inputs = inducing_;
    checkpoint->optimizer = optimiser_.state();
  }
  absl::Status RestoreState(const TrialCheckpoint& checkpoint) override {
    absl::Status status = RestoreCommonState(checkpoint, &policy_, &hyperparameters_, &inducing_);
    if (!status.ok()) return status;
    if (!checkpoint.optimizer || checkpoint.optimizer->v.size() != policy_.num_parameters() ||
        checkpoint.optimizer->m.size() != policy_.num_parameters())
      return absl::InvalidArgumentError("trial checkpoint: no optimiser state of this policy's size");
    optimiser_.set_state(*checkpoint.optimizer);
    return absl::OkStatus();
  }

 private:
  const TrialOptions& options_;
  const tasks::Scene& scene_;
  std::unique_ptr<estimators::Estimator> estimator_;
  ThreadPool* pool_;  // may be null
  int angle_index_;   // -1: raw state; 1: (sin, cos) of beta
  int feature_dim_;   // policy input dimension (4 or 5)
  policy::RbfPolicy policy_;
  RmspropLike optimiser_;
  std::optional<gp::GpHyperparameters> hyperparameters_;
  RowMatrix inducing_;  // FITC inducing inputs of the last sparse fit (warm start)
};

// PILCO: analytic moment matching and BFGS (core/pilco), on the features the
// angle option selects, with FITC once the data exceed gp_inducing points.
class PilcoLearner final : public PolicyLearner {
 public:
  PilcoLearner(const TrialOptions& options, const tasks::Scene& scene, int angle_index)
      : options_(options), scene_(scene), angle_index_(angle_index),
        feature_dim_(pilco::FeatureDim(tasks::kCartPoleStateDim, angle_index)),
        policy_(options.basis_functions, feature_dim_, scene.plant.params().max_force) {}

  absl::Status Init() {
    const tasks::StateCost& cost = *scene_.cost;
    absl::StatusOr<pilco::GaussianCost> gaussian_cost = absl::InvalidArgumentError("unknown cost");
    if (const auto* angle = dynamic_cast<const tasks::AngleCost*>(&cost)) {
      gaussian_cost = pilco::GaussianCost::Angle(angle->target(), angle->q_diagonal().asDiagonal().toDenseMatrix());
    } else if (const auto* tip = dynamic_cast<const tasks::TipCost*>(&cost)) {
      gaussian_cost = pilco::GaussianCost::Tip(tasks::kCartPoleStateDim, 0, 1, tip->pendulum_length(),
                                               tip->width(), tip->target_position());
    }
    if (!gaussian_cost.ok()) return gaussian_cost.status();
    problem_.mu0 = scene_.mu0;
    problem_.S0 = scene_.initial_std.array().square().matrix().asDiagonal();
    problem_.horizon = scene_.horizon;
    problem_.cost = std::make_shared<pilco::GaussianCost>(*std::move(gaussian_cost));
    problem_.propagation.angle_index = angle_index_;
    problem_.propagation.max_force = scene_.plant.params().max_force;
    problem_.propagation.num_basis = options_.basis_functions;
    Rng init_rng(options_.seed, Stream::kPolicyInit);
    absl::StatusOr<Vector> params = pilco::InitialPolicyParameters(problem_, &init_rng);
    if (!params.ok()) return params.status();
    policy_.set_parameters(*params);
    return absl::OkStatus();
  }

  absl::Status Improve(const TrialData& data, int e, TrialObserver* observer,
                       PhaseClock* clock, EpisodeResult* result) override {
    EpisodeTiming& timing = result->timing;
    const RowMatrix states = data.States();
    RowMatrix features;
    pilco::StatesToFeatures(states, angle_index_, &features);
    RowMatrix x(states.rows(), feature_dim_ + 1);
    x.leftCols(feature_dim_) = features;
    for (Eigen::Index r = 0; r < x.rows(); ++r) x(r, feature_dim_) = data.forces[r];
    const RowMatrix y = data.Targets();
    absl::Status status = TrainModel(x, y, options_, e, &hyperparameters_, result);
    if (!status.ok()) return status;
    pilco::DynamicsModelOptions model_options;
    model_options.num_inducing = options_.gp_inducing < 0 ? 300 : options_.gp_inducing;
    Rng inducing_rng(options_.seed, Stream::kGpInit, static_cast<uint64_t>(e));
    pilco::DynamicsModelReport report;
    absl::StatusOr<pilco::GaussianInputGp> model = pilco::BuildDynamicsModel(
        x, y, *hyperparameters_, model_options, &inducing_, &inducing_rng, &report);
    if (!model.ok())
      return absl::Status(model.status().code(),
                          absl::StrCat("episode ", e, ": PILCO model: ", model.status().message()));
    clock->Lap(&timing.model_cpu, &timing.model_wall);
    pilco::PilcoOptions pilco_options;
    bool cancelled = false;
    pilco_options.bfgs.should_stop = [observer, &cancelled]() {
      cancelled = observer != nullptr && observer->ShouldCancel();
      return cancelled;
    };
    Vector params = policy_.parameters();
    absl::StatusOr<pilco::PilcoResult> optimised = pilco::OptimizePolicy(*model, problem_, pilco_options, &params);
    if (cancelled) return absl::CancelledError(absl::StrCat("trial cancelled in episode ", e));
    if (!optimised.ok())
      return absl::Status(optimised.status().code(),
                          absl::StrCat("episode ", e, ": PILCO optimisation: ", optimised.status().message()));
    policy_.set_parameters(params);
    clock->Lap(&timing.policy_cpu, &timing.policy_wall);
    result->predicted_cost = optimised->prediction.total_cost;
    result->predicted_cost_mean_per_step = optimised->prediction.cost_mean;
    result->predicted_cost_std_per_step = optimised->prediction.cost_std;
    result->policy_parameters = params;
    return absl::OkStatus();
  }

  double Control(const tasks::State& observation) const override {
    const Vector features = pilco::StateFeatures(observation, angle_index_);
    Vector force;
    policy_.Evaluate(features.transpose(), &force, nullptr);
    return force(0);
  }
  Vector Parameters() const override { return policy_.parameters(); }
  void SaveState(TrialCheckpoint* checkpoint) const override {
    checkpoint->policy_parameters = policy_.parameters();
    checkpoint->hyperparameters = hyperparameters_;
    checkpoint->inducing_inputs = inducing_;
  }
  absl::Status RestoreState(const TrialCheckpoint& checkpoint) override {
    return RestoreCommonState(checkpoint, &policy_, &hyperparameters_, &inducing_);
  }

 private:
  const TrialOptions& options_;
  const tasks::Scene& scene_;
  int angle_index_;
  int feature_dim_;
  policy::RbfPolicy policy_;
  pilco::PilcoProblem problem_;
  RowMatrix inducing_;
  std::optional<gp::GpHyperparameters> hyperparameters_;
};

}  // namespace

absl::StatusOr<TrialSummary> RunTrial(const TrialOptions& options, TrialObserver* observer,
                                      const RunOptions& run) {
  return RunTrial(options, observer, nullptr, run);
}

absl::StatusOr<TrialSummary> RunTrial(const TrialOptions& options, TrialObserver* observer,
                                      const TrialCheckpoint* resume_from, const RunOptions& run) {
  absl::Status status = options.Validate();
  if (!status.ok()) return status;
  if (run.threads < 1) return absl::InvalidArgumentError("threads must be >= 1");
  if (resume_from != nullptr) {
    status = CheckResumable(*resume_from, options);
    if (!status.ok()) return status;
  }
  std::unique_ptr<ThreadPool> pool;
  if (run.threads > 1) pool = std::make_unique<ThreadPool>(run.threads);
  // Results must not depend on how many threads the BLAS would use on this
  // machine (a multi-threaded gemm sums in another order): one thread.
  SetBlasThreads(1);
  absl::StatusOr<tasks::Scene> scene_or = tasks::MakeScene(options.scene);
  if (!scene_or.ok()) return scene_or.status();
  const tasks::Scene& scene = *scene_or;
  const uint64_t seed = options.seed;

  std::unique_ptr<PolicyLearner> learner;
  if (options.method == kPilco) {
    const int angle_index = options.angle_features == "raw" ? -1 : 1;  // beta is state index 1
    auto pilco_learner = std::make_unique<PilcoLearner>(options, scene, angle_index);
    status = pilco_learner->Init();
    if (!status.ok()) return status;
    learner = std::move(pilco_learner);
  } else {
    absl::StatusOr<std::unique_ptr<estimators::Estimator>> estimator =
        estimators::MakeEstimator(options.method, options.estimator);
    if (!estimator.ok()) return estimator.status();
    // Particle methods: raw unless asked for sincos ("auto" = raw).
    const int angle_index = options.angle_features == "sincos" ? 1 : -1;
    learner = std::make_unique<ParticleLearner>(options, scene, *std::move(estimator), angle_index,
                                                pool.get());
  }
  const tasks::Controller policy_controller = [&learner](const tasks::State& observation) {
    return learner->Control(observation);
  };

  TrialData data;
  TrialSummary summary;
  const bool checkpoints = observer != nullptr && observer->WantsCheckpoints();
  // After episode e: everything the next episode reads (checkpoint.h).
  const auto emit_checkpoint = [&](int e) {
    TrialCheckpoint c;
    c.episode = e;
    c.options = TrialOptionPairs(options);
    c.episodes = summary.episodes;
    c.states = data.States();
    c.forces = Eigen::Map<const Vector>(data.forces.data(), static_cast<Eigen::Index>(data.forces.size()));
    c.next_states.resize(c.states.rows(), 4);
    for (Eigen::Index r = 0; r < c.next_states.rows(); ++r) c.next_states.row(r) = data.next_states[r];
    learner->SaveState(&c);
    observer->OnCheckpoint(c);
  };
  int first_episode = 1;
  if (resume_from != nullptr) {
    // Resume: the data, warm starts and results of episodes 0..k as they were.
    for (Eigen::Index r = 0; r < resume_from->forces.size(); ++r) {
      data.states.push_back(resume_from->states.row(r));
      data.forces.push_back(resume_from->forces(r));
      data.next_states.push_back(resume_from->next_states.row(r));
    }
    status = learner->RestoreState(*resume_from);
    if (!status.ok()) return status;
    summary.episodes = resume_from->episodes;
    if (observer != nullptr)
      for (const EpisodeResult& result : summary.episodes) observer->OnEpisode(result);
    first_episode = resume_from->episode + 1;
  }

  // Episode 0: random exploration (unless resuming).
  if (resume_from == nullptr) {
    PhaseClock clock(pool.get());
    Rng action_rng(seed, Stream::kExplorationAction);
    const double max_force = scene.plant.params().max_force;
    const tasks::Controller random_controller = [&](const tasks::State&) {
      return action_rng.Uniform(-max_force, max_force);
    };
    Rng start_rng(seed, Stream::kInitialState, 0), noise_rng(seed, Stream::kObservationNoise, 0);
    tasks::Episode episode;
    status = tasks::RunEpisode(scene, random_controller, &start_rng, &noise_rng, &episode);
    if (!status.ok()) return absl::InternalError(absl::StrCat("episode 0: ", status.message()));
    data.Append(episode);
    EpisodeResult result;
    result.episode = 0;
    result.real_cost = episode.total_cost;
    clock.Lap(&result.timing.real_episode_cpu, &result.timing.real_episode_wall);
    result.cpu_seconds = result.timing.total_cpu();
    summary.episodes.push_back(result);
    if (observer != nullptr) observer->OnEpisode(result);
    if (checkpoints) emit_checkpoint(0);
  }

  for (int e = first_episode; e <= options.episodes; ++e) {
    EpisodeResult result;
    result.episode = e;
    const auto start_time = std::chrono::steady_clock::now();
    PhaseClock clock(pool.get());
    // 1-2. Fit the model on all data so far and optimise the policy.
    const bool snapshot = observer != nullptr && observer->WantsSnapshot(e);
    const Vector policy_before = snapshot ? learner->Parameters() : Vector();
    status = learner->Improve(data, e, observer, &clock, &result);
    if (!status.ok()) return status;
    result.optimisation_seconds = Seconds(start_time);
    if (snapshot) {
      TrialSnapshot s;
      s.episode = e;
      s.options = TrialOptionPairs(options);
      s.states = data.States();
      s.forces = Eigen::Map<const Vector>(data.forces.data(), static_cast<Eigen::Index>(data.forces.size()));
      s.next_states.resize(s.states.rows(), s.states.cols());
      for (Eigen::Index r = 0; r < s.next_states.rows(); ++r) s.next_states.row(r) = data.next_states[r];
      s.hyperparameters = result.hyperparameters;
      s.policy_parameters_before = policy_before;
      s.policy_parameters = result.policy_parameters;
      observer->OnSnapshot(s);
    }
    clock.Restart();  // the snapshot copy above is not the trial's work

    // 3. One real episode with the new policy; its data are added.
    {
      Rng start_rng(seed, Stream::kInitialState, e), noise_rng(seed, Stream::kObservationNoise, e);
      tasks::Episode episode;
      status = tasks::RunEpisode(scene, policy_controller, &start_rng, &noise_rng, &episode);
      if (!status.ok()) return absl::InternalError(absl::StrCat("episode ", e, ": ", status.message()));
      data.Append(episode);
      result.real_cost = episode.total_cost;
    }
    clock.Lap(&result.timing.real_episode_cpu, &result.timing.real_episode_wall);

    // 4. Evaluate the policy on independent real episodes (not added to the data).
    {
      double sum = 0, sum_sq = 0;
      for (int r = 0; r < options.eval_rollouts; ++r) {
        const uint64_t index = static_cast<uint64_t>(e) * 100000ULL + static_cast<uint64_t>(r);
        Rng start_rng(seed, Stream::kEvaluation, 2 * index), noise_rng(seed, Stream::kEvaluation, 2 * index + 1);
        tasks::Episode episode;
        status = tasks::RunEpisode(scene, policy_controller, &start_rng, &noise_rng, &episode);
        if (!status.ok())
          return absl::InternalError(absl::StrCat("episode ", e, " evaluation ", r, ": ", status.message()));
        sum += episode.total_cost;
        sum_sq += episode.total_cost * episode.total_cost;
      }
      const double n = options.eval_rollouts;
      result.eval_cost_mean = sum / n;
      result.eval_cost_std = n > 1 ? std::sqrt(std::max(0.0, (sum_sq - sum * sum / n) / (n - 1))) : 0.0;
    }
    clock.Lap(&result.timing.evaluation_cpu, &result.timing.evaluation_wall);
    result.cpu_seconds = result.timing.total_cpu();
    summary.episodes.push_back(result);
    if (observer != nullptr) observer->OnEpisode(result);
    if (checkpoints) emit_checkpoint(e);
  }
  summary.final_eval_cost = summary.episodes.back().eval_cost_mean;
  summary.success = summary.final_eval_cost < options.success_threshold;
  return summary;
}

}  // namespace totalgrad::learner
