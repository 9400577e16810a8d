#include "core/learner/trial.h"

#include <algorithm>
#include <chrono>
#include <optional>
#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "core/estimators/estimator.h"
#include "core/estimators/rollout.h"
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
  if (!absl::SimpleAtoi(text, &v))
    return absl::InvalidArgumentError(absl::StrCat("option '", key, "': '", text, "' is not an integer"));
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

std::vector<std::string> AllMethods() {
  std::vector<std::string> methods = estimators::ParticleMethods();
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
      {"gp_penalty",
       [](const std::string& text, TrialOptions* o) {
         return ParseBool("gp_penalty", text, &o->gp_training.penalty.enabled);
       },
       [](const TrialOptions& o) { return std::string(o.gp_training.penalty.enabled ? "true" : "false"); }},
  };
  return *fields;
}

// ---------------------------------------------------------------- trial

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

void AppendEpisodeData(const tasks::Episode& episode, std::vector<Eigen::Matrix<double, 1, 5>>* inputs,
                       std::vector<Eigen::Matrix<double, 1, 4>>* targets) {
  const Eigen::Index h = episode.forces.size();
  for (Eigen::Index t = 0; t < h; ++t) {
    Eigen::Matrix<double, 1, 5> in;
    in.head<4>() = episode.observations.row(t);
    in(4) = episode.forces(t);
    inputs->push_back(in);
    targets->push_back(episode.observations.row(t + 1) - episode.observations.row(t));
  }
}

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

absl::StatusOr<TrialSummary> RunTrial(const TrialOptions& options, TrialObserver* observer) {
  absl::Status status = options.Validate();
  if (!status.ok()) return status;
  absl::StatusOr<tasks::Scene> scene_or = tasks::MakeScene(options.scene);
  if (!scene_or.ok()) return scene_or.status();
  const tasks::Scene& scene = *scene_or;
  const int s_dim = tasks::kCartPoleStateDim;
  const uint64_t seed = options.seed;

  absl::StatusOr<std::unique_ptr<estimators::Estimator>> estimator_or =
      estimators::MakeEstimator(options.method, options.estimator);
  if (!estimator_or.ok()) return estimator_or.status();
  estimators::Estimator& estimator = **estimator_or;

  policy::RbfPolicy policy(options.basis_functions, s_dim, scene.plant.params().max_force);
  {
    Rng init_rng(seed, Stream::kPolicyInit);
    policy.Initialize(scene.mu0, Vector::Constant(s_dim, options.policy_centre_std),
                      options.policy_init_lengthscale, &init_rng);
  }
  const tasks::Controller policy_controller = [&policy](const tasks::State& observation) {
    Vector force;
    policy.Evaluate(observation.transpose(), &force, nullptr);
    return force(0);
  };

  std::vector<Eigen::Matrix<double, 1, 5>> inputs;
  std::vector<Eigen::Matrix<double, 1, 4>> targets;
  TrialSummary summary;

  // Episode 0: random exploration.
  {
    Rng action_rng(seed, Stream::kExplorationAction);
    const double max_force = scene.plant.params().max_force;
    const tasks::Controller random_controller = [&](const tasks::State&) {
      return action_rng.Uniform(-max_force, max_force);
    };
    Rng start_rng(seed, Stream::kInitialState, 0), noise_rng(seed, Stream::kObservationNoise, 0);
    tasks::Episode episode;
    status = tasks::RunEpisode(scene, random_controller, &start_rng, &noise_rng, &episode);
    if (!status.ok()) return absl::InternalError(absl::StrCat("episode 0: ", status.message()));
    AppendEpisodeData(episode, &inputs, &targets);
    EpisodeResult result;
    result.episode = 0;
    result.real_cost = episode.total_cost;
    summary.episodes.push_back(result);
    if (observer != nullptr) observer->OnEpisode(result);
  }

  std::optional<gp::GpHyperparameters> hyperparameters;
  RmspropLike optimiser(options.optimizer, policy.num_parameters());
  for (int e = 1; e <= options.episodes; ++e) {
    EpisodeResult result;
    result.episode = e;
    const auto start_time = std::chrono::steady_clock::now();

    // 1. Fit the dynamics model on all data so far.
    RowMatrix x(inputs.size(), s_dim + 1), y(targets.size(), s_dim);
    for (size_t r = 0; r < inputs.size(); ++r) {
      x.row(r) = inputs[r];
      y.row(r) = targets[r];
    }
    if (!hyperparameters) hyperparameters = gp::InitialHyperparameters(x, y);
    absl::StatusOr<gp::TrainingSummary> training =
        gp::TrainHyperparameters(x, y, options.gp_training, &*hyperparameters);
    if (!training.ok())
      return absl::Status(training.status().code(),
                          absl::StrCat("episode ", e, ": GP training: ", training.status().message()));
    result.flags.gp_line_search_failures = training->line_search_failures;
    result.flags.gp_non_finite_evaluations = training->non_finite_evaluations;
    absl::StatusOr<gp::GpModel> model = gp::GpModel::Create(x, y, *hyperparameters);
    if (!model.ok())
      return absl::Status(model.status().code(),
                          absl::StrCat("episode ", e, ": GP model: ", model.status().message()));
    for (int a = 0; a < model->num_outputs(); ++a)
      if (model->jitter(a) > 0) result.flags.gp_jitter = true;
    result.hyperparameters = *hyperparameters;

    // 2. Optimise the policy on the model.
    estimators::Problem problem;
    problem.model = &*model;
    problem.policy = &policy;
    problem.cost = scene.cost.get();
    problem.mu0 = scene.mu0;
    problem.initial_std = scene.initial_std;
    problem.horizon = scene.horizon;
    problem.noise_variance_multiplier = options.model_noise_multiplier;
    estimators::EstimateOptions estimate_options;
    estimate_options.particles = options.particles;
    optimiser.Reset();
    estimators::GradientEstimate estimate;
    Vector theta = policy.parameters();
    for (int step = 0; step < options.policy_steps; ++step) {
      if (observer != nullptr && observer->ShouldCancel())
        return absl::CancelledError(absl::StrCat("trial cancelled in episode ", e, " at step ", step));
      Rng particle_rng(seed, Stream::kParticleNoise, StepStreamIndex(e, step));
      status = estimator.Estimate(problem, estimate_options, &particle_rng, &estimate);
      if (!status.ok()) return status;
      if (!estimate.finite) {
        ++result.flags.non_finite_gradients;
        continue;
      }
      if (estimate.gradient.isZero(0.0)) result.flags.zero_gradient = true;
      optimiser.Step(estimate.gradient, estimate.per_particle_variance, options.particles, &theta);
      if (observer != nullptr)
        observer->OnPolicyStep(e, step, estimate.objective, (theta - policy.parameters()).norm());
      policy.set_parameters(theta);
    }
    {
      estimators::Rollout rollout;
      Rng predicted_rng(seed, Stream::kParticleNoise, StepStreamIndex(e, kPredictedCostStep));
      status = estimators::SimulateParticles(problem, options.predicted_cost_particles, {}, &predicted_rng,
                                             &rollout);
      if (!status.ok()) return status;
      result.predicted_cost = rollout.objective;
    }
    result.optimisation_seconds = Seconds(start_time);
    result.policy_parameters = policy.parameters();

    // 3. One real episode with the new policy; its data are added.
    {
      Rng start_rng(seed, Stream::kInitialState, e), noise_rng(seed, Stream::kObservationNoise, e);
      tasks::Episode episode;
      status = tasks::RunEpisode(scene, policy_controller, &start_rng, &noise_rng, &episode);
      if (!status.ok()) return absl::InternalError(absl::StrCat("episode ", e, ": ", status.message()));
      AppendEpisodeData(episode, &inputs, &targets);
      result.real_cost = episode.total_cost;
    }

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
    summary.episodes.push_back(result);
    if (observer != nullptr) observer->OnEpisode(result);
  }
  summary.final_eval_cost = summary.episodes.back().eval_cost_mean;
  summary.success = summary.final_eval_cost < options.success_threshold;
  return summary;
}

}  // namespace totalgrad::learner
