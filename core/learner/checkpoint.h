// Trial checkpoints: the state of a policy-learning trial (learner::RunTrial)
// after a finished episode, i.e. everything the next episode reads, so that
// a trial interrupted anywhere (a killed worker) resumes from its last
// finished episode and gives the same bits as an uninterrupted run.
//
// What the next episode reads, and where it is kept:
//   * the data: every observed transition so far (states, forces, next states);
//   * the policy's parameters (the warm start of the next optimisation);
//   * the GP hyperparameters of the last model (the warm start of the next
//     training), and the FITC inducing inputs of the last sparse fit (the
//     warm start of the next one; empty while the full GP is used);
//   * the policy optimiser's running averages (RmspropLike::State; reset at
//     the start of every episode's optimisation today, kept so a change to
//     that cannot silently break resumption);
//   * the results of episodes 0..episode, which a resumed trial reports
//     again (so the attempt that resumes holds every episode);
//   * random numbers: none to keep. Every stream is derived statelessly from
//     (seed, stream, index) at its point of use (core/common/rng.h; in a trial
//     the index is the episode, the gradient step or the evaluation rollout),
//     so a resumed episode draws exactly what it would have drawn.
// PILCO's BFGS state lives inside one episode's optimisation and is not
// carried; its problem (cost, start state) is rebuilt from the options.
//
// Format (EncodeCheckpoint/DecodeCheckpoint): binary, little-endian,
//   "TGCKPT\0\0" | u32 format version (kCheckpointFormatVersion; versions back to
//   kOldestCheckpointFormatVersion are read) | fields |
//   u64 FNV-1a of everything before it,
// doubles as their IEEE-754 bits (exact, NaN kept), so what is decoded is
// bit for bit what was encoded. A version outside that range is refused, not
// guessed at.
//
// Threading: free functions and plain data.
#ifndef TOTALGRAD_CORE_LEARNER_CHECKPOINT_H_
#define TOTALGRAD_CORE_LEARNER_CHECKPOINT_H_

#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "core/common/types.h"
#include "core/gp/gp.h"
#include "core/learner/optimizer.h"
#include "core/learner/trial.h"

namespace totalgrad::learner {

// 4: each episode also holds its trajectories (trajectory.h; version 3 and
// older read with none);
// 3: each episode also lists the record's fields added since version 1 by
// name and type (held_fraction, the optimisation diagnostics, lr_share);
// 2: the same, doubles only, untyped (issue 25's first build); 1: the fixed
// fields only (the others read as their defaults, NaN).
inline constexpr int kCheckpointFormatVersion = 4;
inline constexpr int kOldestCheckpointFormatVersion = 1;

struct TrialCheckpoint {
  // The last finished episode (0: the random one).
  int episode = 0;
  // The trial's options as TrialOptionPairs: a checkpoint resumes only the
  // trial it was taken from.
  std::vector<std::pair<std::string, std::string>> options;
  // Results of episodes 0..episode, in order, as the observer saw them.
  std::vector<EpisodeResult> episodes;
  RowMatrix states;       // N x D, observed x_t of every transition so far
  Vector forces;          // N F, transition-major (Transitions::forces)
  RowMatrix next_states;  // N x D, observed x_{t+1}
  Vector policy_parameters;
  std::optional<gp::GpHyperparameters> hyperparameters;  // none before the first model
  RowMatrix inducing_inputs;  // FITC warm start; 0 x 0 if no sparse fit yet
  std::optional<RmspropLike::State> optimizer;  // particle methods only
};

std::string EncodeCheckpoint(const TrialCheckpoint& checkpoint);

// InvalidArgument naming the problem: not a checkpoint, another format
// version, truncated or corrupt (checksum), inconsistent sizes.
absl::StatusOr<TrialCheckpoint> DecodeCheckpoint(std::string_view bytes);

// OK if `checkpoint` can resume a trial with `options`: the same option
// pairs, an episode within the trial, consistent data. InvalidArgument
// naming the first difference otherwise.
absl::Status CheckResumable(const TrialCheckpoint& checkpoint, const TrialOptions& options);

}  // namespace totalgrad::learner

#endif  // TOTALGRAD_CORE_LEARNER_CHECKPOINT_H_
