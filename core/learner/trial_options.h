// What a policy-learning trial computes (learner::RunTrial), as one options
// struct composed of the options of the modules it configures. Each module's
// struct owns its field table (keys, parsers, canonical texts):
//
//   tasks::SceneOptions          scene, cost, noise_k, horizon, initial_std,
//     tasks::CartPoleParams        cart_mass, ..., gravity,
//       ode::IntegratorOptions       integrator_*
//   (the trial's own fields)     method, seed, episodes, ..., policy_centre_std
//   OptimizerOptions             learning_rate, momentum, decay, epsilon, normalisation
//   gp::TrainingOptions          gp_iterations,
//     gp::PenaltyOptions           gp_penalty, gp_penalty_*
//   (the trial's own fields)     angle_features, gp_inducing, gp_variance_tolerance,
//                                pilco_line_searches,
//                                pilco_evaluations_per_line_search
//   estimators::EstimatorOptions lr_weights, lr_baseline, gs_derivative,
//                                sn_noise_multiplier, forced_k_lr
//
// TrialOptions::Table() nests them in that order, so every option has one key
// everywhere (CLI flags, sweep files, the service's option pairs, trial
// snapshots and checkpoints). Adding an option to a module is a change in its
// table only (docs/core.md, "Options, and adding one").
//
// The method and the angle-feature choice are enums, parsed from text once
// by the table (or by estimators::ParseMethod at another edge).
#ifndef TOTALGRAD_CORE_LEARNER_TRIAL_OPTIONS_H_
#define TOTALGRAD_CORE_LEARNER_TRIAL_OPTIONS_H_

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/common/option_table.h"
#include "core/estimators/estimator.h"
#include "core/estimators/method.h"
#include "core/gp/gp.h"
#include "core/gp/training.h"
#include "core/learner/optimizer.h"
#include "core/policy/policy_class.h"
#include "core/tasks/scene.h"

namespace totalgrad::learner {

// How the GP and the policy see the angles: "raw" state, "sincos" (PILCO's
// (sin, cos) augmentation of the scene's angles; particle methods keep raw
// particles and map through estimators::AngleFeature{Dynamics,Policy}) or
// "auto" (sincos for PILCO and on every scene but the cart-pole, where the
// particle methods keep the paper's raw state; see UsesSinCosFeatures).
enum class AngleFeatures { kAuto, kRaw, kSinCos };
const EnumNames<AngleFeatures>& AngleFeaturesNames();  // "auto", "raw", "sincos"

// gp_variance_tolerance's default, and its value in option pairs stored
// before the key existed.
inline constexpr double kDefaultGpVarianceTolerance = 1e-2;
inline constexpr double kAbsentGpVarianceTolerance = 0.0;
// verdict_rollouts in option pairs stored before the key existed: those
// trials classified no rollouts.
inline constexpr int kAbsentVerdictRollouts = 0;

struct TrialOptions {
  tasks::SceneOptions scene;
  estimators::Method method = estimators::Method::kRp;
  uint64_t seed = 1;
  int episodes = 15;           // learned episodes after the random one
  int policy_steps = 600;      // gradient steps per policy optimisation
  int particles = 300;         // particles per gradient estimate
  int eval_rollouts = 30;      // real evaluation episodes per learned episode
  double success_threshold = 15.0;  // key "threshold"; success: last evaluation mean below this
  // The rollout verdict (evaluation.h, ClassifyController): after the last
  // episode the final policy runs verdict_rollouts real rollouts (0 = none;
  // the first eval_rollouts of them are the last evaluation's own), and a
  // rollout is "held" when the goal distance (tasks::GoalDistance: on the
  // cart-pole the tip's distance from the upright tip, m) stays at most
  // verdict_distance over the last verdict_hold_seconds of the episode (all
  // of it when the episode is shorter).
  // The episode record's held_fraction is the fraction held; the trial's
  // rollout verdict is held_fraction >= 1/2. The defaults were chosen from
  // rollouts of clearly succeeding and clearly failing policies
  // (docs/results/table1.md, "The rollout verdict").
  int verdict_rollouts = 100;
  double verdict_distance = 0.4;
  double verdict_hold_seconds = 1.0;
  int basis_functions = 50;    // RBF policy size
  double model_noise_multiplier = 1.0;  // GP noise variance x this in policy optimisation
  int predicted_cost_particles = 1000;  // particles for the reported model-predicted cost
  double policy_init_lengthscale = 1.0; // initial length-scale of every basis function
  double policy_centre_std = 1.0;       // centres ~ N(mu0, policy_centre_std^2 I)
  OptimizerOptions optimizer;
  gp::TrainingOptions gp_training;
  AngleFeatures angle_features = AngleFeatures::kAuto;
  // The policy's class (key "policy", last in the table): the RBF network of
  // basis_functions centres, or PILCO's linear policy with saturation
  // (W ~ 1e-2 N(0, 1), b = 0 at the start, as PILCO's unicycle; every method).
  policy::PolicyClass policy = policy::PolicyClass::kRbf;
  // Sparse GP (FITC, gp/fitc.h) with this many inducing inputs once the data
  // exceed it, for every method; the full GP while N <= gp_inducing. 0 = always
  // the full GP; -1 = auto (300 for PILCO as PILCO does, 0 for particle
  // methods; see InducingInputs). The inducing inputs are trained with the
  // hyperparameters fixed, from a random subset of the inputs the first time
  // (1500 L-BFGS iterations), then warm-started from the previous episode (500).
  int gp_inducing = -1;
  // The full GP's predictive variance in the particle methods: 0 = exact
  // K^-1; t in (0, 1) = "low rank plus diagonal" K^-1 per output with the
  // a-priori bound t on the variance's relative error
  // (gp::GpModelOptions::variance_rank_tolerance, gp/gp.h; an output whose
  // bound needs rank >= N/2 keeps the exact product). The mean, PILCO and
  // FITC (gp_inducing) ignore it. Default 1e-2: it passed issue 11's accuracy
  // gate for every particle method (docs/results/speed.md, "Low rank plus
  // diagonal"). Stored pairs without this key (written before it existed)
  // read as 0, the exact path they were computed with (TrialOptionsFromStoredPairs).
  double gp_variance_tolerance = kDefaultGpVarianceTolerance;
  // PILCO's BFGS budget per policy optimisation: line searches, and function
  // evaluations per line search. -1 = auto: the scene's PILCO protocol
  // (tasks/scene_catalog.h; 150 x 30 on the cart-pole, 75 x 30 on the
  // pendulum, 150 x 20 on the pendubot). Only PILCO reads them.
  int pilco_line_searches = -1;
  int pilco_evaluations_per_line_search = -1;
  estimators::EstimatorOptions estimator;  // method-specific knobs

  // The composed table described above.
  static const OptionTable<TrialOptions>& Table();
  // OK, or InvalidArgument naming the first bad field (the key), including
  // the nested modules' Validate() and tasks::MakeScene's checks.
  absl::Status Validate() const;
  bool operator==(const TrialOptions&) const = default;
};

// Whether the GP and the policy see (sin, cos) of the angles: "sincos", or
// "auto" for PILCO or on a scene other than the cart-pole's. The one place
// that says what "auto" means.
bool UsesSinCosFeatures(estimators::Method method, AngleFeatures choice, bool cartpole_scene = true);
// The same for the options' method, choice and scene (an unknown scene
// counts as the cart-pole's; Validate() refuses it anyway).
bool UsesSinCosFeatures(const TrialOptions& options);
// The angles the GP and the policy see as (sin, cos): the scene's angle
// indices with sin/cos features, else none (the raw state).
std::vector<int> FeatureAngles(const TrialOptions& options, const tasks::Scene& scene);
// The inducing-input count gp_inducing resolves to: -1 (auto) is, on the
// cart-pole, 300 for PILCO (PILCO's own setting) and 0 (full GP) for the
// particle methods; on the other scenes the scene's M for every method
// (PILCO's model of that scene; tasks/scene_catalog.h).
int InducingInputs(const TrialOptions& options);
// The full GP's build options a particle method's trial uses
// (gp_variance_tolerance).
gp::GpModelOptions GpOptions(const TrialOptions& options);
// OK when trials with options `a` and `b` compute the same episodes: every
// option equal (as option pairs) but the rollout verdict's (verdict_*),
// which only adds the final policy's classification. InvalidArgument naming
// the first option that differs otherwise ("option noise_k is '1' in one,
// '0.01' in the other").
absl::Status SameEpisodes(const TrialOptions& a, const TrialOptions& b);
// verdict_hold_seconds as control steps of `scene`: rounded, then clamped to
// 1..horizon (an episode shorter than the hold time is held over all of it).
int VerdictHoldSteps(const TrialOptions& options, const tasks::Scene& scene);
// The BFGS budget pilco_line_searches / pilco_evaluations_per_line_search
// resolve to: the option when >= 1, else the scene's PILCO protocol (an
// unknown scene: 150 x 30, PILCO's cart-pole).
int PilcoLineSearches(const TrialOptions& options);
int PilcoEvaluationsPerLineSearch(const TrialOptions& options);

// TrialOptions::Table() as free functions (the names every caller uses).
// Sets one option by its key from text; InvalidArgument names an unknown key
// or an unparsable value (range checks are Validate()'s). Pairs: every option
// as (key, canonical text) in the table's order; SetTrialOption of each pair
// on default options reproduces `options`.
absl::Status SetTrialOption(const std::string& key, const std::string& value, TrialOptions* options);
std::vector<std::pair<std::string, std::string>> TrialOptionPairs(const TrialOptions& options);
std::vector<std::string> TrialOptionKeys();
// The keys whose default is the scene's (tasks::SceneDefinition): "horizon"
// (its H), "threshold" (its success_threshold), "cost" (its default_cost)
// and "policy" (its policy_class). TrialOptions{} holds the cart-pole's
// values (30, 15, angle, rbf).
const std::vector<std::string>& SceneDefaultedKeys();
// Options as a user gives them: default options with `pairs` applied in
// order, then each of SceneDefaultedKeys() that `pairs` lacks set to the
// scene's value (an unknown scene keeps the defaults; Validate() names it).
// InvalidArgument from the first pair that fails; no Validate(). Every
// reader of new options goes through this (the CLI's flags, a sweep's
// grid points, Python), so `trial --scene pendulum` runs PILCO's H = 40 and a
// sweep stores the resolved value in each job.
absl::StatusOr<TrialOptions> TrialOptionsFromPairs(
    const std::vector<std::pair<std::string, std::string>>& pairs);
// The same for pairs that were stored (a job's options, a checkpoint, a trial
// snapshot): a key whose default changed after files without it were written
// starts from the value those files were computed with, so that such a file
// still describes (and resumes, and rebuilds) the computation it came from.
// No scene defaults: stored pairs list every key they were run with.
// Today: gp_variance_tolerance (absent = 0, the exact variance) and
// verdict_rollouts (absent = 0, no rollout verdict). Pairs
// written by this build list every key, so for them both functions agree.
absl::StatusOr<TrialOptions> TrialOptionsFromStoredPairs(
    const std::vector<std::pair<std::string, std::string>>& pairs);

}  // namespace totalgrad::learner

#endif  // TOTALGRAD_CORE_LEARNER_TRIAL_OPTIONS_H_
