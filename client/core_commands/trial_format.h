// Text and JSON renderings of trial results, shared by the CLI commands.
#ifndef TOTALGRAD_CLIENT_CORE_COMMANDS_TRIAL_FORMAT_H_
#define TOTALGRAD_CLIENT_CORE_COMMANDS_TRIAL_FORMAT_H_

#include <string>

#include <nlohmann/json.hpp>

#include "core/learner/trial.h"

namespace totalgrad::cli {

// {"episode", "real_cost", "eval_cost_mean", "eval_cost_std", "predicted_cost",
//  "seconds" (wall, model fit + policy optimisation), "cpu_seconds" (the whole
//  episode), "timing": {<phase>_cpu, <phase>_wall for phase in model, policy,
//  prediction, real_episode, evaluation; policy_steps}, "flags": {...},
//  "gp": {"log_lengthscales": [[...] x E] x D, "log_signal_std": [D],
//  "log_noise_std": [D]}} (the layout of the stored details_json,
//  docs/results_schema.md), and for PILCO episodes
// "predicted_cost_mean_per_step" / "predicted_cost_std_per_step" (H numbers
// each, steps 1..H); NaN becomes null.
nlohmann::json EpisodeToJson(const learner::EpisodeResult& result);

// Short text of the set flags ("-" when none).
std::string FlagsText(const learner::EpisodeFlags& flags);

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_CORE_COMMANDS_TRIAL_FORMAT_H_
