// An episode (learner::EpisodeResult) as JSON: one layout for the stored
// details and for `totalgrad trial --json`.
//
//   EpisodeDetailsJson  everything of the episode beyond its record, the
//       object the worker sends and the coordinator stores verbatim as
//       `details_json` (docs/results_schema.md): "gp": {"log_lengthscales"
//       [[...] x inputs] x outputs, "log_signal_std", "log_noise_std"} (not
//       for episode 0), "flags", "cpu_seconds", "timing" ({<phase>_cpu,
//       <phase>_wall for model, policy, prediction, real_episode, evaluation;
//       policy_steps}) and, for PILCO, "predicted_cost_mean_per_step" /
//       "predicted_cost_std_per_step" (steps 1..H). Non-finite numbers: null.
//   EpisodeToJson  the episode's record (learner::EpisodeFields(): the
//       stored row's columns, io/record_format.h) with the details' keys.
//   TrialSummaryJson  a finished trial's verdict: "success",
//       "final_eval_cost", "threshold", "held_fraction" (null without a
//       rollout verdict) and "options" (every option used, key -> text);
//       `totalgrad trial --json`'s last line and Python's summary().
#ifndef TOTALGRAD_IO_EPISODE_JSON_H_
#define TOTALGRAD_IO_EPISODE_JSON_H_

#include <string>

#include <nlohmann/json.hpp>

#include "core/learner/trial.h"

namespace totalgrad::io {

std::string EpisodeDetailsJson(const learner::EpisodeResult& result);
nlohmann::json EpisodeToJson(const learner::EpisodeResult& result);
nlohmann::json TrialSummaryJson(const learner::TrialSummary& summary,
                                const learner::TrialOptions& options);

}  // namespace totalgrad::io

#endif  // TOTALGRAD_IO_EPISODE_JSON_H_
