#include "core/tasks/scene.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <numbers>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "core/common/check.h"
#include "core/common/status_context.h"

namespace totalgrad::tasks {
namespace {


absl::Status RequirePositive(const char* field, double value) {
  if (!std::isfinite(value) || !(value > 0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("scene: ", field, " must be finite and > 0, got ", value));
  }
  return absl::OkStatus();
}

absl::Status RequireNonNegative(const char* field, double value) {
  if (!std::isfinite(value) || !(value >= 0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("scene: ", field, " must be finite and >= 0, got ", value));
  }
  return absl::OkStatus();
}

absl::Status ValidatePlant(const CartPoleParams& p) {
  for (absl::Status st : {RequirePositive("plant.cart_mass", p.cart_mass),
                          RequirePositive("plant.pole_mass", p.pole_mass),
                          RequirePositive("plant.pole_length", p.pole_length),
                          RequireNonNegative("plant.friction", p.friction),
                          RequireNonNegative("plant.gravity", p.gravity),
                          RequirePositive("plant.dt", p.dt),
                          RequirePositive("plant.max_force", p.max_force)}) {
    if (!st.ok()) return st;
  }
  return p.integrator.Validate();
}

// PILCO's scenes have their own plant and start distribution; the
// cart-pole's options must not pretend to change them.
absl::Status RefuseCartPoleOptions(const SceneOptions& options) {
  CartPoleParams defaults;
  defaults.integrator = options.plant.integrator;
  if (!(options.plant == defaults)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "scene '", options.scene, "': the plant options (cart_mass, pole_mass, pole_length, "
        "friction, dt, max_force, gravity) are the cart-pole's; this scene's plant is fixed "
        "(totalgrad scenes)"));
  }
  if (options.initial_std != SceneOptions().initial_std) {
    return absl::InvalidArgumentError(absl::StrCat(
        "scene '", options.scene, "': initial_std is the cart-pole's; this scene's start "
        "distribution is PILCO's (totalgrad scenes)"));
  }
  return absl::OkStatus();
}

// The unicycle: the plant's 12 integrated, the learner's 10 (its GP state)
// costed by loss_unicycle.
absl::Status MakeUnicycleScene(const SceneOptions& options, const SceneDefinition& definition,
                               Scene* scene) {
  if (absl::Status st = RefuseCartPoleOptions(options); !st.ok()) return st;
  if (options.cost != "unicycle") {
    return absl::InvalidArgumentError(absl::StrCat(
        "cost: unknown cost '", options.cost,
        "' for scene 'unicycle' (expected 'unicycle', PILCO's loss_unicycle)"));
  }
  scene->plant = MakePlant(definition, options.plant.integrator);
  scene->max_control = definition.max_control;
  scene->mu0 = definition.learner_mu0;
  scene->initial_std = definition.learner_start_std;
  scene->target = Vector::Zero(definition.learner_mu0.size());
  scene->cost = std::make_shared<UnicycleStateCost>(definition.unicycle_cost);
  const double wheel_radius = definition.unicycle.wheel_radius;
  scene->learner_state_of = [wheel_radius](const Vector& x) {
    return UnicycleGpState(x, wheel_radius);
  };
  scene->dynamics_inputs = definition.dynamics_inputs;
  return absl::OkStatus();
}

std::string StepError(int step, const absl::Status& cause) {
  return absl::StrCat("episode step ", step, ": ", cause.message());
}

}  // namespace

const OptionTable<SceneOptions>& SceneOptions::Table() {
  static const OptionTable<SceneOptions>* table = [] {
    auto* t = new OptionTable<SceneOptions>();
    t->String("scene", &SceneOptions::scene)
        .String("cost", &SceneOptions::cost)
        // The noise std is the scene's times sqrt(noise_k): at most 100 times
        // the paper's (the paper sweeps 0.01 to 1).
        .Double("noise_k", &SceneOptions::noise_k,
                {0, 1e4, "observation noise variance multiplier of the scene's measurement noise"})
        .Int("horizon", &SceneOptions::horizon, {1, 1e5, "time steps per episode"})
        .Double("initial_std", &SceneOptions::initial_std,
                {0, 1e4, "std of the start state around the scene's mean, state units"})
        .Nest(&SceneOptions::plant, CartPoleParams::Table());
    return t;
  }();
  return *table;
}

absl::StatusOr<Scene> MakeScene(const std::string& scene, const std::string& cost, int horizon) {
  SceneOptions options;
  options.scene = scene;
  options.cost = cost;
  options.horizon = horizon;
  return MakeScene(options);
}

absl::StatusOr<Scene> MakeScene(const SceneOptions& options) {
  absl::StatusOr<const SceneDefinition*> runnable = RunnableScene(options.scene, "trials");
  if (!runnable.ok()) return WithContext(runnable.status(), "scene");
  const SceneDefinition* definition = *runnable;
  if (!std::isfinite(options.noise_k) || !(options.noise_k >= 0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("scene: noise_k must be finite and >= 0, got ", options.noise_k));
  }
  if (options.horizon < 1) {
    return absl::InvalidArgumentError(
        absl::StrCat("scene: horizon must be >= 1, got ", options.horizon));
  }
  if (absl::Status st = RequireNonNegative("initial_std", options.initial_std); !st.ok()) return st;
  if (absl::Status st = ValidatePlant(options.plant); !st.ok()) return st;

  Scene scene;
  scene.name = options.scene;
  scene.definition = definition;
  scene.target = definition->target;
  scene.mu0 = definition->mu0;
  scene.horizon = options.horizon;
  scene.angle_indices = definition->angle_indices;
  const int d = definition->state_dim();
  if (definition->plant == PlantKind::kCartPole) {
    // The paper's cart-pole: the plant and the start spread from the options.
    scene.plant = std::make_shared<CartPole>(options.plant);
    scene.max_control = Vector::Constant(1, options.plant.max_force);
    scene.initial_std = Vector::Constant(d, options.initial_std);
    if (options.cost == "tip") {
      // The tip is the tip of this plant's pole, so the cost uses its length.
      scene.cost = std::make_shared<TipCost>(scene.target(0), options.plant.pole_length);
    } else if (options.cost == "saturating") {
      scene.cost = std::make_shared<SaturatingCost>(scene.target, definition->angle_indices,
                                                    definition->saturating_cost.q,
                                                    definition->saturating_cost.widths);
    } else {
      absl::StatusOr<std::unique_ptr<StateCost>> cost = MakeCost(options.cost, State(scene.target));
      if (!cost.ok()) return cost.status();
      scene.cost = std::shared_ptr<const StateCost>(std::move(*cost));
    }
  } else if (definition->plant == PlantKind::kUnicycle) {
    if (absl::Status st = MakeUnicycleScene(options, *definition, &scene); !st.ok()) return st;
  } else {
    // PILCO's scene: its own plant and start distribution.
    if (absl::Status st = RefuseCartPoleOptions(options); !st.ok()) return st;
    scene.plant = MakePlant(*definition, options.plant.integrator);
    scene.max_control = definition->max_control;
    scene.initial_std = definition->start_std;
    if (options.cost == "angle") {
      scene.cost = std::make_shared<AngleCost>(scene.target, definition->angle_cost_q);
    } else if (options.cost == "saturating") {
      scene.cost = std::make_shared<SaturatingCost>(scene.target, definition->angle_indices,
                                                    definition->saturating_cost.q,
                                                    definition->saturating_cost.widths);
    } else {
      return absl::InvalidArgumentError(absl::StrCat("cost: unknown cost '", options.cost, "' for scene '",
                                                     options.scene, "' (expected 'angle' or 'saturating')"));
    }
  }
  // The real episodes start from the plant's distribution (the learner's
  // unless the catalog gives the learner a state of its own).
  const bool learner_state_differs = definition->learner_mu0.size() > 0;
  scene.plant_mu0 = learner_state_differs ? definition->mu0 : scene.mu0;
  scene.plant_initial_std = learner_state_differs ? definition->start_std : scene.initial_std;
  scene.random_episodes = definition->random_episodes;
  scene.random_control_fraction = definition->random_control_fraction;
  scene.observation_noise_std = std::sqrt(options.noise_k) * definition->measurement_noise_std;
  scene.episode_end_indices = definition->episode_end_indices;
  scene.episode_end_bound = definition->episode_end_bound;
  scene.goal_q = definition->saturating_cost.q;
  if (definition->plant == PlantKind::kCartPole) {
    // d^2 = (s + l sin beta)^2 + l^2 (cos beta + 1)^2 = |C (z - z_t)|^2 with
    // C = [[1, l, 0], [0, 0, l]] on z's (s, sin beta, cos beta), for this
    // plant's l (the catalog's Q has PILCO's 0.5 m).
    const double l = options.plant.pole_length;
    const int at[3] = {0, d, d + 1};  // z = [x (D), sin beta, cos beta]
    const double c[2][3] = {{1.0, l, 0.0}, {0.0, 0.0, l}};
    scene.goal_q.setZero();
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        scene.goal_q(at[i], at[j]) = c[0][i] * c[0][j] + c[1][i] * c[1][j];
  }
  return scene;
}

bool Scene::EpisodeEnds(const Vector& x) const {
  for (int i : episode_end_indices) {
    if (std::abs(x(i)) > episode_end_bound) return true;
  }
  return false;
}

double GoalDistance(const Scene& scene, const Vector& x) {
  const int d = scene.state_dim();
  TG_CHECK_EQ(x.size(), d);
  if (scene.definition != nullptr && scene.definition->plant == PlantKind::kUnicycle)
    return UnicycleUprightDistance(scene.definition->unicycle_cost, x);
  const int angles = static_cast<int>(scene.angle_indices.size());
  Vector dz(d + 2 * angles);
  dz.head(d) = x - scene.target;
  for (int a = 0; a < angles; ++a) {
    const int i = scene.angle_indices[a];
    dz(d + 2 * a) = std::sin(x(i)) - std::sin(scene.target(i));
    dz(d + 2 * a + 1) = std::cos(x(i)) - std::cos(scene.target(i));
  }
  const double quad = dz.dot(scene.goal_q * dz);
  // Round-off can leave a PSD form slightly below 0; a NaN state stays NaN.
  return quad < 0 ? 0.0 : std::sqrt(quad);
}

absl::Status RunEpisode(const Scene& scene, const Controller& controller, Rng* start_rng,
                        Rng* noise_rng, Episode* episode) {
  if (scene.control_dim() != 1) {
    return absl::InvalidArgumentError(absl::StrCat(
        "scene '", scene.name, "' has ", scene.control_dim(),
        " controls; a one-control controller cannot run it"));
  }
  const MultiController multi = [&controller](const Vector& observation) {
    return Vector::Constant(1, controller(observation)).eval();
  };
  return RunEpisode(scene, multi, start_rng, noise_rng, episode);
}

absl::Status RunEpisode(const Scene& scene, const MultiController& controller, Rng* start_rng,
                        Rng* noise_rng, Episode* episode) {
  TG_CHECK(start_rng != nullptr);
  TG_CHECK(noise_rng != nullptr);
  TG_CHECK(episode != nullptr);
  TG_CHECK(scene.cost != nullptr && scene.plant != nullptr);
  const int horizon = scene.horizon;
  TG_CHECK(horizon >= 1);
  const int d = scene.state_dim();
  const int p = scene.plant->state_dim();
  const int f = scene.control_dim();
  TG_CHECK(scene.plant_mu0.size() == p && scene.plant_initial_std.size() == p &&
           scene.observation_noise_std.size() == p);

  Episode& ep = *episode;
  ep.steps = horizon;
  ep.ended = false;
  ep.states.resize(horizon + 1, d);
  ep.observations.resize(horizon + 1, d);
  ep.forces.resize(horizon * f);
  ep.costs.resize(horizon);
  ep.total_cost = 0;

  // Draw order is part of the reproducibility contract: x0 takes the first
  // P normals of the start stream (in the plant's state order); observation
  // t takes normals P t .. P t + P - 1 of the noise stream.
  Vector x(p);
  for (int m = 0; m < p; ++m) {
    x(m) = scene.plant_mu0(m) + scene.plant_initial_std(m) * start_rng->Normal();
  }
  if (!x.allFinite()) {
    return absl::InternalError("episode step 0: non-finite start state");
  }
  auto observe = [&](int t) {
    ep.states.row(t) = scene.LearnerState(x).transpose();
    Vector o(p);
    for (int m = 0; m < p; ++m) {
      o(m) = x(m) + scene.observation_noise_std(m) * noise_rng->Normal();
    }
    const Vector observed = scene.LearnerState(o);
    ep.observations.row(t) = observed.transpose();
    return observed;
  };

  for (int t = 0; t < horizon; ++t) {
    const Vector observation = observe(t);
    const Vector u = controller(observation);
    if (u.size() != f) {
      return absl::InvalidArgumentError(absl::StrCat("episode step ", t, ": controller returned ",
                                                     u.size(), " controls; the scene has ", f));
    }
    for (int j = 0; j < f; ++j) {
      if (!std::isfinite(u(j))) {
        // One control keeps the message it always had; several name the control.
        return absl::InternalError(absl::StrCat(
            "episode step ", t, ": controller returned a non-finite force ", u(j),
            f == 1 ? std::string() : absl::StrCat(" for control ", j)));
      }
    }
    ep.forces.segment(t * f, f) = u;
    Vector next;
    if (absl::Status st = scene.plant->Step(x, u, &next); !st.ok()) {
      return absl::InternalError(StepError(t, st));
    }
    if (scene.EpisodeEnds(next)) {
      // PILCO's rollout: the step into the end is neither kept nor costed;
      // the steps from it on cost ended_step_cost each.
      ep.steps = t;
      ep.ended = true;
      ep.states.conservativeResize(t + 1, d);
      ep.observations.conservativeResize(t + 1, d);
      ep.forces.conservativeResize(t * f);
      for (int k = t; k < horizon; ++k) {
        ep.costs(k) = scene.ended_step_cost;
        ep.total_cost += scene.ended_step_cost;
      }
      return absl::OkStatus();
    }
    x = next;
    const double cost = scene.cost->Value(scene.LearnerState(x));
    if (!std::isfinite(cost)) {
      return absl::InternalError(absl::StrCat("episode step ", t, ": non-finite cost"));
    }
    ep.costs(t) = cost;
    ep.total_cost += cost;
  }
  observe(horizon);
  return absl::OkStatus();
}

}  // namespace totalgrad::tasks
