// A scene: the plant, its start distribution, its cost, its observation noise
// and episode length; and real episodes on it.
//
// Scenes: "cartpole-swingup" (start hanging, mu0 = 0, target upright) and
// "cartpole-balance" (start upright, mu0 = target = [0, pi, 0, 0]).
// Start x0 ~ N(mu0, S0), S0 = initial_std^2 I (0.1^2 as in PILCO).
// Observation noise: o = x + n, n ~ N(0, k * diag(base^2)), base std =
// (0.01 m, 1 deg, 0.1 m/s, 10 deg/s). The policy acts on observations; the
// cost is taken of the true post-step state.
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
  CartPole plant;
  State mu0;
  State initial_std;            // per-dimension std of x0
  State target;
  State observation_noise_std;  // sqrt(k) * base std
  int horizon = 30;
  std::shared_ptr<const StateCost> cost;
  // The state index of the pole angle: where PILCO's (sin, cos) features of
  // the GP's and the policy's inputs act (pilco/angle_features.h).
  int angle_index = 1;
};

// InvalidArgument names the bad field (unknown scene or cost, k < 0,
// horizon < 1, non-finite numbers).
// Also rejected: initial_std < 0; plant masses, pole_length, dt or max_force
// <= 0; friction or gravity < 0 (the field is named as "plant.<field>");
// invalid integrator options (ode::IntegratorOptions::Validate()).
// The tip cost measures the tip of this plant's pole, so it uses
// plant.pole_length (PILCO: cost length = pole length = 0.5 m).
absl::StatusOr<Scene> MakeScene(const SceneOptions& options);

// One real episode.
struct Episode {
  RowMatrix states;        // (H+1) x 4 true states, row 0 is x0
  RowMatrix observations;  // (H+1) x 4 noisy observations of `states`
  Vector forces;           // H, the force applied at steps 0..H-1 (N)
  Vector costs;            // H, cost of the true post-step states x1..xH
  double total_cost = 0;   // sum of costs
};

// Maps the current observation to a force in N (the caller saturates).
using Controller = std::function<double(const State& observation)>;

// Runs one episode of scene.horizon steps from x0 ~ N(mu0, S0) drawn from
// *start_rng, observation noise from *noise_rng. Fails (Internal, with the
// step number) if the plant integration fails or a state is non-finite;
// *episode is then unspecified.
// Also Internal (with the step number) when the controller returns a
// non-finite force. Draw order, part of the reproducibility contract: x0 takes
// the first 4 normals of *start_rng (in state order); observation t
// (t = 0..H) takes the next 4 normals of *noise_rng, drawn before the
// controller is called at step t.
absl::Status RunEpisode(const Scene& scene, const Controller& controller, Rng* start_rng,
                        Rng* noise_rng, Episode* episode);

}  // namespace totalgrad::tasks

#endif  // TOTALGRAD_CORE_TASKS_SCENE_H_
