// A scene: the plant, its start distribution, its cost, its observation noise
// and episode length; and real episodes on it. The scenes are data
// (tasks/scene_catalog.h); the options choose one and tune it.
//
// The cart-pole scenes, as the paper has them: "cartpole-swingup" (start
// hanging, mu0 = 0, target upright) and "cartpole-balance" (start upright,
// mu0 = target = [0, pi, 0, 0]); start x0 ~ N(mu0, S0), S0 = initial_std^2 I
// (0.1^2 as in PILCO); observation noise o = x + n, n ~ N(0, k *
// diag(base^2)), base std = (0.01 m, 1 deg, 0.1 m/s, 10 deg/s); the plant's
// constants from the options (cart_mass, ...); costs "angle", "tip" or
// "saturating" (PILCO's, equal to the tip cost).
// Every other scene of the catalog: PILCO's start distribution, plant and
// measurement noise std (x sqrt(k)); costs "angle" (the scene's angle cost)
// or "saturating" (PILCO's loss); the cart-pole's plant options and
// initial_std must keep their defaults there. horizon and the integrator
// options apply to every scene.
// The policy acts on observations; the cost is taken of the true post-step
// state.
// The unicycle: the plant integrates 12 values; the learner (GP, policy,
// cost, start distribution) sees PILCO's 10-entry GP state of them
// (tasks::UnicycleGpState), so its states and observations are that map of
// the plant's state and of the plant's state plus measurement noise, as
// PILCO's rollout augments the noisy ODE state. Its only cost is "unicycle"
// (loss_unicycle).
#ifndef TOTALGRAD_CORE_TASKS_SCENE_H_
#define TOTALGRAD_CORE_TASKS_SCENE_H_

#include <functional>
#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "core/common/rng.h"
#include "core/common/types.h"
#include "core/tasks/cartpole.h"
#include "core/tasks/cost.h"
#include "core/tasks/plant.h"
#include "core/tasks/scene_catalog.h"

namespace totalgrad::tasks {

struct SceneOptions {
  std::string scene = "cartpole-swingup";  // or "cartpole-balance"
  std::string cost = "angle";              // or "tip"
  double noise_k = 1.0;                    // observation noise variance multiplier
  int horizon = 30;                        // control steps per episode
  double initial_std = 0.1;                // std of every start-state dimension
  CartPoleParams plant;

  // Trial option keys scene, cost, noise_k, horizon, initial_std and the
  // plant's (CartPoleParams::Table()).
  static const OptionTable<SceneOptions>& Table();
  bool operator==(const SceneOptions&) const = default;
};

struct Scene {
  std::string name;
  const SceneDefinition* definition = nullptr;  // the catalog entry (static)
  std::shared_ptr<const Plant> plant;
  Vector max_control;           // F, the policy's saturation bounds
  // D below is the learner's state dimension, P the plant's (equal but on
  // the unicycle, D 10 and P 12).
  Vector mu0;                   // D, the learner's start mean
  Vector initial_std;           // D, the learner's per-dimension start std
  Vector plant_mu0;             // P, x0 ~ N(plant_mu0, diag(plant_initial_std^2))
  Vector plant_initial_std;     // P
  Vector target;                // D
  Vector observation_noise_std; // P, sqrt(k) * base std, on the plant's state
  int horizon = 30;
  std::shared_ptr<const StateCost> cost;  // on the learner's state
  // The learner's state of a plant state (P -> D); null: the plant's own.
  std::function<Vector(const Vector&)> learner_state_of;
  Vector LearnerState(const Vector& plant_state) const {
    return learner_state_of ? learner_state_of(plant_state) : plant_state;
  }
  // The GP's state inputs when they are a strict subset of the learner's
  // state (the unicycle's dyni, without its yaw; only with no angle
  // features); empty: all.
  std::vector<int> dynamics_inputs;
  // Episode 0's random rollouts (SceneDefinition::random_episodes) and
  // their controls' fraction of max_control.
  int random_episodes = 1;
  double random_control_fraction = 1.0;
  // The state indices of the angles: where PILCO's (sin, cos) features of
  // the GP's and the policy's inputs act (the definition's angle_indices).
  std::vector<int> angle_indices;
  // Where the real episode ends (the definition's episode_end_*; empty:
  // never), and what each step after the end costs: 1, the supremum of
  // PILCO's saturating costs and of loss_unicycle, so that an early fall
  // does not look cheap (PILCO sums only the executed steps).
  std::vector<int> episode_end_indices;
  double episode_end_bound = 0;
  double ended_step_cost = 1.0;
  // Whether the real episode ends at plant state x (P).
  bool EpisodeEnds(const Vector& x) const;
  // The metric of GoalDistance: PILCO's saturating cost's Q on z (the
  // definition's), for the cart-pole built from the plant's pole length, so
  // that the distance is the pole tip's from the upright tip, in metres.
  Matrix goal_q;

  int state_dim() const { return static_cast<int>(mu0.size()); }
  int control_dim() const { return static_cast<int>(max_control.size()); }
  // The cart-pole scenes (the paper's; their options and costs).
  bool is_cartpole() const { return definition != nullptr && definition->plant == PlantKind::kCartPole; }
};

// InvalidArgument names the bad field (unknown scene or cost, k < 0,
// horizon < 1, non-finite numbers, a cart-pole option changed on another
// scene).
// Also rejected: initial_std < 0; plant masses, pole_length, dt or max_force
// <= 0; friction or gravity < 0 (the field is named as "plant.<field>");
// invalid integrator options (ode::IntegratorOptions::Validate()).
// The tip cost measures the tip of this plant's pole, so it uses
// plant.pole_length (PILCO: cost length = pole length = 0.5 m).
absl::StatusOr<Scene> MakeScene(const SceneOptions& options);
// The scene `scene` with cost `cost` and horizon `horizon`, every other
// option at its default (the gradient studies' synthetic problems).
absl::StatusOr<Scene> MakeScene(const std::string& scene, const std::string& cost, int horizon);

// How far state x (D) is from the scene's goal, in the metric of PILCO's
// saturating cost: sqrt((z - z_t)^T Q (z - z_t)), z = [x, sin x_a, cos x_a,
// ...] and z_t the target's, Q = scene.goal_q. On PILCO's scenes and the
// cart-pole this is the distance (m) of the tip (the pendulum's, the outer
// pole's) from where it is at the goal, whichever cost the trial uses.
double GoalDistance(const Scene& scene, const Vector& x);

// One real episode. It runs the horizon H unless the scene's episode end
// is reached: when step t would lead to a state beyond it, the episode ends
// after t steps as PILCO's rollout does (that last transition is not kept:
// the data are the t steps before it), and steps t+1..H cost
// scene.ended_step_cost each.
struct Episode {
  int steps = 0;           // T: H, or the steps kept before the end
  bool ended = false;      // whether the scene's episode end was reached
  RowMatrix states;        // (T+1) x D true (learner) states, row 0 is x0's
  RowMatrix observations;  // (T+1) x D noisy observations of `states`
  Vector forces;           // T F, the controls applied at steps 0..T-1, step-major
                           // (u_0^1..u_0^F, u_1^1, ...; one control: T)
  Vector costs;            // H, cost of the true post-step states x1..xT, then
                           // ended_step_cost for each step after the end
  double total_cost = 0;   // sum of costs (all H)
};

// Maps the current observation (D) to the control of a one-control scene
// (the caller saturates).
using Controller = std::function<double(const Vector& observation)>;
// Maps the current observation (D) to the F controls of any scene.
using MultiController = std::function<Vector(const Vector& observation)>;

// Runs one episode of scene.horizon steps (fewer when it ends: Episode)
// from x0 ~ N(mu0, S0) drawn from
// *start_rng, observation noise from *noise_rng. Fails (Internal, with the
// step number) if the plant integration fails or a state is non-finite;
// *episode is then unspecified.
// Also Internal (with the step number, and the control's 0-based index when
// F > 1) when the controller returns a non-finite control, and
// InvalidArgument (with the step number) when it returns other than F
// controls. Draw order, part of the
// reproducibility contract: x0 takes the first P normals of *start_rng (in
// the plant's state order); observation t (t = 0..H) takes the next P
// normals of *noise_rng, drawn before the controller is called at step t.
absl::Status RunEpisode(const Scene& scene, const MultiController& controller, Rng* start_rng,
                        Rng* noise_rng, Episode* episode);
// The same for a one-control scene (InvalidArgument on a scene of F > 1).
absl::Status RunEpisode(const Scene& scene, const Controller& controller, Rng* start_rng,
                        Rng* noise_rng, Episode* episode);

}  // namespace totalgrad::tasks

#endif  // TOTALGRAD_CORE_TASKS_SCENE_H_
