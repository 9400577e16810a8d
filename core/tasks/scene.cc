#include "core/tasks/scene.h"

#include <cmath>
#include <memory>
#include <numbers>

#include "absl/strings/str_cat.h"
#include "core/common/check.h"

namespace totalgrad::tasks {
namespace {

constexpr double kPi = std::numbers::pi;

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

std::string StepError(int step, const absl::Status& cause) {
  return absl::StrCat("episode step ", step, ": ", cause.message());
}

}  // namespace

const OptionTable<SceneOptions>& SceneOptions::Table() {
  static const OptionTable<SceneOptions>* table = [] {
    auto* t = new OptionTable<SceneOptions>();
    t->String("scene", &SceneOptions::scene)
        .String("cost", &SceneOptions::cost)
        .Double("noise_k", &SceneOptions::noise_k)
        .Int("horizon", &SceneOptions::horizon)
        .Double("initial_std", &SceneOptions::initial_std)
        .Nest(&SceneOptions::plant, CartPoleParams::Table());
    return t;
  }();
  return *table;
}

absl::StatusOr<Scene> MakeScene(const SceneOptions& options) {
  Scene scene;
  scene.name = options.scene;
  scene.target << 0.0, kPi, 0.0, 0.0;
  if (options.scene == "cartpole-swingup") {
    scene.mu0 = State::Zero();
  } else if (options.scene == "cartpole-balance") {
    scene.mu0 = scene.target;
  } else {
    return absl::InvalidArgumentError(absl::StrCat(
        "scene: unknown scene '", options.scene,
        "' (expected 'cartpole-swingup' or 'cartpole-balance')"));
  }
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

  if (options.cost == "tip") {
    // The tip is the tip of this plant's pole, so the cost uses its length.
    scene.cost = std::make_shared<TipCost>(scene.target(0), options.plant.pole_length);
  } else {
    absl::StatusOr<std::unique_ptr<StateCost>> cost = MakeCost(options.cost, scene.target);
    if (!cost.ok()) return cost.status();
    scene.cost = std::shared_ptr<const StateCost>(std::move(*cost));
  }

  scene.plant = CartPole(options.plant);
  scene.initial_std = State::Constant(options.initial_std);
  State base_std;
  base_std << 0.01, kPi / 180.0, 0.1, 10.0 * kPi / 180.0;
  scene.observation_noise_std = std::sqrt(options.noise_k) * base_std;
  scene.horizon = options.horizon;
  return scene;
}

absl::Status RunEpisode(const Scene& scene, const Controller& controller, Rng* start_rng,
                        Rng* noise_rng, Episode* episode) {
  TG_CHECK(start_rng != nullptr);
  TG_CHECK(noise_rng != nullptr);
  TG_CHECK(episode != nullptr);
  TG_CHECK(scene.cost != nullptr);
  const int horizon = scene.horizon;
  TG_CHECK(horizon >= 1);

  Episode& ep = *episode;
  ep.states.resize(horizon + 1, kCartPoleStateDim);
  ep.observations.resize(horizon + 1, kCartPoleStateDim);
  ep.forces.resize(horizon);
  ep.costs.resize(horizon);
  ep.total_cost = 0;

  // Draw order is part of the reproducibility contract: x0 takes the first
  // four normals of the start stream (s, beta, s_dot, beta_dot); observation
  // t takes normals 4t .. 4t+3 of the noise stream.
  State x;
  for (int m = 0; m < kCartPoleStateDim; ++m) {
    x(m) = scene.mu0(m) + scene.initial_std(m) * start_rng->Normal();
  }
  if (!x.allFinite()) {
    return absl::InternalError("episode step 0: non-finite start state");
  }
  auto observe = [&](int t) {
    ep.states.row(t) = x.transpose();
    State o;
    for (int m = 0; m < kCartPoleStateDim; ++m) {
      o(m) = x(m) + scene.observation_noise_std(m) * noise_rng->Normal();
    }
    ep.observations.row(t) = o.transpose();
    return o;
  };

  for (int t = 0; t < horizon; ++t) {
    const State observation = observe(t);
    const double force = controller(observation);
    if (!std::isfinite(force)) {
      return absl::InternalError(
          absl::StrCat("episode step ", t, ": controller returned a non-finite force ", force));
    }
    ep.forces(t) = force;
    State next;
    if (absl::Status st = scene.plant.Step(x, force, &next); !st.ok()) {
      return absl::InternalError(StepError(t, st));
    }
    x = next;
    const double cost = scene.cost->Value(x);
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
