// Trial snapshots (learner::TrialSnapshot) as JSON files, written by
// `totalgrad trial --snapshot-episodes 1,5,10 --snapshot-file FILE` and read
// by `totalgrad study` (docs/error-vs-time.md).
//
// File format (numbers are written with round-trip precision, so a snapshot
// read back rebuilds the trial's model and policy bit for bit):
//   {"format": "totalgrad-trial-snapshots", "version": 1,
//    "snapshots": [
//      {"episode": 3,
//       "options": {"scene": "cartpole-swingup", ...},   // TrialOptionPairs, in order
//       "states": [[s, beta, s_dot, beta_dot], ...],     // N x D (here the cart-pole), observed x_t
//       "forces": [...],                                 // N F: the F controls of each transition in turn
//       "next_states": [[...], ...],                     // N x D, observed x_{t+1}
//       "hyperparameters": {"log_lengthscales": [[...], ...],  // D x E
//                           "log_signal_std": [...], "log_noise_std": [...]},
//       "policy_parameters_before": [...],
//       "policy_parameters": [...]},
//      ...]}
#ifndef TOTALGRAD_IO_SNAPSHOT_JSON_H_
#define TOTALGRAD_IO_SNAPSHOT_JSON_H_

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/status/statusor.h"
#include "core/learner/trial.h"

namespace totalgrad::io {

nlohmann::ordered_json SnapshotsToJson(const std::vector<learner::TrialSnapshot>& snapshots);

// InvalidArgument naming the field (and index) that is missing, mistyped,
// ragged or not finite.
absl::StatusOr<std::vector<learner::TrialSnapshot>> SnapshotsFromJson(const nlohmann::json& doc);

// Writes atomically (temporary file, then rename), so a reader never sees a
// half-written file. Errors name the path.
absl::Status WriteSnapshotFile(const std::string& path,
                               const std::vector<learner::TrialSnapshot>& snapshots);
absl::StatusOr<std::vector<learner::TrialSnapshot>> ReadSnapshotFile(const std::string& path);

// "1,5,10" -> {1, 5, 10}; InvalidArgument for anything but positive integers.
absl::StatusOr<std::vector<int>> ParseEpisodeList(const std::string& text);

}  // namespace totalgrad::io

#endif  // TOTALGRAD_IO_SNAPSHOT_JSON_H_
