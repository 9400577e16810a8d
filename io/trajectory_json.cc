#include "io/trajectory_json.h"

#include <cmath>
#include <limits>

#include "absl/strings/str_cat.h"
#include "core/learner/trial_options.h"
#include "core/tasks/scene.h"
#include "core/tasks/scene_catalog.h"

namespace totalgrad::io {
namespace {

nlohmann::ordered_json Number(double v) {
  return std::isfinite(v) ? nlohmann::ordered_json(v) : nlohmann::ordered_json(nullptr);
}

nlohmann::ordered_json Rows(const RowMatrix& m) {
  nlohmann::ordered_json rows = nlohmann::ordered_json::array();
  for (Eigen::Index r = 0; r < m.rows(); ++r) {
    nlohmann::ordered_json row = nlohmann::ordered_json::array();
    for (Eigen::Index c = 0; c < m.cols(); ++c) row.push_back(Number(m(r, c)));
    rows.push_back(std::move(row));
  }
  return rows;
}

std::vector<std::string> Numbered(const char* prefix, Eigen::Index n) {
  std::vector<std::string> names;
  for (Eigen::Index i = 1; i <= n; ++i) names.push_back(absl::StrCat(prefix, i));
  return names;
}

}  // namespace

absl::StatusOr<TrajectoryView> ViewTrajectory(const learner::TrialCheckpoint& checkpoint,
                                              int episode, int rollout) {
  if (episode < 0 || episode >= static_cast<int>(checkpoint.episodes.size())) {
    return absl::NotFoundError(absl::StrCat("episode ", episode, " is not recorded: the trial holds episodes 0..",
                                            static_cast<int>(checkpoint.episodes.size()) - 1));
  }
  const learner::EpisodeResult& e = checkpoint.episodes[episode];
  if (e.trajectories.real.empty()) {
    return absl::NotFoundError(absl::StrCat(
        "episode ", episode, " was recorded without trajectories (by a build before them, "
        "or resumed from such a build's checkpoint)"));
  }
  const int held = static_cast<int>(e.trajectories.verdict_rollouts.size());
  if (rollout >= 0 && rollout >= held) {
    return absl::NotFoundError(absl::StrCat(
        "episode ", episode, " holds ", held, " verdict rollouts", held > 0 ? absl::StrCat(" (0..", held - 1, ")") : "",
        "; rollout ", rollout, " is not one of them",
        held == 0 ? " (only a trial's last episode holds them)" : ""));
  }
  TrajectoryView view;
  view.episode = episode;
  view.rollout = rollout < 0 ? -1 : rollout;
  view.real_cost = e.real_cost;
  view.verdict_rollouts = held;
  view.episode_trajectories = &e.trajectories;
  view.shown = rollout < 0 ? &e.trajectories.real : &e.trajectories.verdict_rollouts[rollout];
  absl::StatusOr<learner::TrialOptions> options =
      learner::TrialOptionsFromStoredPairs(checkpoint.options);
  if (!options.ok()) {
    return absl::InvalidArgumentError(
        absl::StrCat("the checkpoint's options do not parse: ", options.status().message()));
  }
  absl::StatusOr<tasks::Scene> scene = tasks::MakeScene(options->scene);
  if (!scene.ok()) return scene.status();
  view.scene = scene->name;
  const tasks::SceneDefinition* definition = scene->definition;
  const Eigen::Index d = view.shown->states.cols(), f = view.shown->controls.cols();
  // An episode that ended before its first step has no control rows (0 x 0).
  const bool no_controls = view.shown->controls.rows() == 0;
  if (d != scene->state_dim() || (f != scene->control_dim() && !no_controls)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "the trajectory has ", d, " states and ", f, " controls; scene '", scene->name, "' has ",
        scene->state_dim(), " and ", scene->control_dim()));
  }
  view.dt = scene->plant->dt();
  // The learner's state names (the unicycle's GP state; the plant's elsewhere).
  const std::vector<std::string>* state_names =
      definition == nullptr ? nullptr : &definition->LearnerStateNames();
  if (state_names != nullptr && static_cast<Eigen::Index>(state_names->size()) == d &&
      static_cast<Eigen::Index>(definition->control_names.size()) == scene->control_dim()) {
    view.state_names = *state_names;
    view.control_names = definition->control_names;
  } else {
    view.state_names = Numbered("x", d);
    view.control_names = Numbered("u", scene->control_dim());
  }
  for (Eigen::Index t = 0; t < view.shown->states.rows(); ++t)
    view.goal_distance.push_back(tasks::GoalDistance(*scene, view.shown->states.row(t).transpose()));
  view.verdict_distance = options->verdict_distance;
  view.verdict_hold_steps = learner::VerdictHoldSteps(*options, *scene);
  if (definition != nullptr) {
    // The state orders of the catalog (scene_catalog.cc).
    switch (definition->plant) {
      case tasks::PlantKind::kPendulum:
        view.links = {{1, definition->pendulum.length}};
        break;
      case tasks::PlantKind::kCartPole:
        view.cart_index = 0;
        view.links = {{1, options->scene.plant.pole_length}};
        break;
      case tasks::PlantKind::kCartDoublePendulum:
        view.cart_index = 0;
        view.links = {{4, definition->cart_double_pendulum.length1},
                      {5, definition->cart_double_pendulum.length2}};
        break;
      case tasks::PlantKind::kDoublePendulum:
        view.links = {{2, definition->double_pendulum.length1},
                      {3, definition->double_pendulum.length2}};
        break;
      case tasks::PlantKind::kUnicycle:  // no planar drawing: its states and distance only
        break;
    }
  }
  return view;
}

nlohmann::ordered_json TrajectoryToJson(const TrajectoryView& view) {
  nlohmann::ordered_json out;
  out["episode"] = view.episode;
  if (view.rollout >= 0) out["rollout"] = view.rollout;
  out["scene"] = view.scene;
  out["dt"] = Number(view.dt);
  out["state_names"] = view.state_names;
  out["control_names"] = view.control_names;
  out["real_cost"] = Number(view.real_cost);
  out["states"] = Rows(view.shown->states);
  out["controls"] = Rows(view.shown->controls);
  out["predicted_mean"] = Rows(view.episode_trajectories->predicted_mean);
  out["predicted_std"] = Rows(view.episode_trajectories->predicted_std);
  out["verdict_rollouts"] = view.verdict_rollouts;
  nlohmann::ordered_json distance = nlohmann::ordered_json::array();
  for (double v : view.goal_distance) distance.push_back(Number(v));
  out["goal_distance"] = std::move(distance);
  out["verdict_distance"] = Number(view.verdict_distance);
  out["verdict_hold_steps"] = view.verdict_hold_steps;
  nlohmann::ordered_json geometry;
  geometry["cart"] = view.cart_index >= 0 ? nlohmann::ordered_json(view.cart_index)
                                          : nlohmann::ordered_json(nullptr);
  geometry["links"] = nlohmann::ordered_json::array();
  for (const auto& [angle, length] : view.links)
    geometry["links"].push_back({{"angle", angle}, {"length", length}});
  out["geometry"] = std::move(geometry);
  return out;
}

TrajectoryTable TrajectoryRows(const TrajectoryView& view) {
  TrajectoryTable table;
  const RowMatrix& states = view.shown->states;
  const RowMatrix& controls = view.shown->controls;
  const RowMatrix& mean = view.episode_trajectories->predicted_mean;
  const RowMatrix& std = view.episode_trajectories->predicted_std;
  const bool predicted = mean.rows() == states.rows() && mean.cols() == states.cols();
  table.columns = {"t", "time"};
  for (const std::string& name : view.state_names) table.columns.push_back(name);
  for (const std::string& name : view.control_names) table.columns.push_back(name);
  if (predicted) {
    for (const std::string& name : view.state_names) table.columns.push_back("mean_" + name);
    for (const std::string& name : view.state_names) table.columns.push_back("std_" + name);
  }
  for (Eigen::Index t = 0; t < states.rows(); ++t) {
    std::vector<double> row = {static_cast<double>(t), static_cast<double>(t) * view.dt};
    for (Eigen::Index m = 0; m < states.cols(); ++m) row.push_back(states(t, m));
    for (Eigen::Index j = 0; j < controls.cols(); ++j)
      row.push_back(t < controls.rows() ? controls(t, j) : std::numeric_limits<double>::quiet_NaN());
    if (predicted) {
      for (Eigen::Index m = 0; m < mean.cols(); ++m) row.push_back(mean(t, m));
      for (Eigen::Index m = 0; m < std.cols(); ++m) row.push_back(std(t, m));
    }
    table.rows.push_back(std::move(row));
  }
  return table;
}

}  // namespace totalgrad::io
