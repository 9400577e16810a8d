// The scenes as data: one SceneDefinition per scene, with PILCO's published
// settings for the scenes taken from PILCO (UCL-SML/pilco-matlab at a0b48b7,
// scenarios/*/settings_*.m, dynamics_*.m, loss_*.m; docs/scenes.md says
// where every number comes from) and the paper's cart-pole as it is:
//
//   pendulum              D 2, F 1, A 1   swing-up, torque |u| <= 2.5 N m
//   cartpole-swingup      D 4, F 1, A 1   the paper's cart-pole (options
//   cartpole-balance                      scene/cost/noise_k/... as before)
//   cart-double-pendulum  D 6, F 1, A 2   swing-up, force |u| <= 20 N
//   double-pendulum       D 4, F 2, A 2   swing-up, torques |u_i| <= 2 N m
//   pendubot              D 4, F 1, A 2   swing-up, torque at joint 1 |u| <= 3.5 N m
//   unicycle              D 12, F 2, A 0  balance, torques |V| <= 10, |U| <= 50 N m
//                                         (the learner sees 10: learner_mu0 below)
//
// Index sets are 0-based; the augmented state is z = [x, sin x_a1,
// cos x_a1, sin x_a2, cos x_a2, ...] over angle_indices in order;
// dynamics_inputs and policy_inputs index z.
//
// Thread safety: the catalog is immutable (built on first use).
#ifndef TOTALGRAD_CORE_TASKS_SCENE_CATALOG_H_
#define TOTALGRAD_CORE_TASKS_SCENE_CATALOG_H_

#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "core/common/types.h"
#include "core/tasks/cart_double_pendulum.h"
#include "core/tasks/cartpole.h"
#include "core/tasks/double_pendulum.h"
#include "core/tasks/pendulum.h"
#include "core/tasks/plant.h"
#include "core/tasks/unicycle.h"

namespace totalgrad::tasks {

enum class PlantKind { kPendulum, kCartPole, kCartDoublePendulum, kDoublePendulum, kUnicycle };

// PILCO's saturating cost (lossSat) on z: for each width w,
// c_w(x) = 1 - exp(-(z - z_t)^T (Q / w^2) (z - z_t) / 2), z_t the augmented
// target; the cost is the mean over the widths.
struct SaturatingCostSpec {
  Matrix q;                    // (D + 2A) x (D + 2A), symmetric PSD, on z
  std::vector<double> widths;  // > 0
};

// A scene whose state has more entries than its plant integrates (PILCO's
// unicycle): the full state's entries by name and which of them are what.
// 0-based (PILCO's 1-based indices minus one). Empty for the scenes whose
// full state is the plant's (their GP and policy inputs index z above).
struct FullStateIndexSets {
  std::vector<std::string> names;    // every entry of the full state
  std::vector<int> integrated;       // odei: the plant's state, in its order
  std::vector<int> augmented;        // augi: computed from it after each step
  std::vector<int> controls;         // the controls, in the plant's order
  std::vector<int> predicted;        // dyno: the GP's outputs (as differences)
  std::vector<int> dynamics_inputs;  // dyni: into `predicted`, the GP's state inputs
  std::vector<int> policy_inputs;    // poli: into `predicted`
  bool empty() const { return names.empty(); }
};

struct SceneDefinition {
  std::string name;
  std::string summary;
  PlantKind plant = PlantKind::kCartPole;
  // The parameters of `plant` (the other kinds' are unused).
  PendulumParams pendulum;
  CartPoleParams cartpole;
  CartDoublePendulumParams cart_double_pendulum;
  DoublePendulumParams double_pendulum;
  UnicycleParams unicycle;
  double dt = 0.1;                       // s, control period
  std::vector<std::string> state_names;  // D, in the plant's state order
  std::vector<std::string> state_units;  // D
  std::vector<std::string> control_names;  // F
  Vector max_control;                    // F, |u_i| <= max_control_i
  int horizon = 30;                      // H = T / dt (PILCO's; the cart-pole the paper's)
  // A trial succeeds when its last evaluation's mean episode cost is below
  // this (the trial option "threshold" defaults to it, as "horizon" to H).
  // The paper's cart-pole: 15 of H = 30. PILCO publishes no threshold, so the
  // other scenes take the same rule, H / 2: with a per-step cost in [0, 1],
  // the cost of an episode that reaches the goal by its middle and stays.
  double success_threshold = 15.0;
  Vector mu0;                            // D, start mean
  Vector start_std;                      // D, sqrt(diag S0)
  Vector measurement_noise_std;          // D, observation noise std
  Vector target;                         // D, the goal state
  std::vector<int> angle_indices;        // A, strictly increasing state indices
  std::vector<int> dynamics_inputs;      // into z, strictly increasing
  std::vector<int> policy_inputs;        // into z, strictly increasing
  FullStateIndexSets full_state;         // the unicycle's; empty elsewhere
  SaturatingCostSpec saturating_cost;    // PILCO's loss (empty for the unicycle)
  // The unicycle's loss_unicycle instead of a saturating cost (its
  // parameters; unused by the other scenes, whose cost_kind is "saturating").
  std::string cost_kind = "saturating";  // "saturating" or "unicycle"
  UnicycleCostParams unicycle_cost;
  std::string policy_class = "rbf";      // PILCO's policy: "rbf" or "linear"
  // The trial option "cost" defaults to this ("angle" on the cart-pole and
  // PILCO's swing-ups, as before; "unicycle" on the unicycle, whose only cost
  // is loss_unicycle).
  std::string default_cost = "angle";
  // A scene whose learner sees another state than the plant's (the
  // unicycle: its GP state, UnicycleGpState of the plant's 12, 10 entries):
  // that state's start mean and std (empty: the plant's mu0 and start_std).
  // dynamics_inputs and policy_inputs then index it.
  Vector learner_mu0;
  Vector learner_start_std;
  std::vector<std::string> learner_state_names;
  // PILCO's initial random rollouts: the trial's episode 0 is this many
  // real episodes with each control uniform in +-random_control_fraction x
  // its bound (PILCO's J and maxU / 5 on the unicycle; 1 and 1 elsewhere,
  // the paper's one random episode).
  int random_episodes = 1;
  double random_control_fraction = 1.0;
  // Empty when trials run on the scene; else why they do not yet (MakeScene
  // refuses the scene with this text; `simulate` and `scenes` take it).
  std::string trials_unavailable;
  // The same for studies (RunnableScene(name, "studies") takes either).
  std::string studies_unavailable;
  // PILCO's plant.constraint: the real episode ends at the first state with
  // |x_i| > episode_end_bound for an i in episode_end_indices (the
  // unicycle's roll and pitch beyond pi/2). Empty: episodes run the horizon.
  std::vector<int> episode_end_indices;
  double episode_end_bound = 0;
  Vector angle_cost_q;                   // D, diag Q of the angle cost 1 - exp(-(x-t)^T Q (x-t))
  // PILCO's protocol.
  int basis_functions = 50;              // RBF centres
  int inducing_inputs = 300;             // FITC with M inducing inputs once N > M
  int learned_episodes = 15;             // policy optimisations
  int line_searches = 150;               // BFGS line searches per optimisation
  int evaluations_per_line_search = 30;
  std::string source;                    // where the numbers come from

  int state_dim() const { return static_cast<int>(mu0.size()); }
  int control_dim() const { return static_cast<int>(max_control.size()); }
  int num_angles() const { return static_cast<int>(angle_indices.size()); }
  // The names of the learner's state: learner_state_names, else state_names.
  const std::vector<std::string>& LearnerStateNames() const {
    return learner_state_names.empty() ? state_names : learner_state_names;
  }
  // The state the learner sees (its GP's outputs): learner_mu0's, else D.
  int learner_state_dim() const {
    return learner_mu0.size() > 0 ? static_cast<int>(learner_mu0.size()) : state_dim();
  }
  int augmented_dim() const { return state_dim() + 2 * num_angles(); }
};

// Every scene, in the order above.
const std::vector<SceneDefinition>& SceneCatalog();
// The scene named `name`, or null.
const SceneDefinition* FindSceneDefinition(const std::string& name);
// The names, in catalog order.
std::vector<std::string> SceneNames();
// What to say of a scene name the catalog does not list: "unknown scene
// 'cartpole' (did you mean cartpole-swingup or cartpole-balance?; known:
// ...)": the catalog names it begins, else the closest name, then every
// name. Every reader of a scene name (trial options, `simulate`, study
// files) says the same.
std::string UnknownSceneText(const std::string& name);
// The definition of a scene that runs `what` ("trials", "studies": both
// need the learning loop); InvalidArgument "unknown scene ..."
// (UnknownSceneText) or "'<name>' has no <what> yet: <why>" (the
// entry's trials_unavailable, and for studies its studies_unavailable). Callers put their field name in front.
absl::StatusOr<const SceneDefinition*> RunnableScene(const std::string& name,
                                                     const std::string& what);

// The plant of a definition with its dt and `integrator`.
std::unique_ptr<Plant> MakePlant(const SceneDefinition& definition,
                                 const ode::IntegratorOptions& integrator = {});

// z = [x, sin x_a1, cos x_a1, ...] of one state.
Vector AugmentState(const Vector& x, const std::vector<int>& angle_indices);

// A rough peak of a trial's memory (bytes): the GP of the last episode (per
// output K^-1 and one factor of min(N, M)^2 doubles, N = H (episodes + 1))
// and the particle methods' rollout record (P = particles, H steps, per
// particle D x (D + F + 1) Jacobian entries for mean and variance), the
// larger of the two model paths counted. For `totalgrad scenes`.
double PeakTrialBytes(const SceneDefinition& definition, int particles);

}  // namespace totalgrad::tasks

#endif  // TOTALGRAD_CORE_TASKS_SCENE_CATALOG_H_
