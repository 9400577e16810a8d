#include "server/dashboard/dashboard_data.h"

#include <algorithm>
#include <cmath>
#include <set>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "io/record_format.h"
#include "results/comparison.h"
#include "results/plot_style.h"
#include "results/stats.h"
#include "results/table1.h"
#include "server/storage/service_records.h"
#include "server/storage/store_results_reader.h"

namespace totalgrad::dashboard {
namespace {

using nlohmann::json;

// NaN and infinities are not JSON numbers: null.
json Number(double value) { return std::isfinite(value) ? json(value) : json(nullptr); }

double Median(std::vector<double> values) { return results::Quantile(std::move(values), 0.5); }

// A sweep summary and a job are their records' JSON (the field tables of
// server/storage/service_records.h, io/record_format.h's format): the same
// keys and values as `totalgrad sweep list -f json` and `job list -f json`.
json SweepJson(const storage::SweepRecord& s) {
  json out = json::object();
  io::AppendRecordJson(storage::SweepFields(), s, &out);
  return out;
}

json EstimateJson(const FinishEstimate& e) {
  return {{"known", e.known},
          {"seconds", e.known ? json(e.seconds) : json(nullptr)},
          {"remaining_work_s", Number(e.remaining_work_s)},
          {"throughput", Number(e.throughput)},
          {"basis", e.basis}};
}

json JobJson(const storage::JobRecord& j) {
  json out = json::object();
  io::AppendRecordJson(storage::JobFields(), j, &out);
  return out;
}

// The episode's record (io/record_format.h), and the work seconds.
json EpisodeJson(const storage::Episode& e) {
  json out = json::object();
  io::AppendRecordJson<learner::EpisodeSummary>(learner::EpisodeFields(), e, &out);
  out["work_seconds"] = Number(EpisodeWorkSeconds(e.details_json, e.optimisation_seconds));
  return out;
}

std::string FormatSeconds(double seconds) {
  if (seconds < 120) return absl::StrFormat("%.0f s", seconds);
  if (seconds < 7200) return absl::StrFormat("%.0f min", seconds / 60);
  return absl::StrFormat("%.1f h", seconds / 3600);
}

// Stops an export once the rows of the wanted job are past (rows come
// ordered by job): not an error.
constexpr absl::string_view kPastTheJob = "past the job";

}  // namespace

json& MethodCurve(json& panel, const std::string& variant, const std::string& method,
                  int trials, std::map<std::pair<std::string, std::string>, size_t>* slots) {
  auto [slot, inserted] = slots->emplace(std::pair{variant, method}, panel["methods"].size());
  if (inserted) {
    panel["methods"].push_back({{"method", method},
                                {"colour", results::MethodColour(method)},
                                {"trials", 0},
                                {"points", json::array()}});
  }
  json& curve = panel["methods"][slot->second];
  curve["trials"] = std::max(curve["trials"].get<int>(), trials);
  return curve;
}

double EpisodeWorkSeconds(const std::string& details_json, double fallback) {
  const json details = json::parse(details_json, nullptr, /*allow_exceptions=*/false);
  if (details.is_object()) {
    auto timing = details.find("timing");
    if (timing != details.end() && timing->is_object()) {
      double wall = 0;
      bool any = false;
      for (auto it = timing->begin(); it != timing->end(); ++it) {
        const std::string& key = it.key();
        if (key.size() > 5 && key.compare(key.size() - 5, 5, "_wall") == 0 &&
            it->is_number()) {
          wall += it->get<double>();
          any = true;
        }
      }
      if (any) return wall;
    }
  }
  return fallback;
}

FinishEstimate EstimateFinish(const std::vector<RemainingJob>& remaining,
                              const std::vector<EpisodeWork>& episodes, int64_t now_ms,
                              int64_t window_ms) {
  FinishEstimate estimate;
  int64_t missing_episodes = 0;
  for (const RemainingJob& job : remaining) {
    missing_episodes += std::max(0, job.episodes_expected - job.episodes_stored);
  }
  if (missing_episodes == 0) {
    estimate.basis = "no episode left to run";
    return estimate;
  }
  std::map<int, std::vector<double>> by_index;
  int64_t first_ms = now_ms;
  for (const EpisodeWork& e : episodes) {
    if (!std::isfinite(e.work_seconds) || e.work_seconds < 0) continue;
    by_index[e.episode].push_back(e.work_seconds);
    first_ms = std::min(first_ms, e.reported_ms);
  }
  if (by_index.empty()) {
    estimate.basis = "no episode finished yet";
    return estimate;
  }
  std::map<int, double> typical;  // median work per episode index
  for (auto& [index, values] : by_index) typical[index] = Median(values);
  auto work_of = [&](int index) {
    auto it = typical.upper_bound(index);  // first index > `index`
    if (it == typical.begin()) return it->second;  // only later indices seen
    return std::prev(it)->second;                  // this index, or the nearest lower one
  };
  for (const RemainingJob& job : remaining) {
    for (int e = std::max(0, job.episodes_stored); e < job.episodes_expected; ++e) {
      estimate.remaining_work_s += work_of(e);
    }
  }
  const int64_t window_start = std::max(now_ms - window_ms, first_ms);
  const double window_s = std::max(1.0, (now_ms - window_start) / 1000.0);
  double done = 0;
  for (const EpisodeWork& e : episodes) {
    if (e.reported_ms >= window_start && std::isfinite(e.work_seconds) && e.work_seconds >= 0) {
      done += e.work_seconds;
    }
  }
  estimate.throughput = done / window_s;
  if (done <= 0) {
    estimate.basis = absl::StrCat("no episode stored in the last ", FormatSeconds(window_s),
                                  " (no worker running it?)");
    return estimate;
  }
  estimate.known = true;
  estimate.seconds = estimate.remaining_work_s / estimate.throughput;
  estimate.basis = absl::StrFormat(
      "%s of trial work left (%d episodes, each at the median time of its index so far); "
      "%.1f worker-seconds of work done per second over the last %s",
      FormatSeconds(estimate.remaining_work_s), missing_episodes, estimate.throughput,
      FormatSeconds(window_s));
  return estimate;
}

absl::StatusOr<std::vector<storage::JobRecord>> DashboardData::AllJobs(
    const std::string& sweep_name) {
  std::vector<storage::JobRecord> all;
  storage::JobFilter filter;
  filter.sweep_name = sweep_name;
  filter.limit = 1000;
  while (true) {
    absl::StatusOr<std::vector<storage::JobRecord>> page = store_->ListJobs(filter);
    if (!page.ok()) return page.status();
    const bool full = static_cast<int>(page->size()) == filter.limit;
    for (auto& job : *page) all.push_back(std::move(job));
    if (!full) break;
    filter.after_job_id = all.back().id;
  }
  return all;
}

absl::StatusOr<FinishEstimate> DashboardData::Estimate(const storage::SweepRecord& sweep,
                                                       int64_t now_ms) {
  FinishEstimate none;
  if (sweep.finished()) {
    none.basis = "finished";
    return none;
  }
  if (sweep.state == storage::SweepState::kPaused) {
    none.basis = "paused: no new jobs are handed out";
    return none;
  }
  if (sweep.state == storage::SweepState::kCancelled) {
    none.basis = "cancelled";
    return none;
  }
  const std::string key =
      absl::StrCat(sweep.episodes_stored, "/", sweep.jobs_queued, "/", sweep.jobs_running, "/",
                   sweep.jobs_completed, "/", sweep.jobs_failed, "/", sweep.jobs_cancelled);
  {
    absl::MutexLock lock(&cache_mutex_);
    auto it = eta_cache_.find(sweep.id);
    if (it != eta_cache_.end() && it->second.key == key &&
        now_ms - it->second.computed_ms < 60 * 1000) {
      FinishEstimate cached = it->second.estimate;
      if (cached.known) {
        cached.seconds = std::max(0.0, cached.seconds - (now_ms - it->second.computed_ms) / 1e3);
      }
      return cached;
    }
  }
  absl::StatusOr<std::vector<storage::JobRecord>> jobs = AllJobs(sweep.name);
  if (!jobs.ok()) return jobs.status();
  std::vector<RemainingJob> remaining;
  for (const storage::JobRecord& job : *jobs) {
    if (job.kind != storage::JobKind::kTrial) continue;
    if (job.state == storage::JobState::kQueued || job.state == storage::JobState::kRunning) {
      remaining.push_back({job.episodes_stored, job.episodes_expected});
    }
  }
  std::vector<EpisodeWork> episodes;
  const absl::Status exported = store_->ExportEpisodes(
      sweep.name, /*all_attempts=*/false, /*batch_size=*/2000,
      [&](std::vector<storage::EpisodeRowRecord> rows) {
        for (const storage::EpisodeRowRecord& row : rows) {
          episodes.push_back(
              {row.episode.episode,
               EpisodeWorkSeconds(row.episode.details_json, row.episode.optimisation_seconds),
               row.reported_ms});
        }
        return absl::OkStatus();
      });
  if (!exported.ok()) return exported;
  FinishEstimate estimate = EstimateFinish(remaining, episodes, now_ms, options_.eta_window_ms);
  if (!remaining.empty() && remaining.size() < static_cast<size_t>(sweep.jobs_queued + sweep.jobs_running)) {
    estimate.basis += "; study jobs not counted";
  }
  absl::MutexLock lock(&cache_mutex_);
  eta_cache_[sweep.id] = {key, now_ms, estimate};
  return estimate;
}

absl::StatusOr<json> DashboardData::Overview(int64_t now_ms) {
  absl::StatusOr<std::vector<storage::SweepRecord>> sweeps = store_->ListSweeps();
  if (!sweeps.ok()) return sweeps.status();
  json out = {{"build", options_.build},
              {"database", options_.database},
              {"now_ms", now_ms},
              {"sweeps", json::array()},
              {"workers", json::array()}};
  for (const storage::SweepRecord& sweep : *sweeps) {
    json entry = SweepJson(sweep);
    absl::StatusOr<FinishEstimate> eta = Estimate(sweep, now_ms);
    if (!eta.ok()) return eta.status();
    entry["eta"] = EstimateJson(*eta);
    out["sweeps"].push_back(std::move(entry));
  }
  absl::StatusOr<std::vector<storage::WorkerRecord>> workers = store_->ListWorkers();
  if (!workers.ok()) return workers.status();
  for (const storage::WorkerRecord& w : *workers) {
    const bool gone = now_ms - w.last_seen_ms > options_.lease_timeout_ms;
    out["workers"].push_back({{"id", w.identity.worker_id},
                              {"host", w.identity.host},
                              {"build", w.identity.build},
                              {"slots", w.identity.slots},
                              {"running", w.running},
                              {"state", gone ? "gone" : w.draining ? "draining" : "active"},
                              {"last_seen_ms", w.last_seen_ms}});
  }
  return out;
}

absl::StatusOr<json> DashboardData::Sweep(const std::string& name, int64_t now_ms) {
  absl::StatusOr<storage::SweepRecord> sweep = store_->GetSweep(name);
  if (!sweep.ok()) return sweep.status();
  json out = {{"sweep", SweepJson(*sweep)}};
  absl::StatusOr<FinishEstimate> eta = Estimate(*sweep, now_ms);
  if (!eta.ok()) return eta.status();
  out["sweep"]["eta"] = EstimateJson(*eta);

  storage::StoreResultsReader reader(store_);
  absl::StatusOr<std::vector<results::CompletedTrial>> completed = reader.CompletedTrials(name);
  if (!completed.ok()) return completed.status();
  json table = {{"methods", json::array()}, {"variants", json::array()}, {"cells", json::array()}};
  for (const results::TableCell& cell : results::SuccessTable(*completed)) {
    if (std::find(table["methods"].begin(), table["methods"].end(), cell.method) ==
        table["methods"].end()) {
      table["methods"].push_back(cell.method);
    }
    if (std::find(table["variants"].begin(), table["variants"].end(), cell.variant) ==
        table["variants"].end()) {
      table["variants"].push_back(cell.variant);
    }
    // The cell's record: the keys of `results table -f json`.
    json record = json::object();
    io::AppendRecordJson(results::TableCellFields(), cell, &record);
    table["cells"].push_back(std::move(record));
  }
  // Each method's colour in every plot (results/plot_style.h).
  table["colours"] = json::object();
  for (const json& method : table["methods"]) {
    table["colours"][method.get<std::string>()] = results::MethodColour(method.get<std::string>());
  }
  out["table"] = std::move(table);
  return out;
}

absl::StatusOr<json> DashboardData::Curves(const std::string& name, bool include_running) {
  absl::StatusOr<std::vector<storage::JobRecord>> jobs = AllJobs(name);
  if (!jobs.ok()) return jobs.status();
  if (jobs->empty()) {
    absl::StatusOr<storage::SweepRecord> sweep = store_->GetSweep(name);  // NotFound?
    if (!sweep.ok()) return sweep.status();
  }
  std::map<int64_t, storage::JobState> state_of;
  std::vector<results::CurvePanel> panels;
  std::set<std::string> described;
  for (const storage::JobRecord& job : *jobs) {
    if (job.kind != storage::JobKind::kTrial) continue;
    state_of[job.id] = job.state;
    if (described.insert(job.variant).second) {
      panels.push_back(results::DescribePanel(job.variant, job.options));
    }
  }
  std::vector<results::EpisodeValue> values;
  std::set<int64_t> trials_in_curves;
  const absl::Status exported = store_->ExportEpisodes(
      name, /*all_attempts=*/false, /*batch_size=*/2000,
      [&](std::vector<storage::EpisodeRowRecord> rows) {
        for (const storage::EpisodeRowRecord& row : rows) {
          auto state = state_of.find(row.job_id);
          if (state == state_of.end()) continue;
          const bool completed = state->second == storage::JobState::kCompleted;
          const bool unfinished = state->second == storage::JobState::kRunning ||
                                  state->second == storage::JobState::kQueued;
          if (!completed && !(include_running && unfinished)) continue;
          trials_in_curves.insert(row.job_id);
          values.push_back({row.method, row.variant, row.episode.episode,
                            row.episode.eval_cost_mean});
        }
        return absl::OkStatus();
      });
  if (!exported.ok()) return exported;

  json out = {{"include_running", include_running},
              {"trials", trials_in_curves.size()},
              {"panels", json::array()}};
  std::map<std::string, json> by_variant;
  for (const results::CurvePanel& panel : panels) {
    by_variant[panel.variant] = {{"variant", panel.variant},
                                 {"title", panel.title},
                                 {"threshold", Number(panel.threshold)},
                                 {"methods", json::array()}};
  }
  std::map<std::pair<std::string, std::string>, size_t> method_slot;
  for (const results::CurvePoint& p : results::Curves(values)) {
    json& panel = by_variant[p.variant];
    if (panel.is_null()) {
      const results::CurvePanel described_panel = results::DescribePanel(p.variant, {});
      panel = {{"variant", p.variant}, {"title", described_panel.title},
               {"threshold", nullptr}, {"methods", json::array()}};
    }
    json& method = MethodCurve(panel, p.variant, p.method, p.values.trials, &method_slot);
    method["points"].push_back({{"episode", p.episode},
                                {"n", p.values.trials},
                                {"q25", Number(p.values.q25)},
                                {"median", Number(p.values.median)},
                                {"q75", Number(p.values.q75)}});
  }
  for (const results::CurvePanel& panel : panels) out["panels"].push_back(by_variant[panel.variant]);
  for (auto& [variant, panel] : by_variant) {
    if (!described.count(variant)) out["panels"].push_back(panel);
  }
  return out;
}

absl::StatusOr<json> DashboardData::Compare(const std::string& name, const std::string& baseline) {
  storage::StoreResultsReader reader(store_);
  absl::StatusOr<std::vector<results::CompletedTrial>> trials = reader.CompletedTrials(name);
  if (!trials.ok()) return trials.status();
  results::ComparisonOptions options;
  options.baseline = baseline;
  absl::StatusOr<results::ComparisonReport> report = results::CompareMethods(*trials, options);
  if (!report.ok()) return report.status();
  json out = {{"alpha", options.alpha},
              {"baseline", baseline},
              {"methods", report->methods},
              {"variants", report->variants},
              {"comparisons", json::array()}};
  for (const results::Comparison& c : report->comparisons) {
    out["comparisons"].push_back(
        {{"variant", c.variant},
         {"method", c.method},
         {"vs", c.other},
         {"pairs", c.success.pairs},
         {"both_succeeded", c.success.both},
         {"method_only", c.success.method_only},
         {"vs_only", c.success.other_only},
         {"neither", c.success.neither},
         {"success_difference", Number(c.success.difference)},
         {"success_difference95_low", Number(c.success.difference95_low)},
         {"success_difference95_high", Number(c.success.difference95_high)},
         {"mcnemar_p", Number(c.success.mcnemar_p)},
         {"mcnemar_p_holm", Number(c.success.mcnemar_p_holm)},
         {"mcnemar_power", Number(c.success.mcnemar_power)},
         {"cost_pairs", c.cost_pairs},
         {"cost_shift_hl", Number(c.wilcoxon.hodges_lehmann)},
         {"rank_biserial", Number(c.wilcoxon.rank_biserial)},
         {"wilcoxon_w_plus", Number(c.wilcoxon.w_plus)},
         {"wilcoxon_exact", c.wilcoxon.exact},
         {"wilcoxon_p", Number(c.wilcoxon.p)},
         {"wilcoxon_p_holm", Number(c.wilcoxon_p_holm)},
         {"wilcoxon_power", Number(c.wilcoxon_power)},
         {"method_trials", c.method_trials},
         {"method_successes", c.method_successes},
         {"vs_trials", c.other_trials},
         {"vs_successes", c.other_successes},
         {"rate_difference", Number(c.rate_difference)},
         {"odds_ratio", std::isinf(c.odds_ratio) ? json("inf") : Number(c.odds_ratio)},
         {"fisher_p", Number(c.fisher_p)},
         {"fisher_p_holm", Number(c.fisher_p_holm)},
         {"fisher_power", Number(c.fisher_power)},
         {"success_verdict", results::SuccessVerdict(c, options.alpha)},
         {"cost_verdict", results::CostVerdict(c, options.alpha)}});
  }
  return out;
}

absl::StatusOr<json> DashboardData::Table1(const std::vector<std::string>& names) {
  if (names.empty()) return absl::InvalidArgumentError("name at least one sweep");
  storage::StoreResultsReader reader(store_);
  absl::StatusOr<std::vector<results::CompletedTrial>> trials =
      results::ReadCompletedTrials(reader, names);
  if (!trials.ok()) return trials.status();
  absl::StatusOr<results::Table1> table = results::ComputeTable1(*trials);
  if (!table.ok()) return table.status();
  json out = {{"sweeps", names},
              {"methods", results::Table1Methods()},
              {"rows", json::array()},
              {"protocol", json::array()},
              {"cells", json::array()},
              {"outside", table->outside},
              {"trials_outside", table->trials_outside}};
  for (const results::Table1Row& row : results::Table1Rows()) {
    out["rows"].push_back({{"cost", row.cost}, {"noise_k", row.noise_k}, {"label", row.Label()}});
  }
  for (const auto& [key, value] : results::PaperProtocol()) out["protocol"].push_back({key, value});
  out["colours"] = json::object();
  for (const std::string& method : results::Table1Methods()) {
    out["colours"][method] = results::MethodColour(method);
  }
  for (const results::Table1Cell& cell : table->cells) {
    json record = json::object();
    io::AppendRecordJson(results::Table1CellFields(), cell, &record);
    out["cells"].push_back(std::move(record));
  }
  return out;
}

absl::StatusOr<json> DashboardData::Jobs(const std::string& name, int64_t after, int limit) {
  if (limit < 1 || limit > 10000) {
    return absl::InvalidArgumentError("limit must be in 1..10000");
  }
  absl::StatusOr<storage::SweepRecord> sweep = store_->GetSweep(name);
  if (!sweep.ok()) return sweep.status();
  storage::JobFilter filter;
  filter.sweep_name = name;
  filter.after_job_id = after;
  filter.limit = limit;
  absl::StatusOr<std::vector<storage::JobRecord>> jobs = store_->ListJobs(filter);
  if (!jobs.ok()) return jobs.status();
  json out = {{"jobs", json::array()}, {"next_after", nullptr}};
  for (const storage::JobRecord& job : *jobs) out["jobs"].push_back(JobJson(job));
  if (static_cast<int>(jobs->size()) == limit) out["next_after"] = jobs->back().id;
  return out;
}

absl::StatusOr<json> DashboardData::Job(int64_t job_id) {
  absl::StatusOr<storage::JobRecord> job = store_->GetJob(job_id);
  if (!job.ok()) return job.status();
  absl::StatusOr<std::vector<storage::AttemptRecord>> attempts = store_->ListAttempts(job_id);
  if (!attempts.ok()) return attempts.status();
  absl::StatusOr<std::vector<storage::EventRecord>> events = store_->ListEvents(job_id);
  if (!events.ok()) return events.status();
  json out = {{"job", JobJson(*job)},
              {"sweep", job->sweep_name},
              {"options", json::array()},
              {"attempts", json::array()},
              {"events", json::array()},
              {"episodes", json::array()}};
  for (const auto& [key, value] : job->options) out["options"].push_back({key, value});
  for (const storage::AttemptRecord& a : *attempts) {
    out["attempts"].push_back({{"attempt", a.key.attempt},
                               {"state", std::string(storage::ToString(a.state))},
                               {"worker", a.worker_id},
                               {"host", a.worker_host},
                               {"build", a.worker_build},
                               {"started_ms", a.started_ms},
                               {"ended_ms", a.ended_ms},
                               {"episodes_stored", a.episodes_stored},
                               {"error", a.error}});
  }
  for (const storage::EventRecord& e : *events) {
    out["events"].push_back(
        {{"ms", e.ms}, {"attempt", e.attempt}, {"kind", e.kind}, {"message", e.message}});
  }
  // Every attempt's episodes of this job; rows are ordered by job, so the
  // export stops once it is past this one.
  const absl::Status exported = store_->ExportEpisodes(
      job->sweep_name, /*all_attempts=*/true, /*batch_size=*/500,
      [&](std::vector<storage::EpisodeRowRecord> rows) -> absl::Status {
        for (const storage::EpisodeRowRecord& row : rows) {
          if (row.job_id < job_id) continue;
          if (row.job_id > job_id) return absl::CancelledError(kPastTheJob);
          json episode = EpisodeJson(row.episode);
          episode["attempt"] = row.attempt;
          episode["final_attempt"] = row.final_attempt;
          episode["reported_ms"] = row.reported_ms;
          out["episodes"].push_back(std::move(episode));
        }
        return absl::OkStatus();
      });
  if (!exported.ok() && exported.message() != kPastTheJob) return exported;
  return out;
}

}  // namespace totalgrad::dashboard
