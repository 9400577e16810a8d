// An episode's trajectories (core/learner/trajectory.h) as JSON, one layout
// for `totalgrad job trajectory -f json` and the dashboard's job page:
//
//   {"episode": E, "scene": name, "dt": seconds per step,
//    "state_names": [D], "control_names": [F],
//    "real_cost": the episode's stored cost,
//    "states": [[D] x (H+1)], "controls": [[F] x H],
//    "predicted_mean": [[D] x (H+1)] or [], "predicted_std": likewise,
//    "verdict_rollouts": how many the episode holds,
//    "goal_distance": [H+1] tasks::GoalDistance of each state (on the
//                     cart-pole the tip's distance from upright, metres),
//    "verdict_distance", "verdict_hold_steps": the rollout verdict's rule,
//    "geometry": {"cart": the cart position's state index or null,
//                 "links": [{"angle": state index, "length": metres}]}
//                (angles from hanging down, counter-clockwise; a link's
//                end is (sin a, -cos a) x length from its start),
//    "rollout": R (only when one verdict rollout is shown: "states" and
//               "controls" are then rollout R's, and "predicted_*" the
//               episode's prediction as before)}
//
// Non-finite numbers are null. Names come from the scene catalog
// (core/tasks/scene_catalog.h); a scene it does not list gets x1..xD and
// u1..uF.
#ifndef TOTALGRAD_IO_TRAJECTORY_JSON_H_
#define TOTALGRAD_IO_TRAJECTORY_JSON_H_

#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/status/statusor.h"
#include "core/learner/checkpoint.h"

namespace totalgrad::io {

// What one view of a trial's trajectories shows: the real episode E, or
// rollout R of the verdict rollouts that episode E holds.
struct TrajectoryView {
  std::string scene;
  double dt = 0;
  std::vector<std::string> state_names;
  std::vector<std::string> control_names;
  int episode = 0;
  int rollout = -1;  // -1: the real episode
  double real_cost = 0;
  int verdict_rollouts = 0;
  const learner::StateTrajectory* shown = nullptr;       // into the checkpoint
  const learner::EpisodeTrajectories* episode_trajectories = nullptr;
  std::vector<double> goal_distance;  // per state row of `shown`
  double verdict_distance = 0;
  int verdict_hold_steps = 0;
  int cart_index = -1;  // -1: no cart
  std::vector<std::pair<int, double>> links;  // (angle's state index, length m)
};

// The view of episode `episode` (rollout -1) or of its verdict rollout
// `rollout` in `checkpoint`, which must outlive it. NotFound naming what is
// missing: an episode the checkpoint does not hold yet, an episode recorded
// without trajectories (by a build before them: checkpoint version < 4), a
// rollout beyond those held. InvalidArgument when the checkpoint's options
// do not give a scene.
absl::StatusOr<TrajectoryView> ViewTrajectory(const learner::TrialCheckpoint& checkpoint,
                                              int episode, int rollout);

nlohmann::ordered_json TrajectoryToJson(const TrajectoryView& view);

// Rows t = 0..H: t, time (t dt), the states, the controls (none at t = H:
// NaN), the prediction's means then stds (absent when there is none), with
// their column names ("theta", "u", "mean_theta", "std_theta").
struct TrajectoryTable {
  std::vector<std::string> columns;
  std::vector<std::vector<double>> rows;
};
TrajectoryTable TrajectoryRows(const TrajectoryView& view);

}  // namespace totalgrad::io

#endif  // TOTALGRAD_IO_TRAJECTORY_JSON_H_
