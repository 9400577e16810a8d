// What an episode did, beside its numbers (issue 27 item 2): the real
// trajectory (true states and the controls applied), the model's multi-step
// prediction of the optimised policy, and on a trial's last episode the
// rollouts the rollout verdict classified. learner::RunTrial fills them
// (EpisodeResult::trajectories); recording them reads the computation and
// never alters a number of the trial.
//
// Format (EncodeEpisodeTrajectories / DecodeEpisodeTrajectories): binary,
// little-endian (core/common/binary_codec.h),
//   "TGTRAJ\0\0" | u32 format version (kTrajectoryFormatVersion) |
//   real.states | real.controls | predicted_mean | predicted_std |
//   u64 rollouts | per rollout: states | controls | u64 FNV-1a of all before,
// each matrix as u64 rows, u64 cols and its doubles row by row, exact.
// Stored as the opaque `trajectories` bytes of an episode by the worker, the
// coordinator's store and sweep archives (base64 there).
//
// Sizes: a cart-pole swing-up trial of the paper's protocol (H = 30, D = 4,
// F = 1, 15 learned episodes, 100 verdict rollouts) encodes 177.3 KB:
// 21,584 doubles (16 real episodes of 31 x 4 states and 30 controls, 15
// predictions of 2 x 31 x 4, 100 rollouts of 154 doubles) and the headers.
//
// Threading: free functions and plain data.
#ifndef TOTALGRAD_CORE_LEARNER_TRAJECTORY_H_
#define TOTALGRAD_CORE_LEARNER_TRAJECTORY_H_

#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "core/common/types.h"
#include "core/tasks/scene.h"

namespace totalgrad::learner {

inline constexpr int kTrajectoryFormatVersion = 1;

// One real episode: x_0..x_H and u_0..u_{H-1}.
struct StateTrajectory {
  RowMatrix states;    // (H+1) x D, the true states (not the noisy observations)
  RowMatrix controls;  // H x F, row t the controls applied at x_t
  bool empty() const { return states.size() == 0 && controls.size() == 0; }
};

// The states and controls of a tasks::Episode (its forces are step-major,
// F per step).
StateTrajectory TrajectoryOfEpisode(const tasks::Episode& episode);

struct EpisodeTrajectories {
  // The episode whose data were added (episode 0: the random one).
  StateTrajectory real;
  // The model's prediction of the optimised policy's episode from the
  // start distribution, per time step t = 0..H and state dimension:
  // particle methods, the mean and sample standard deviation (divisor
  // P - 1) of the predicted-cost rollout's particles (predicted_cost_
  // particles of them); PILCO, the moment-matched mean and the square root
  // of its covariance's diagonal. (H+1) x D each; empty for episode 0.
  RowMatrix predicted_mean;
  RowMatrix predicted_std;
  // The last episode only (when the trial classifies its final policy):
  // the verdict_rollouts rollouts in the order ClassifyController ran them.
  std::vector<StateTrajectory> verdict_rollouts;
  bool empty() const {
    return real.empty() && predicted_mean.size() == 0 && predicted_std.size() == 0 &&
           verdict_rollouts.empty();
  }
};

// Bytes of the format above; the same bytes for the same trajectories.
std::string EncodeEpisodeTrajectories(const EpisodeTrajectories& trajectories);
// InvalidArgument naming the problem: not trajectories, another format
// version, truncated or corrupt (checksum), inconsistent sizes (a state
// matrix with other than one row more than its controls; a prediction whose
// mean and std differ in shape).
absl::StatusOr<EpisodeTrajectories> DecodeEpisodeTrajectories(std::string_view bytes);

}  // namespace totalgrad::learner

#endif  // TOTALGRAD_CORE_LEARNER_TRAJECTORY_H_
