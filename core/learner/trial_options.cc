#include "core/learner/trial_options.h"

#include <algorithm>
#include <cmath>

#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "core/common/status_context.h"

namespace totalgrad::learner {

const EnumNames<AngleFeatures>& AngleFeaturesNames() {
  static const EnumNames<AngleFeatures>* names = new EnumNames<AngleFeatures>{
      {AngleFeatures::kAuto, "auto"}, {AngleFeatures::kRaw, "raw"}, {AngleFeatures::kSinCos, "sincos"}};
  return *names;
}

const OptionTable<TrialOptions>& TrialOptions::Table() {
  using O = TrialOptions;
  static const OptionTable<O>* table = [] {
    auto* t = new OptionTable<O>();
    t->Nest(&O::scene, tasks::SceneOptions::Table())
        .Custom(
            "method",
            [](absl::string_view text, O* o) {
              absl::StatusOr<estimators::Method> method = estimators::ParseMethod(text);
              if (!method.ok())
                return absl::InvalidArgumentError(absl::StrCat("option 'method': ", method.status().message()));
              o->method = *method;
              return absl::OkStatus();
            },
            [](const O& o) { return estimators::MethodName(o.method); }, OptionType::kChoice,
            [] {
              std::vector<std::string> names;
              for (const auto& entry : estimators::MethodNames()) names.push_back(entry.second);
              return names;
            }())
        .Uint64("seed", &O::seed)
        .Int("episodes", &O::episodes)
        .Int("policy_steps", &O::policy_steps)
        .Int("particles", &O::particles)
        .Int("eval_rollouts", &O::eval_rollouts)
        .Double("threshold", &O::success_threshold)
        .Int("verdict_rollouts", &O::verdict_rollouts)
        .Double("verdict_distance", &O::verdict_distance)
        .Double("verdict_hold_seconds", &O::verdict_hold_seconds)
        .Int("basis_functions", &O::basis_functions)
        .Double("model_noise_multiplier", &O::model_noise_multiplier)
        .Int("predicted_cost_particles", &O::predicted_cost_particles)
        .Double("policy_init_lengthscale", &O::policy_init_lengthscale)
        .Double("policy_centre_std", &O::policy_centre_std)
        .Nest(&O::optimizer, OptimizerOptions::Table())
        .Nest(&O::gp_training, gp::TrainingOptions::Table())
        .Enum("angle_features", &O::angle_features, AngleFeaturesNames())
        .Int("gp_inducing", &O::gp_inducing)
        .Double("gp_variance_tolerance", &O::gp_variance_tolerance)
        .Int("pilco_line_searches", &O::pilco_line_searches)
        .Int("pilco_evaluations_per_line_search", &O::pilco_evaluations_per_line_search)
        .Nest(&O::estimator, estimators::EstimatorOptions::Table())
        .Enum("policy", &O::policy, policy::PolicyClassNames());
    return t;
  }();
  return *table;
}

absl::Status TrialOptions::Validate() const {
  if (episodes < 1) return InvalidOption("episodes", "must be >= 1");
  if (policy_steps < 0) return InvalidOption("policy_steps", "must be >= 0");
  if (particles < 1) return InvalidOption("particles", "must be >= 1");
  if (eval_rollouts < 1) return InvalidOption("eval_rollouts", "must be >= 1");
  if (basis_functions < 1) return InvalidOption("basis_functions", "must be >= 1");
  if (!(model_noise_multiplier >= 0) || !std::isfinite(model_noise_multiplier))
    return InvalidOption("model_noise_multiplier", "must be finite and >= 0");
  if (predicted_cost_particles < 1) return InvalidOption("predicted_cost_particles", "must be >= 1");
  if (!(policy_init_lengthscale > 0)) return InvalidOption("policy_init_lengthscale", "must be > 0");
  if (!(policy_centre_std >= 0)) return InvalidOption("policy_centre_std", "must be >= 0");
  if (absl::Status st = optimizer.Validate(); !st.ok()) return st;
  if (absl::Status st = gp_training.Validate(); !st.ok()) return st;
  if (!std::isfinite(success_threshold)) return InvalidOption("threshold", "must be finite");
  if (gp_inducing < -1) return InvalidOption("gp_inducing", "must be -1 (auto), 0 (full GP) or a count");
  if (!std::isfinite(gp_variance_tolerance) || !(gp_variance_tolerance >= 0) ||
      !(gp_variance_tolerance < 1))
    return InvalidOption("gp_variance_tolerance", "must be finite, >= 0 and < 1 (0 = exact variance)");
  if (pilco_line_searches == 0 || pilco_line_searches < -1)
    return InvalidOption("pilco_line_searches", "must be -1 (the scene's PILCO protocol) or >= 1");
  if (pilco_evaluations_per_line_search == 0 || pilco_evaluations_per_line_search < -1)
    return InvalidOption("pilco_evaluations_per_line_search",
                         "must be -1 (the scene's PILCO protocol) or >= 1");
  if (!IsNamedEnum(policy::PolicyClassNames(), policy)) return InvalidOption("policy", "is not rbf or linear");
  if (!IsNamedEnum(AngleFeaturesNames(), angle_features))
    return InvalidOption("angle_features", "is not one of auto, raw, sincos");
  if (!IsNamedEnum(estimators::MethodNames(), method)) return InvalidOption("method", "is not a known method");
  if (absl::Status st = estimator.Validate(); !st.ok()) return st;
  if (verdict_rollouts < 0) return InvalidOption("verdict_rollouts", "must be >= 0 (0 = no rollout verdict)");
  if (!std::isfinite(verdict_distance) || !(verdict_distance > 0))
    return InvalidOption("verdict_distance", "must be finite and > 0 (metres from the goal)");
  if (!std::isfinite(verdict_hold_seconds) || !(verdict_hold_seconds > 0))
    return InvalidOption("verdict_hold_seconds", "must be finite and > 0");
  absl::StatusOr<tasks::Scene> made = tasks::MakeScene(scene);
  if (!made.ok()) return made.status();
  return absl::OkStatus();
}

bool UsesSinCosFeatures(estimators::Method method, AngleFeatures choice, bool cartpole_scene) {
  switch (choice) {
    case AngleFeatures::kSinCos: return true;
    case AngleFeatures::kRaw: return false;
    case AngleFeatures::kAuto: return method == estimators::Method::kPilco || !cartpole_scene;
  }
  return false;
}

bool UsesSinCosFeatures(const TrialOptions& options) {
  const tasks::SceneDefinition* scene = tasks::FindSceneDefinition(options.scene.scene);
  const bool cartpole = scene == nullptr || scene->plant == tasks::PlantKind::kCartPole;
  return UsesSinCosFeatures(options.method, options.angle_features, cartpole);
}

std::vector<int> FeatureAngles(const TrialOptions& options, const tasks::Scene& scene) {
  return UsesSinCosFeatures(options) ? scene.angle_indices : std::vector<int>();
}

int InducingInputs(const TrialOptions& options) {
  if (options.gp_inducing >= 0) return options.gp_inducing;
  const tasks::SceneDefinition* scene = tasks::FindSceneDefinition(options.scene.scene);
  if (scene != nullptr && scene->plant != tasks::PlantKind::kCartPole) return scene->inducing_inputs;
  return options.method == estimators::Method::kPilco ? 300 : 0;
}

gp::GpModelOptions GpOptions(const TrialOptions& options) {
  gp::GpModelOptions gp_options;
  gp_options.variance_rank_tolerance = options.gp_variance_tolerance;
  return gp_options;
}

absl::Status SameEpisodes(const TrialOptions& a, const TrialOptions& b) {
  TrialOptions b_with_a_verdict = b;
  b_with_a_verdict.verdict_rollouts = a.verdict_rollouts;
  b_with_a_verdict.verdict_distance = a.verdict_distance;
  b_with_a_verdict.verdict_hold_seconds = a.verdict_hold_seconds;
  const auto ours = TrialOptionPairs(a);
  const auto theirs = TrialOptionPairs(b_with_a_verdict);
  for (size_t i = 0; i < ours.size() && i < theirs.size(); ++i) {
    if (ours[i] != theirs[i]) {
      return absl::InvalidArgumentError(absl::StrCat("option ", ours[i].first, " is '",
                                                     ours[i].second, "' in one, '",
                                                     theirs[i].second, "' in the other"));
    }
  }
  return absl::OkStatus();
}

int VerdictHoldSteps(const TrialOptions& options, const tasks::Scene& scene) {
  const double steps = std::round(options.verdict_hold_seconds / scene.plant->dt());
  // At least the last step; at most the whole episode (a short horizon, e.g.
  // a test's, is held over all of it).
  return static_cast<int>(std::clamp(steps, 1.0, static_cast<double>(scene.horizon)));
}

int PilcoLineSearches(const TrialOptions& options) {
  if (options.pilco_line_searches >= 1) return options.pilco_line_searches;
  const tasks::SceneDefinition* scene = tasks::FindSceneDefinition(options.scene.scene);
  return scene != nullptr ? scene->line_searches : 150;
}

int PilcoEvaluationsPerLineSearch(const TrialOptions& options) {
  if (options.pilco_evaluations_per_line_search >= 1) return options.pilco_evaluations_per_line_search;
  const tasks::SceneDefinition* scene = tasks::FindSceneDefinition(options.scene.scene);
  return scene != nullptr ? scene->evaluations_per_line_search : 30;
}

absl::Status SetTrialOption(const std::string& key, const std::string& value, TrialOptions* options) {
  return TrialOptions::Table().Set(key, value, options);
}

std::vector<std::pair<std::string, std::string>> TrialOptionPairs(const TrialOptions& options) {
  return TrialOptions::Table().Pairs(options);
}

std::vector<std::string> TrialOptionKeys() { return TrialOptions::Table().Keys(); }

namespace {

// Sets `pairs` on top of `base`, in order.
absl::StatusOr<TrialOptions> ApplyPairs(TrialOptions base,
                                        const std::vector<std::pair<std::string, std::string>>& pairs) {
  for (const auto& [key, value] : pairs)
    if (absl::Status st = SetTrialOption(key, value, &base); !st.ok()) return st;
  return base;
}

}  // namespace

const std::vector<std::string>& SceneDefaultedKeys() {
  static const std::vector<std::string>* keys =
      new std::vector<std::string>{"horizon", "threshold", "cost", "policy"};
  return *keys;
}

absl::StatusOr<TrialOptions> TrialOptionsFromPairs(
    const std::vector<std::pair<std::string, std::string>>& pairs) {
  absl::StatusOr<TrialOptions> options = ApplyPairs(TrialOptions{}, pairs);
  if (!options.ok()) return options;
  // An unknown name is left to MakeScene, which names it with the rest.
  if (tasks::FindSceneDefinition(options->scene.scene) == nullptr) return options;
  absl::StatusOr<const tasks::SceneDefinition*> runnable =
      tasks::RunnableScene(options->scene.scene, "trials");
  if (!runnable.ok()) return WithContext(runnable.status(), "scene");
  const tasks::SceneDefinition* scene = *runnable;
  const auto given = [&pairs](const std::string& key) {
    return std::any_of(pairs.begin(), pairs.end(), [&key](const auto& pair) { return pair.first == key; });
  };
  if (!given("horizon")) options->scene.horizon = scene->horizon;
  if (!given("threshold")) options->success_threshold = scene->success_threshold;
  if (!given("cost")) options->scene.cost = scene->default_cost;
  if (!given("policy"))
    options->policy = scene->policy_class == "linear" ? policy::PolicyClass::kLinear
                                                      : policy::PolicyClass::kRbf;
  return options;
}

absl::StatusOr<TrialOptions> TrialOptionsFromStoredPairs(
    const std::vector<std::pair<std::string, std::string>>& pairs) {
  // The keys added after pairs were first stored start at their pre-change value.
  TrialOptions base;
  base.gp_variance_tolerance = kAbsentGpVarianceTolerance;
  base.verdict_rollouts = kAbsentVerdictRollouts;
  return ApplyPairs(base, pairs);
}

}  // namespace totalgrad::learner
