// The trial options as command-line flags, shared by `totalgrad trial` and
// `totalgrad bench trial`: every key of learner::TrialOptionKeys() is a flag of
// its own (key noise_k is --noise-k), and `--set KEY=VALUE` reaches any key.
#ifndef TOTALGRAD_CLIENT_CORE_COMMANDS_TRIAL_FLAGS_H_
#define TOTALGRAD_CLIENT_CORE_COMMANDS_TRIAL_FLAGS_H_

#include <map>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "absl/status/status.h"
#include "core/learner/trial.h"

namespace totalgrad::cli {

// What the flags collected; owned by the command (it must outlive parsing).
struct TrialFlagValues {
  std::map<std::string, std::string> values;  // key -> text given ("" = not given)
  std::vector<std::string> sets;              // --set KEY=VALUE, in order
};

// Adds one flag per trial option and --set to `cmd`, with the defaults of
// `defaults` in the help text. Keys in `skip` get no flag (a command that
// sets them itself); --set still reaches them.
void AddTrialOptionFlags(CLI::App* cmd, const learner::TrialOptions& defaults,
                         TrialFlagValues* values, const std::vector<std::string>& skip = {});

// Sets *options to the collected flags over the defaults, the scene's for
// the keys of learner::SceneDefaultedKeys() (learner::TrialOptionsFromPairs),
// then validates the result. InvalidArgument names the flag or key
// that is wrong, including a key given both as a flag and by --set (which one
// should win would be a guess).
absl::Status ApplyTrialOptionFlags(const TrialFlagValues& values, learner::TrialOptions* options);

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_CORE_COMMANDS_TRIAL_FLAGS_H_
