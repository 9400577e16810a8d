// The dashboard's documents of what happened inside trials (issue 27):
// Trajectory and FinalTrajectories, what a trial recorded of its episodes,
// read from the trial checkpoint the store keeps (core/learner/trajectory.h;
// checkpoint version 4 and later hold them) in io/trajectory_json.h's
// layout; Diagnostics, the estimator statistics per method and episode
// (results/diagnostics.h, as `totalgrad results diagnostics`).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <utility>
#include <optional>

#include "absl/strings/str_cat.h"
#include "core/learner/checkpoint.h"
#include "io/record_format.h"
#include "io/trajectory_json.h"
#include "results/diagnostics.h"
#include "server/dashboard/dashboard_data.h"

namespace totalgrad::dashboard {
namespace {

using nlohmann::json;

json FiniteOrNull(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

}  // namespace

// A completed job's checkpoint is its completed attempt's final state;
// otherwise the latest of any attempt (as ControlService::GetJobArtifacts).
absl::StatusOr<std::optional<learner::TrialCheckpoint>> DashboardData::JobCheckpoint(
    const storage::JobRecord& job) {
  absl::StatusOr<std::optional<storage::CheckpointRecord>> stored =
      store_->GetCheckpoint(job.id, job.completed_attempt);
  if (!stored.ok()) return stored.status();
  if (!stored->has_value()) return std::optional<learner::TrialCheckpoint>();
  absl::StatusOr<learner::TrialCheckpoint> decoded =
      learner::DecodeCheckpoint((*stored)->checkpoint.data);
  if (!decoded.ok()) {
    return absl::FailedPreconditionError(absl::StrCat(
        "job ", job.id, ": its checkpoint (attempt ", (*stored)->key.attempt, ", build ",
        (*stored)->worker_build, ") does not decode here: ", decoded.status().message()));
  }
  return std::optional<learner::TrialCheckpoint>(*std::move(decoded));
}

absl::StatusOr<json> DashboardData::Trajectory(int64_t job_id, int episode, int rollout) {
  absl::StatusOr<storage::JobRecord> job = store_->GetJob(job_id);
  if (!job.ok()) return job.status();
  absl::StatusOr<std::optional<learner::TrialCheckpoint>> checkpoint = JobCheckpoint(*job);
  if (!checkpoint.ok()) return checkpoint.status();
  if (!checkpoint->has_value()) {
    return absl::NotFoundError(absl::StrCat("job ", job_id, " has no trial checkpoint yet"));
  }
  absl::StatusOr<io::TrajectoryView> view = io::ViewTrajectory(**checkpoint, episode, rollout);
  if (!view.ok()) return view.status();
  json out(io::TrajectoryToJson(*view));  // ordered_json -> json, no text in between
  out["job"] = job_id;
  // Which episodes can be shown (recorded with trajectories), for the picker.
  json recorded = json::array();
  for (const learner::EpisodeResult& e : (*checkpoint)->episodes)
    if (!e.trajectories.real.empty()) recorded.push_back(e.episode);
  out["episodes_recorded"] = std::move(recorded);
  return out;
}

absl::StatusOr<std::optional<json>> DashboardData::FinalTrajectorySummary(
    const storage::JobRecord& job) {
  const auto now = std::chrono::steady_clock::now();
  const std::pair<int64_t, int> key{job.id, job.completed_attempt};
  {
    absl::MutexLock lock(&cache_mutex_);
    const auto cached = final_trajectory_cache_.find(key);
    if (cached != final_trajectory_cache_.end() &&
        now - cached->second.computed < kFinalTrajectoryCacheLife) {
      return cached->second.summary;
    }
  }
  absl::StatusOr<std::optional<learner::TrialCheckpoint>> checkpoint = JobCheckpoint(job);
  if (!checkpoint.ok()) return checkpoint.status();
  std::optional<json> summary;
  if (checkpoint->has_value()) {
    const int last = (*checkpoint)->episode;
    absl::StatusOr<io::TrajectoryView> view = io::ViewTrajectory(**checkpoint, last, -1);
    if (view.ok()) {  // else recorded by a build before trajectories
      json distance = json::array();
      for (double v : view->goal_distance) distance.push_back(FiniteOrNull(v));
      summary = json{{"job", job.id},
                     {"method", job.method},
                     {"seed", job.seed},
                     {"variant", job.variant},
                     {"episode", last},
                     {"success", job.success},
                     {"final_eval_cost", FiniteOrNull(job.final_eval_cost)},
                     {"held_fraction", FiniteOrNull(job.held_fraction)},
                     {"dt", FiniteOrNull(view->dt)},
                     {"verdict_distance", FiniteOrNull(view->verdict_distance)},
                     {"verdict_hold_steps", view->verdict_hold_steps},
                     {"goal_distance", std::move(distance)}};
    }
  }
  absl::MutexLock lock(&cache_mutex_);
  // Entries of deleted sweeps or pruned checkpoints are never asked for
  // again: drop the expired ones whenever the cache has grown large.
  if (final_trajectory_cache_.size() >= kFinalTrajectoryCacheEntries) {
    std::erase_if(final_trajectory_cache_, [&](const auto& entry) {
      return now - entry.second.computed >= kFinalTrajectoryCacheLife;
    });
  }
  final_trajectory_cache_[key] = {now, summary};
  return summary;
}

absl::StatusOr<json> DashboardData::FinalTrajectories(const std::string& sweep_name) {
  absl::StatusOr<std::vector<storage::JobRecord>> jobs = AllJobs(sweep_name);
  if (!jobs.ok()) return jobs.status();
  json out = {{"sweep", sweep_name}, {"trials", json::array()}, {"without", 0}};
  int without = 0;
  for (const storage::JobRecord& job : *jobs) {
    if (job.kind != storage::JobKind::kTrial || job.state != storage::JobState::kCompleted) continue;
    absl::StatusOr<std::optional<json>> summary = FinalTrajectorySummary(job);
    if (!summary.ok()) return summary.status();
    if (!summary->has_value()) {
      ++without;
      continue;
    }
    out["trials"].push_back(**std::move(summary));
  }
  out["without"] = without;
  return out;
}

absl::StatusOr<json> DashboardData::Diagnostics(const std::string& name,
                                                const std::string& statistic) {
  const std::vector<std::string>& known = results::DiagnosticStatistics();
  if (std::find(known.begin(), known.end(), statistic) == known.end()) {
    return absl::InvalidArgumentError(absl::StrCat("unknown statistic '", statistic, "'"));
  }
  absl::StatusOr<storage::SweepRecord> sweep = store_->GetSweep(name);
  if (!sweep.ok()) return sweep.status();
  // The completed trials' counting attempts (ExportEpisodes' final attempts).
  std::vector<results::EpisodeStatistics> rows;
  const absl::Status exported = store_->ExportEpisodes(
      name, /*all_attempts=*/false, /*batch_size=*/2000,
      [&](std::vector<storage::EpisodeRowRecord> batch) {
        for (storage::EpisodeRowRecord& row : batch) {
          if (!row.final_attempt) continue;
          rows.push_back({row.method, row.variant, std::move(row.episode)});
        }
        return absl::OkStatus();
      });
  if (!exported.ok()) return exported;
  json out = {{"statistic", statistic}, {"statistics", known}, {"panels", json::array()}};
  std::map<std::string, size_t> panel_of;
  std::map<std::pair<std::string, std::string>, size_t> method_slot;
  for (const results::DiagnosticPoint& diagnostic : results::DiagnosticCurves(rows, statistic)) {
    const results::CurvePoint& p = diagnostic.curve;
    auto [panel_slot, new_panel] = panel_of.emplace(p.variant, out["panels"].size());
    if (new_panel) {
      out["panels"].push_back({{"variant", p.variant},
                               {"title", p.variant.empty() ? statistic : statistic + ", " + p.variant},
                               {"threshold", nullptr},
                               {"y_label", statistic},
                               {"methods", json::array()}});
    }
    json& method = MethodCurve(out["panels"][panel_slot->second], p.variant, p.method,
                               p.values.trials, &method_slot);
    json point = json::object();
    io::AppendRecordJson(results::DiagnosticPointFields(), diagnostic, &point);
    point["n"] = p.values.trials;
    method["points"].push_back(std::move(point));
  }
  return out;
}

}  // namespace totalgrad::dashboard
