// SqliteStore: sweep archives taken over (ImportJobs) and sweeps grown (GrowSweep)
// (sqlite_store.h).
#include <algorithm>
#include <map>
#include <set>
#include <string>
#include <tuple>
#include <utility>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "runtime/status_macros.h"
#include "server/storage/sqlite_internal.h"
#include "server/storage/sqlite_schema.h"
#include "server/storage/sqlite_store.h"

namespace totalgrad::storage {

using internal::Db;
using internal::Statement;
using namespace internal;  // the row helpers of sqlite_internal.h

namespace {

// The completion check of EndAttempt (the kind's rule, then every row of
// 0..total-1 of each of its tables) on the archived attempt `attempt` that
// completed `job`, once its rows are stored as `key`: a job with rows missing
// is not taken over as completed. InvalidArgument naming the job.
absl::Status CheckImportedCompletion(Db& db, const ImportedJob& job, const ImportedAttempt& attempt,
                                     const LeaseKey& key, int episodes_expected) {
  const JobKindInfo& kind = KindInfo(job.record.kind);
  const std::string name = absl::StrCat("archive: job ", job.record.method, " seed ",
                                        job.record.seed, " ", job.record.variant,
                                        " is completed by attempt ", attempt.attempt);
  if (kind.rule == CompletionRule::kJobExpected &&
      static_cast<int>(attempt.episodes.size()) != episodes_expected) {
    return absl::InvalidArgumentError(absl::StrCat(name, ", which holds ", attempt.episodes.size(),
                                                   " of its ", episodes_expected, " episodes"));
  }
  // What the archive holds stands for what a worker would have reported.
  JobResults rows;
  rows.study = attempt.study;
  rows.episodes.reserve(attempt.episodes.size());
  for (const auto& [episode, reported_ms] : attempt.episodes) rows.episodes.push_back(episode);
  ResultTotals reported;
  for (const ResultTable* table : kind.tables) {
    reported.*table->total = static_cast<int>(table->rows(rows));
  }
  absl::StatusOr<ResultTotals> required = RequiredRows(kind, key, episodes_expected, reported);
  if (!required.ok()) {
    return absl::InvalidArgumentError(absl::StrCat(name, ": ", required.status().message()));
  }
  for (const ResultTable* table : kind.tables) {
    const int total = (*required).*table->total;
    ASSIGN_OR_RETURN(std::vector<int> missing, MissingRows(db, key, *table, total));
    if (!missing.empty()) {
      return absl::InvalidArgumentError(absl::StrCat(name, ", which lacks ", table->noun, " ",
                                                     absl::StrJoin(missing, ","), " of 0..",
                                                     total - 1));
    }
  }
  return absl::OkStatus();
}

// The statements an import runs for every attempt, prepared once.
struct ImportStatements {
  Statement attempt_insert;
  Statement checkpoint_insert;
  Statement episode_insert;
  Statement stored_options;  // internal::StoredJobOptionsSql()
  Statement options_update;
};

// Stores archived attempt `a` of `job` as attempt `key` here: the attempt
// row, its checkpoint, episodes and study rows, each checked as a worker's
// report would be (tables the kind owns, episodes in range).
absl::Status ImportAttempt(Db& db, ImportStatements& statements, const ImportedJob& job,
                           const ImportedAttempt& a, const LeaseKey& key, int episodes_expected,
                           int64_t now_ms, ImportResult* result) {
  Statement& attempt_insert = statements.attempt_insert;
  Statement& checkpoint_insert = statements.checkpoint_insert;
  Statement& episode_insert = statements.episode_insert;
  // An attempt that was still open where the archive was written ran
  // nowhere here: it arrives released.
  const AttemptState arrived =
      a.state == AttemptState::kRunning ? AttemptState::kReleased : a.state;
  attempt_insert.Bind(1, key.job_id).Bind(2, key.attempt).Bind(3, ToString(arrived));
  attempt_insert.Bind(4, a.worker_id).Bind(5, a.worker_host).Bind(6, a.worker_build);
  attempt_insert.Bind(7, a.started_ms).Bind(8, a.ended_ms > 0 ? a.ended_ms : a.started_ms);
  attempt_insert.Bind(9, a.ended_ms > 0 ? a.ended_ms : now_ms).Bind(10, a.error);
  attempt_insert.Bind(11, a.origin);
  RETURN_IF_ERROR(attempt_insert.Run());
  attempt_insert.Reset();
  if (a.checkpoint.has_value()) {
    if (!KindInfo(job.record.kind).checkpoints) {
      return absl::InvalidArgumentError(absl::StrCat(
          "archive: job ", job.record.method, " seed ", job.record.seed, " attempt ",
          a.attempt, " has a checkpoint, but ", ToString(job.record.kind),
          " jobs keep none"));
    }
    if (a.checkpoint->episode < 0 || a.checkpoint->episode >= episodes_expected) {
      return absl::InvalidArgumentError(absl::StrCat(
          "archive: job ", job.record.method, " seed ", job.record.seed, " attempt ",
          a.attempt, ": checkpoint episode ", a.checkpoint->episode,
          " is out of range 0..", episodes_expected - 1));
    }
    checkpoint_insert.Bind(1, key.job_id).Bind(2, key.attempt).Bind(3, a.checkpoint->episode);
    checkpoint_insert.Bind(4, a.checkpoint->format_version);
    checkpoint_insert.BindBlob(5, a.checkpoint->data);
    checkpoint_insert.Bind(6, a.ended_ms > 0 ? a.ended_ms : now_ms);
    RETURN_IF_ERROR(checkpoint_insert.Run());
    checkpoint_insert.Reset();
    ++result->checkpoints_imported;
  }
  // Rows of a table the job's kind does not own are refused
  // (job_kinds.h); one row of each table is enough to tell.
  JobResults probe;
  probe.study = a.study;
  if (!a.episodes.empty()) probe.episodes.push_back(a.episodes.front().first);
  RETURN_IF_ERROR(CheckOwnedTables(KindInfo(job.record.kind), key.job_id, probe));
  for (const auto& [episode, reported_ms] : a.episodes) {
    if (episode.episode < 0 || episode.episode >= episodes_expected) {
      return absl::InvalidArgumentError(absl::StrCat(
          "archive: job ", job.record.method, " seed ", job.record.seed, " ",
          job.record.variant, " attempt ",
          a.attempt, ": episode ", episode.episode, " is out of range 0..",
          episodes_expected - 1));
    }
    BindEpisode(episode_insert, key, episode, reported_ms);
    RETURN_IF_ERROR(episode_insert.Run());
    episode_insert.Reset();
    ++result->episodes_imported;
  }
  if (!a.study.empty()) {
    OpenAttempt into;
    into.kind = job.record.kind;
    probe.episodes.clear();  // stored above, each with its own time
    RETURN_IF_ERROR(InsertResults(db, key, into, probe, now_ms));
    result->study_rows_imported += static_cast<int64_t>(a.study.size());
  }
  return absl::OkStatus();
}

// A job's identity in its sweep, as the job ids below are keyed. Seeds are
// stored as integers: "07" names seed 7, as SQLite's comparison of the text
// with the integer column did.
using JobIdentity = std::tuple<std::string, std::string, std::string, std::string>;

JobIdentity IdentityOf(JobKind kind, const std::string& method, const std::string& seed,
                       const std::string& variant) {
  int64_t seed_number = 0;
  return {std::string(ToString(kind)), method,
          absl::SimpleAtoi(seed, &seed_number) ? std::to_string(seed_number) : seed, variant};
}

// The sweep's jobs by identity, read once (internal::SweepJobIdsSql): no
// index covers a lookup by identity, so a query per imported (or grown) job
// scanned the whole sweep each time (100,000 jobs: over ten minutes; issue 28).
using SweepJobIds = std::map<JobIdentity, int64_t>;

absl::StatusOr<SweepJobIds> ReadSweepJobIds(Db& db, int64_t sweep_id) {
  SweepJobIds job_ids;
  ASSIGN_OR_RETURN(Statement all, Statement::Prepare(db, internal::SweepJobIdsSql()));
  all.Bind(1, sweep_id);
  while (true) {
    ASSIGN_OR_RETURN(bool row, all.Step());
    if (!row) break;
    job_ids.emplace(JobIdentity(all.ColumnText(1), all.ColumnText(2), all.ColumnText(3),
                                all.ColumnText(4)),
                    all.ColumnInt(0));
  }
  return job_ids;
}

// The keys whose values differ between two option lists (a key one list
// lacks differs), sorted.
std::set<std::string> DifferingKeys(const OptionPairs& a, const OptionPairs& b) {
  const std::map<std::string, std::string> in_a(a.begin(), a.end());
  const std::map<std::string, std::string> in_b(b.begin(), b.end());
  std::set<std::string> keys;
  for (const auto& [key, value] : in_a) {
    const auto found = in_b.find(key);
    if (found == in_b.end() || found->second != value) keys.insert(key);
  }
  for (const auto& [key, value] : in_b) {
    if (!in_a.count(key)) keys.insert(key);
  }
  return keys;
}

// The stored options must say what ran: this sweep's list for the job,
// unless the archive's trial ran others (ImportedJob::options_as_run), which
// are then stored as the job's own list and counted; the keys that differ
// are added to `kept`.
absl::Status KeepOptionsAsRun(ImportStatements& statements, SharedOptionsCache* cache,
                              const ImportedJob& job, int64_t job_id, std::set<std::string>* kept,
                              ImportResult* result) {
  if (!job.options_as_run.has_value()) return absl::OkStatus();
  Statement& stored = statements.stored_options;
  stored.Bind(1, job_id);
  ASSIGN_OR_RETURN(bool present, stored.Step());
  if (!present) return absl::InternalError(absl::StrCat("job ", job_id, " vanished"));
  std::optional<std::string> shared;
  if (!stored.ColumnIsNull(2)) shared = stored.ColumnText(2);
  const OptionPairs here = StoredJobOptions(stored.ColumnText(0), job.record.kind,
                                            job.record.method, stored.ColumnText(1),
                                            job.record.variant, shared, cache);
  stored.Reset();
  const std::set<std::string> differing = DifferingKeys(here, *job.options_as_run);
  if (differing.empty()) return absl::OkStatus();
  statements.options_update.Bind(1, OptionsToJson(*job.options_as_run)).Bind(2, job_id);
  RETURN_IF_ERROR(statements.options_update.Run());
  statements.options_update.Reset();
  kept->insert(differing.begin(), differing.end());
  ++result->jobs_keeping_options;
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<ImportResult> SqliteStore::ImportJobStream(const std::optional<NewSweep>& create,
                                                         const std::string& sweep_name,
                                                         const ImportedJobProducer& jobs,
                                                         const std::string& source,
                                                         int64_t now_ms) {
  ImportResult result;
  const absl::Status status = InWriteTransaction([&](Db& db) -> absl::Status {
    result = ImportResult();
    if (create.has_value()) {
      RETURN_IF_ERROR(InsertSweep(db, *create, now_ms, &result.sweep_created));
    }
    ASSIGN_OR_RETURN(Statement sweep_query,
                     Statement::Prepare(db, "SELECT id FROM sweeps WHERE name = ?"));
    sweep_query.Bind(1, sweep_name);
    ASSIGN_OR_RETURN(bool found, sweep_query.Step());
    if (!found) return absl::NotFoundError(absl::StrCat("no sweep named '", sweep_name, "'"));
    const int64_t sweep_id = sweep_query.ColumnInt(0);
    ASSIGN_OR_RETURN(const SweepJobIds job_ids, ReadSweepJobIds(db, sweep_id));
    ASSIGN_OR_RETURN(Statement job_query, Statement::Prepare(db, internal::ImportedJobStateSql()));
    ASSIGN_OR_RETURN(Statement attempt_insert, Statement::Prepare(db, R"sql(
INSERT INTO attempts(job_id, attempt, state, worker_id, worker_host, worker_build, started_ms,
                     lease_expires_ms, ended_ms, error, origin)
VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?))sql"));
    ASSIGN_OR_RETURN(Statement checkpoint_insert, Statement::Prepare(db, R"sql(
INSERT INTO checkpoints(job_id, attempt, episode, format_version, data, reported_ms)
VALUES(?, ?, ?, ?, ?, ?))sql"));
    ASSIGN_OR_RETURN(Statement episode_insert, Statement::Prepare(db, EpisodeInsertSql()));
    ASSIGN_OR_RETURN(Statement stored_options, Statement::Prepare(db, internal::StoredJobOptionsSql()));
    ASSIGN_OR_RETURN(Statement options_update,
                     Statement::Prepare(db, "UPDATE jobs SET options_json = ? WHERE id = ?"));
    ImportStatements statements{std::move(attempt_insert), std::move(checkpoint_insert),
                                std::move(episode_insert), std::move(stored_options),
                                std::move(options_update)};
    ASSIGN_OR_RETURN(Statement job_update, Statement::Prepare(db, R"sql(
UPDATE jobs SET state = 'completed', attempts = ?, completed_attempt = ?, success = ?,
                final_eval_cost = ?, failures = failures + ?, lost_leases = lost_leases + ?,
                last_error = ?
WHERE id = ?)sql"));
    SharedOptionsCache shared_options;
    std::set<std::string> options_kept;
    RETURN_IF_ERROR(jobs([&](const ImportedJob& job) -> absl::Status {
      const auto known = job_ids.find(IdentityOf(job.record.kind, job.record.method,
                                                  job.record.seed, job.record.variant));
      if (known == job_ids.end()) {
        ++result.jobs_unknown;
        return absl::OkStatus();
      }
      const int64_t job_id = known->second;
      job_query.Bind(1, job_id);
      ASSIGN_OR_RETURN(bool match, job_query.Step());
      if (!match) return absl::InternalError(absl::StrCat("job ", job_id, " vanished"));
      const std::string state = job_query.ColumnText(0);
      const int attempts_here = static_cast<int>(job_query.ColumnInt(1));
      const int episodes_expected = static_cast<int>(job_query.ColumnInt(2));
      job_query.Reset();
      if (state == ToString(JobState::kCompleted)) {
        ++result.jobs_already_complete;
        return absl::OkStatus();
      }
      if (job.record.state != JobState::kCompleted || job.completed_attempt <= 0) {
        ++result.jobs_not_completed;
        return absl::OkStatus();
      }
      if (state == ToString(JobState::kRunning)) {
        ++result.jobs_running_here;
        return absl::OkStatus();
      }
      int completed_here = 0;
      for (size_t i = 0; i < job.attempts.size(); ++i) {
        const ImportedAttempt& a = job.attempts[i];
        const int number = attempts_here + static_cast<int>(i) + 1;
        if (a.attempt == job.completed_attempt) completed_here = number;
        RETURN_IF_ERROR(ImportAttempt(db, statements, job, a, {job_id, number},
                                      episodes_expected, now_ms, &result));
        if (a.attempt == job.completed_attempt) {
          RETURN_IF_ERROR(CheckImportedCompletion(db, job, a, {job_id, number}, episodes_expected));
        }
      }
      if (completed_here == 0) {
        return absl::InvalidArgumentError(absl::StrCat(
            "archive: job ", job.record.method, " seed ", job.record.seed, " ", job.record.variant,
            " is completed by attempt ", job.completed_attempt, ", which the archive lacks"));
      }
      job_update.Bind(1, attempts_here + static_cast<int>(job.attempts.size()));
      job_update.Bind(2, completed_here).Bind(3, job.record.success ? 1 : 0);
      job_update.Bind(4, job.record.final_eval_cost).Bind(5, job.record.failures);
      job_update.Bind(6, job.record.lost_leases);
      job_update.Bind(7, job.record.last_error).Bind(8, job_id);
      RETURN_IF_ERROR(job_update.Run());
      job_update.Reset();
      RETURN_IF_ERROR(KeepOptionsAsRun(statements, &shared_options, job, job_id, &options_kept,
                                       &result));
      RETURN_IF_ERROR(AddEvent(db, now_ms, sweep_id, job_id, completed_here, "imported",
                               absl::StrCat("completed attempt ", job.completed_attempt, " of ",
                                            source, " (now attempt ", completed_here, ")")));
      ++result.jobs_imported;
      return absl::OkStatus();
    }));
    result.options_kept.assign(options_kept.begin(), options_kept.end());
    return AddEvent(db, now_ms, sweep_id, 0, 0, "sweep_imported",
                    absl::StrCat(source, ": ", result.jobs_imported, " jobs taken over, ",
                                 result.jobs_already_complete, " already complete here, ",
                                 result.jobs_not_completed, " not completed there"));
  });
  if (!status.ok()) return status;
  return result;
}

namespace {

// FailedPrecondition naming the first option whose stored text differs from
// `job`'s. Keys one side lacks are not compared: a key added after the job
// was stored defaults to the computation it ran (TrialOptionsFromStoredPairs).
absl::Status SameStoredOptions(const std::string& sweep, const NewJob& job, const OptionPairs& list) {
  const std::map<std::string, std::string> stored(list.begin(), list.end());
  for (const auto& [key, value] : job.options) {
    const auto found = stored.find(key);
    if (found == stored.end() || found->second == value) continue;
    return absl::FailedPreconditionError(absl::StrCat(
        "sweep '", sweep, "' cannot grow: its job ", job.method, " seed ", job.seed,
        job.variant.empty() ? "" : " (" + job.variant + ")", " is stored with ", key, " = ",
        found->second, ", and this coordinator resolves the same job to ", key, " = ", value,
        " (a default changed between builds); set ", key, " = ", found->second,
        " in the sweep file's [protocol] to grow it with the computation it ran, or submit it "
        "under a new name"));
  }
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<int> SqliteStore::GrowSweep(const NewSweep& grown, int64_t now_ms) {
  int added = 0;
  const absl::Status status = InWriteTransaction([&](Db& db) -> absl::Status {
    added = 0;
    ASSIGN_OR_RETURN(Statement sweep_query,
                     Statement::Prepare(db, "SELECT id, spec_hash FROM sweeps WHERE name = ?"));
    sweep_query.Bind(1, grown.name);
    ASSIGN_OR_RETURN(bool found, sweep_query.Step());
    if (!found) return absl::NotFoundError(absl::StrCat("no sweep named '", grown.name, "'"));
    const int64_t sweep_id = sweep_query.ColumnInt(0);
    const std::string previous_hash = sweep_query.ColumnText(1);
    ASSIGN_OR_RETURN(const SweepJobIds job_ids, ReadSweepJobIds(db, sweep_id));
    ASSIGN_OR_RETURN(Statement exists, Statement::Prepare(db, internal::StoredJobOptionsSql()));
    SharedOptionsCache shared_options;
    ASSIGN_OR_RETURN(Statement last, Statement::Prepare(
        db, "SELECT COALESCE(MAX(ordinal), -1) FROM jobs WHERE sweep_id = ?"));
    last.Bind(1, sweep_id);
    ASSIGN_OR_RETURN(bool any, last.Step());
    const int64_t ordinal = any ? last.ColumnInt(0) : -1;
    // Jobs are inserted as they are met: one the grown spec lists twice
    // does not exist (a job's identity is unique in a spec), so the ids read
    // before need no update, and an error rolls them all back.
    ASSIGN_OR_RETURN(QueuedJobInserter inserter,
                     QueuedJobInserter::Prepare(db, sweep_id, ordinal + 1));
    RETURN_IF_ERROR(grown.ForEachJob([&](const NewJob& job) -> absl::Status {
      const auto known = job_ids.find(IdentityOf(job.kind, job.method, job.seed, job.variant));
      if (known == job_ids.end()) return inserter.Insert(job);
      exists.Bind(1, known->second);
      ASSIGN_OR_RETURN(bool present, exists.Step());
      if (!present) return absl::InternalError(absl::StrCat("job ", known->second, " vanished"));
      std::optional<std::string> shared;
      if (!exists.ColumnIsNull(2)) shared = exists.ColumnText(2);
      const OptionPairs stored_options =
          StoredJobOptions(exists.ColumnText(0), job.kind, job.method, exists.ColumnText(1),
                           job.variant, shared, &shared_options);
      exists.Reset();
      // The stored job must be the job this build would run: a default
      // that changed between builds (e.g. a scene's own horizon) would
      // otherwise give the new jobs another computation than the old.
      return SameStoredOptions(grown.name, job, stored_options);
    }));
    added = static_cast<int>(inserter.inserted());
    ASSIGN_OR_RETURN(Statement update, Statement::Prepare(db, R"sql(
UPDATE sweeps SET canonical_spec = ?, spec_hash = ?, description = ?, source_name = ?,
                  source_text = ?
WHERE id = ?)sql"));
    update.Bind(1, grown.canonical_spec).Bind(2, grown.spec_hash).Bind(3, grown.description);
    update.Bind(4, grown.source_name).Bind(5, grown.source_text).Bind(6, sweep_id);
    RETURN_IF_ERROR(update.Run());
    RETURN_IF_ERROR(internal::CreateSweepView(db, sweep_id, grown.name));
    return AddEvent(db, now_ms, sweep_id, 0, 0, "sweep_grown",
                    absl::StrCat(added, " jobs added; spec ", previous_hash.substr(0, 12), " -> ",
                                 grown.spec_hash.substr(0, 12)));
  });
  if (!status.ok()) return status;
  return added;
}


namespace internal {
// Both read a sweep's jobs through the unique index on (sweep_id, ordinal),
// or one job by its id; storage_test checks the plans.
const char* SweepJobIdsSql() {
  return R"sql(
SELECT id, kind, method, CAST(seed AS TEXT), variant FROM jobs WHERE sweep_id = ?)sql";
}
const char* ImportedJobStateSql() {
  return "SELECT state, attempts, episodes_expected FROM jobs WHERE id = ?";
}
const char* StoredJobOptionsSql() {
  return R"sql(
SELECT j.options_json, j.seed, s.trial_options_json FROM jobs j JOIN sweeps s ON s.id = j.sweep_id
WHERE j.id = ?)sql";
}
}  // namespace internal

}  // namespace totalgrad::storage
