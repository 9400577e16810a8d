// Text renderings of trial results, shared by the CLI commands.
#ifndef TOTALGRAD_CLIENT_CORE_COMMANDS_TRIAL_FORMAT_H_
#define TOTALGRAD_CLIENT_CORE_COMMANDS_TRIAL_FORMAT_H_

#include <string>

#include <nlohmann/json.hpp>

#include "core/learner/trial.h"

namespace totalgrad::cli {

// An episode as JSON: io::EpisodeToJson (io/episode_json.h), the layout of
// the stored record and details.
// Short text of the set flags ("-" when none).
std::string FlagsText(const learner::EpisodeFlags& flags);

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_CORE_COMMANDS_TRIAL_FORMAT_H_
