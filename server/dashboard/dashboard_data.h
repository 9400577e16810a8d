// What the dashboard shows, as JSON documents built from the store's read
// interface (server/storage/store.h, the same calls the gRPC handlers make)
// and the results library (results/: Wilson intervals, quartile curves,
// comparisons, Table 1), as the CLI's are. Nothing here writes.
//
// Every function returns the document or the store's error (NotFound for an
// unknown sweep or job, InvalidArgument for a bad parameter, Unavailable
// and others from SQLite). Thread-safe as the store is; the ETA cache is
// guarded by its own mutex.
#ifndef TOTALGRAD_SERVER_DASHBOARD_DASHBOARD_DATA_H_
#define TOTALGRAD_SERVER_DASHBOARD_DASHBOARD_DATA_H_

#include <chrono>
#include <cstdint>
#include <map>
#include <optional>
#include <utility>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"
#include "core/learner/checkpoint.h"
#include "server/storage/store.h"

namespace totalgrad::dashboard {

// ---- Estimated time to finish (pure, unit-tested) ----

// A job that is not finished: episodes its counting attempt has and needs.
struct RemainingJob {
  int episodes_stored = 0;
  int episodes_expected = 0;
};

// A stored episode: its index, the wall seconds the worker spent on it
// (`work_seconds`, from the episode's timing) and when it was stored.
struct EpisodeWork {
  int episode = 0;
  double work_seconds = 0;
  int64_t reported_ms = 0;
};

struct FinishEstimate {
  bool known = false;
  double seconds = 0;            // to finish, if known
  double remaining_work_s = 0;   // worker-seconds of trial work left
  double throughput = 0;         // worker-seconds of work done per second, recently
  std::string basis;             // how it was estimated, or why it is unknown
};

// The work left is the sum over unfinished jobs and their missing episodes
// of the median work of stored episodes with that index (episodes grow
// slower as the data grow, so index matters; an index not seen yet takes
// the nearest lower one seen: an underestimate while only early episodes
// are in). The rate is the work stored in the last `window_ms` (or since
// the first episode, if later) per second of that window. Unknown when
// nothing is left, no episode is stored yet, or none in the window.
FinishEstimate EstimateFinish(const std::vector<RemainingJob>& remaining,
                              const std::vector<EpisodeWork>& episodes, int64_t now_ms,
                              int64_t window_ms);

// Wall seconds of an episode from its details_json ("timing": the sum of
// the *_wall phases), else `fallback` (the optimisation seconds).
double EpisodeWorkSeconds(const std::string& details_json, double fallback);

// The curve of `method` in a curve panel ({"variant", "title", "threshold",
// "methods": [{"method", "colour", "trials", "points"}]}, the layout of
// /api/curves and /api/diagnostics), appended on first use with the method's
// colour (results::MethodColour); `slots` keeps each (variant, method)'s
// position across calls. Its "trials" becomes at least `trials`.
nlohmann::json& MethodCurve(nlohmann::json& panel, const std::string& variant,
                            const std::string& method, int trials,
                            std::map<std::pair<std::string, std::string>, size_t>* slots);

// ---- The documents ----

struct DashboardOptions {
  std::string build;     // the coordinator's BuildId()
  std::string database;  // the SQLite file's path
  int64_t lease_timeout_ms = 90000;  // workers unseen for longer are shown as gone
  int64_t eta_window_ms = 10 * 60 * 1000;
};

class DashboardData {
 public:
  // `store` is not owned and must outlive this object.
  DashboardData(storage::StoreReader* store, DashboardOptions options)
      : store_(store), options_(std::move(options)) {}

  // Sweeps (newest first) with progress and an estimated time to finish,
  // the workers, the coordinator's build and database.
  absl::StatusOr<nlohmann::json> Overview(int64_t now_ms);
  // One sweep: its progress and its success table's cells (success rate,
  // 95% Wilson interval, n, median final cost, the rollout verdict), one per
  // (method, variant), with the keys of `results table -f json`
  // (results::TableCellFields()).
  absl::StatusOr<nlohmann::json> Sweep(const std::string& name, int64_t now_ms);
  // Median and quartiles of the evaluation cost per method, variant and
  // episode, over completed trials and, with `include_running`, the
  // episodes running (and queued, partly done) trials have stored so far.
  absl::StatusOr<nlohmann::json> Curves(const std::string& name, bool include_running);
  // Methods compared per variant (results/comparison.h); `baseline` may be empty.
  absl::StatusOr<nlohmann::json> Compare(const std::string& name, const std::string& baseline);
  // The paper's Table 1 from the completed trials of the named sweeps
  // (results/table1.h): the grid's rows, methods and the paper's protocol,
  // its 32 cells with the keys of `results table1 -f json`
  // (results::Table1CellFields()), and the trials outside the grid.
  // InvalidArgument with no name or when a seed would be counted twice
  // (results::ComputeTable1); NotFound for an unknown sweep.
  absl::StatusOr<nlohmann::json> Table1(const std::vector<std::string>& names);
  // The sweep's jobs (at most `limit`, from job id `after`).
  absl::StatusOr<nlohmann::json> Jobs(const std::string& name, int64_t after, int limit);
  // One job: its options, attempts, events and every attempt's episodes.
  absl::StatusOr<nlohmann::json> Job(int64_t job_id);
  // What a trial recorded of episode `episode` (or, rollout >= 0, of that
  // verdict rollout of it), from its checkpoint: io/trajectory_json.h's
  // document plus "job" and "episodes_recorded" (the episodes that hold
  // trajectories). NotFound: no such job, no checkpoint yet, or the episode
  // holds none (inside_trials.cc).
  absl::StatusOr<nlohmann::json> Trajectory(int64_t job_id, int episode, int rollout);
  // The final episode of every completed trial of the sweep that recorded
  // trajectories: its goal distance per step with the verdict rule, its
  // threshold verdict (success, final_eval_cost) and rollout verdict
  // (held_fraction); "without" counts the completed trials that recorded none.
  absl::StatusOr<nlohmann::json> FinalTrajectories(const std::string& sweep_name);
  // The estimator statistic `statistic` (one of results::DiagnosticStatistics())
  // of the sweep's completed trials per method and episode, as curve panels
  // (one per variant, the layout of Curves, points with the keys of
  // results::DiagnosticPointFields()). InvalidArgument for an unknown
  // statistic, NotFound for an unknown sweep.
  absl::StatusOr<nlohmann::json> Diagnostics(const std::string& name, const std::string& statistic);

 private:
  absl::StatusOr<FinishEstimate> Estimate(const storage::SweepRecord& sweep, int64_t now_ms);
  absl::StatusOr<std::vector<storage::JobRecord>> AllJobs(const std::string& sweep_name);
  // The job's checkpoint, decoded (inside_trials.cc); nullopt: none.
  absl::StatusOr<std::optional<learner::TrialCheckpoint>> JobCheckpoint(
      const storage::JobRecord& job);
  // A completed trial's entry of FinalTrajectories (nullopt: it recorded no
  // trajectories), decoded from its final checkpoint at most once a minute:
  // the sweep page asks every few seconds, a completed attempt's checkpoint
  // never changes, and `sweep prune --completed` (which removes it) shows
  // within the minute.
  absl::StatusOr<std::optional<nlohmann::json>> FinalTrajectorySummary(
      const storage::JobRecord& job);

  storage::StoreReader* const store_;
  const DashboardOptions options_;

  // ETAs are recomputed only when a sweep's stored episodes or job counts
  // change (or a minute has passed), not on every poll of every browser.
  struct CachedEstimate {
    std::string key;
    int64_t computed_ms = 0;
    FinishEstimate estimate;
  };
  absl::Mutex cache_mutex_;
  std::map<int64_t, CachedEstimate> eta_cache_ ABSL_GUARDED_BY(cache_mutex_);  // by sweep id
  static constexpr std::chrono::seconds kFinalTrajectoryCacheLife{60};
  static constexpr size_t kFinalTrajectoryCacheEntries = 20000;  // then expired ones go
  struct CachedFinalTrajectory {
    std::chrono::steady_clock::time_point computed;
    std::optional<nlohmann::json> summary;
  };
  // By (job id, completed attempt).
  std::map<std::pair<int64_t, int>, CachedFinalTrajectory> final_trajectory_cache_
      ABSL_GUARDED_BY(cache_mutex_);
};

}  // namespace totalgrad::dashboard

#endif  // TOTALGRAD_SERVER_DASHBOARD_DASHBOARD_DATA_H_
