#include "server/service/sweep_archive.h"

#include <google/protobuf/util/json_util.h>

#include <cmath>
#include <limits>
#include <map>
#include <optional>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "core/study/study.h"
#include "io/record_format.h"
#include "server/common/record_proto.h"
#include "server/service/convert.h"
#include "server/storage/job_kinds.h"

namespace totalgrad::service {
namespace {

nlohmann::ordered_json Number(double v) {
  return std::isfinite(v) ? nlohmann::ordered_json(v) : nlohmann::ordered_json(nullptr);
}

// A study row of an archive: {"index", ...the record's fields}.
template <typename Record, typename Row>
nlohmann::ordered_json RowJson(const record::FieldTable<Record>& table, const Row& row) {
  Record record;
  record_proto::RecordFromProto(table, row, &record);
  nlohmann::ordered_json object = {{"index", row.index()}};
  io::AppendRecordJson(table, record, &object);
  return object;
}

// Reads a row that RowJson wrote into *stored (a storage row: the record
// and its index). False when it is not one.
template <typename Record, typename Stored>
bool RowFromJson(const record::FieldTable<Record>& table, const nlohmann::json& row,
                 Stored* stored) {
  if (!row.is_object() || !row.contains("index") || !row["index"].is_number_integer()) return false;
  stored->index = row["index"].get<int>();
  return io::RecordFromJson<Record>(table, row, "", stored).ok();
}

std::string JobStateText(v1::JobState state) {
  switch (state) {
    case v1::JOB_STATE_QUEUED: return "queued";
    case v1::JOB_STATE_RUNNING: return "running";
    case v1::JOB_STATE_COMPLETED: return "completed";
    case v1::JOB_STATE_FAILED: return "failed";
    case v1::JOB_STATE_CANCELLED: return "cancelled";
    default: return "unknown";
  }
}

std::string AttemptStateText(v1::AttemptState state) {
  switch (state) {
    case v1::ATTEMPT_STATE_RUNNING: return "running";
    case v1::ATTEMPT_STATE_COMPLETED: return "completed";
    case v1::ATTEMPT_STATE_FAILED: return "failed";
    case v1::ATTEMPT_STATE_LEASE_LOST: return "lease_lost";
    case v1::ATTEMPT_STATE_RELEASED: return "released";
    case v1::ATTEMPT_STATE_CANCELLED: return "cancelled";
    default: return "unknown";
  }
}

std::string SweepStateText(v1::SweepState state) {
  switch (state) {
    case v1::SWEEP_STATE_RUNNING: return "running";
    case v1::SWEEP_STATE_PAUSED: return "paused";
    case v1::SWEEP_STATE_CANCELLED: return "cancelled";
    default: return "unknown";
  }
}

// Field readers with errors that name where in the archive.
class Reader {
 public:
  explicit Reader(std::string where) : where_(std::move(where)) {}
  absl::Status Error(const std::string& field) const {
    return absl::InvalidArgumentError(
        absl::StrCat("archive: ", where_, "'", field, "' is missing or mistyped"));
  }
  absl::StatusOr<std::string> String(const nlohmann::json& o, const char* field) const {
    if (!o.contains(field) || !o[field].is_string()) return Error(field);
    return o[field].get<std::string>();
  }
  absl::StatusOr<int64_t> Integer(const nlohmann::json& o, const char* field) const {
    if (!o.contains(field) || !o[field].is_number_integer()) return Error(field);
    return o[field].get<int64_t>();
  }
  // null reads as NaN.
  absl::StatusOr<double> Real(const nlohmann::json& o, const char* field) const {
    if (!o.contains(field)) return Error(field);
    if (o[field].is_null()) return std::numeric_limits<double>::quiet_NaN();
    if (!o[field].is_number()) return Error(field);
    return o[field].get<double>();
  }

 private:
  std::string where_;
};

#define TG_READ(var, expr)            \
  auto var##_or = (expr);             \
  if (!var##_or.ok()) return var##_or.status(); \
  const auto var = *var##_or

}  // namespace

nlohmann::ordered_json SweepArchiveToJson(const v1::SweepInfo& sweep,
                                          const std::vector<ArchiveJobInput>& jobs,
                                          const std::string& exported_by, int64_t exported_ms) {
  nlohmann::ordered_json doc;
  doc["format"] = kSweepArchiveFormat;
  doc["version"] = kSweepArchiveVersion;
  doc["exported_by"] = exported_by;
  doc["exported_unix_ms"] = exported_ms;
  doc["sweep"] = {{"name", sweep.name()},
                  {"description", sweep.description()},
                  {"state", SweepStateText(sweep.state())},
                  {"spec_hash", sweep.spec_hash()},
                  {"canonical_spec", sweep.canonical_spec()},
                  {"coordinator_build", sweep.coordinator_build()},
                  {"created_unix_ms", sweep.created_unix_ms()},
                  {"source_name", sweep.source_name()},
                  {"max_attempts", sweep.max_attempts()},
                  {"max_lost_leases", sweep.max_lost_leases()},
                  {"max_concurrent", sweep.max_concurrent()}};
  nlohmann::ordered_json job_array = nlohmann::ordered_json::array();
  for (const ArchiveJobInput& input : jobs) {
    const v1::JobInfo& job = input.job;
    nlohmann::ordered_json options = nlohmann::ordered_json::object();
    for (const auto& option : job.options()) options[option.key()] = option.value();
    int64_t seed = 0;
    nlohmann::ordered_json seed_json = job.seed();
    if (absl::SimpleAtoi(job.seed(), &seed)) seed_json = seed;
    int completed_attempt = 0;
    nlohmann::ordered_json attempts = nlohmann::ordered_json::array();
    for (const v1::AttemptInfo& attempt : input.attempts) {
      if (attempt.state() == v1::ATTEMPT_STATE_COMPLETED) completed_attempt = attempt.attempt();
      nlohmann::ordered_json episodes = nlohmann::ordered_json::array();
      for (const v1::EpisodeRow& row : input.episodes) {
        if (row.attempt() != attempt.attempt()) continue;
        const v1::EpisodeReport& e = row.report();
        // The episode's record (io/record_format.h), then when and the details.
        learner::EpisodeSummary summary;
        record_proto::RecordFromProto(learner::EpisodeFields(), e, &summary);
        nlohmann::ordered_json episode = io::RecordToJson(learner::EpisodeFields(), summary);
        episode["reported_unix_ms"] = row.reported_unix_ms();
        const nlohmann::ordered_json details =
            nlohmann::ordered_json::parse(e.details_json(), nullptr, false);
        episode["details"] =
            details.is_discarded() ? nlohmann::ordered_json(e.details_json()) : details;
        episodes.push_back(std::move(episode));
      }
      // Study rows: the records' JSON (io/record_format.h, the objects of a
      // study's results.json) after the row's index.
      nlohmann::ordered_json cells = nlohmann::ordered_json::array();
      for (const v1::StudyCellRow& cell : input.cells) {
        if (cell.attempt() == attempt.attempt()) cells.push_back(RowJson(study::CellFields(), cell));
      }
      nlohmann::ordered_json references = nlohmann::ordered_json::array();
      for (const v1::StudyReferenceRow& reference : input.references) {
        if (reference.attempt() == attempt.attempt()) {
          references.push_back(RowJson(study::ReferenceFields(), reference));
        }
      }
      attempts.push_back({{"attempt", attempt.attempt()},
                          {"state", AttemptStateText(attempt.state())},
                          {"worker_id", attempt.worker_id()},
                          {"worker_host", attempt.worker_host()},
                          {"worker_build", attempt.worker_build()},
                          {"started_unix_ms", attempt.started_unix_ms()},
                          {"ended_unix_ms", attempt.ended_unix_ms()},
                          {"error", attempt.error()},
                          {"episodes", std::move(episodes)},
                          {"study_cells", std::move(cells)},
                          {"study_references", std::move(references)}});
    }
    job_array.push_back({{"kind", storage::ToString(FromProto(job.kind()))},
                         {"method", job.method()},
                         {"seed", seed_json},
                         {"variant", job.variant()},
                         {"options", std::move(options)},
                         {"state", JobStateText(job.state())},
                         {"attempts", job.attempts()},
                         {"failures", job.failures()},
                         {"lost_leases", job.lost_leases()},
                         {"last_error", job.last_error()},
                         {"success", job.success()},
                         {"final_eval_cost", Number(job.final_eval_cost())},
                         {"completed_attempt",
                          job.state() == v1::JOB_STATE_COMPLETED ? completed_attempt : 0},
                         {"attempt_log", std::move(attempts)}});
  }
  doc["jobs"] = std::move(job_array);
  return doc;
}

absl::StatusOr<ParsedSweepArchive> ParseSweepArchive(const std::string& text) {
  const nlohmann::json doc = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded() || !doc.is_object())
    return absl::InvalidArgumentError("archive: not a JSON document");
  const Reader top("");
  TG_READ(format, top.String(doc, "format"));
  if (format != kSweepArchiveFormat)
    return absl::InvalidArgumentError(absl::StrCat("archive: format '", format, "' is not '",
                                                   kSweepArchiveFormat, "'"));
  TG_READ(version, top.Integer(doc, "version"));
  if (version < 1 || version > kSweepArchiveVersion)
    return absl::InvalidArgumentError(absl::StrCat("archive: version ", version,
                                                   "; this build reads versions 1 to ",
                                                   kSweepArchiveVersion));
  if (!doc.contains("sweep") || !doc["sweep"].is_object()) return top.Error("sweep");
  const nlohmann::json& sweep = doc["sweep"];
  const Reader sr("sweep: ");
  ParsedSweepArchive archive;
  TG_READ(name, sr.String(sweep, "name"));
  TG_READ(spec, sr.String(sweep, "canonical_spec"));
  TG_READ(hash, sr.String(sweep, "spec_hash"));
  TG_READ(state, sr.String(sweep, "state"));
  archive.name = name;
  archive.canonical_spec = spec;
  archive.spec_hash = hash;
  const std::optional<storage::SweepState> sweep_state = storage::ParseSweepState(state);
  if (!sweep_state) return sr.Error("state");
  archive.state = *sweep_state;
  if (!doc.contains("jobs") || !doc["jobs"].is_array()) return top.Error("jobs");
  int index = 0;
  for (const nlohmann::json& j : doc["jobs"]) {
    const Reader jr(absl::StrCat("jobs[", index++, "]: "));
    if (!j.is_object()) return jr.Error("{}");
    storage::ImportedJob job;
    TG_READ(kind, jr.String(j, "kind"));
    // The kinds' names are the job-kind table's (server/storage/job_kinds.h).
    const std::optional<storage::JobKind> parsed_kind = storage::ParseJobKind(kind);
    if (!parsed_kind) return jr.Error("kind");
    job.kind = *parsed_kind;
    TG_READ(method, jr.String(j, "method"));
    job.method = method;
    if (!j.contains("seed")) return jr.Error("seed");
    if (j["seed"].is_number_integer()) job.seed = std::to_string(j["seed"].get<int64_t>());
    else if (j["seed"].is_string()) job.seed = j["seed"].get<std::string>();
    else return jr.Error("seed");
    TG_READ(variant, jr.String(j, "variant"));
    job.variant = variant;
    TG_READ(job_state, jr.String(j, "state"));
    const std::optional<storage::JobState> parsed_state = storage::ParseJobState(job_state);
    if (!parsed_state) return jr.Error("state");
    job.state = *parsed_state;
    TG_READ(failures, jr.Integer(j, "failures"));
    TG_READ(lost, jr.Integer(j, "lost_leases"));
    TG_READ(last_error, jr.String(j, "last_error"));
    TG_READ(final_cost, jr.Real(j, "final_eval_cost"));
    TG_READ(completed, jr.Integer(j, "completed_attempt"));
    if (!j.contains("success") || !j["success"].is_boolean()) return jr.Error("success");
    job.failures = static_cast<int>(failures);
    job.lost_leases = static_cast<int>(lost);
    job.last_error = last_error;
    job.final_eval_cost = final_cost;
    job.completed_attempt = static_cast<int>(completed);
    job.success = j["success"].get<bool>();
    if (!j.contains("attempt_log") || !j["attempt_log"].is_array()) return jr.Error("attempt_log");
    for (const nlohmann::json& a : j["attempt_log"]) {
      storage::ImportedAttempt attempt;
      TG_READ(number, jr.Integer(a, "attempt"));
      TG_READ(attempt_state, jr.String(a, "state"));
      const std::optional<storage::AttemptState> parsed = storage::ParseAttemptState(attempt_state);
      if (!parsed) return jr.Error("attempt_log[].state");
      TG_READ(worker_id, jr.String(a, "worker_id"));
      TG_READ(worker_host, jr.String(a, "worker_host"));
      TG_READ(worker_build, jr.String(a, "worker_build"));
      TG_READ(started, jr.Integer(a, "started_unix_ms"));
      TG_READ(ended, jr.Integer(a, "ended_unix_ms"));
      TG_READ(error, jr.String(a, "error"));
      attempt.attempt = static_cast<int>(number);
      attempt.state = *parsed;
      attempt.worker_id = worker_id;
      attempt.worker_host = worker_host;
      attempt.worker_build = worker_build;
      attempt.started_ms = started;
      attempt.ended_ms = ended;
      attempt.error = error;
      if (!a.contains("episodes") || !a["episodes"].is_array()) return jr.Error("episodes");
      for (const nlohmann::json& e : a["episodes"]) {
        storage::Episode episode;
        TG_READ(episode_number, jr.Integer(e, "episode"));
        TG_READ(reported, jr.Integer(e, "reported_unix_ms"));
        if (version >= 2) {  // the episode's record
          if (!io::RecordFromJson<learner::EpisodeSummary>(learner::EpisodeFields(), e, "", &episode)
                   .ok()) {
            return jr.Error("episodes");
          }
        } else {  // version 1 named the optimisation time wall_seconds
          TG_READ(real_cost, jr.Real(e, "real_cost"));
          TG_READ(eval_mean, jr.Real(e, "eval_cost_mean"));
          TG_READ(eval_std, jr.Real(e, "eval_cost_std"));
          TG_READ(predicted, jr.Real(e, "predicted_cost"));
          TG_READ(wall, jr.Real(e, "wall_seconds"));
          TG_READ(cpu, jr.Real(e, "cpu_seconds"));
          episode.episode = static_cast<int>(episode_number);
          episode.real_cost = real_cost;
          episode.eval_cost_mean = eval_mean;
          episode.eval_cost_std = eval_std;
          episode.predicted_cost = predicted;
          episode.optimisation_seconds = wall;
          episode.cpu_seconds = cpu;
        }
        if (e.contains("details")) {
          episode.details_json = e["details"].is_string() ? e["details"].get<std::string>()
                                                          : e["details"].dump();
        }
        attempt.episodes.emplace_back(std::move(episode), reported);
      }
      for (const char* field : {"study_cells", "study_references"}) {
        if (!a.contains(field)) continue;
        if (!a[field].is_array()) return jr.Error(field);
        for (const nlohmann::json& row : a[field]) {
          if (version >= 2) {  // the records' JSON
            const bool ok = std::string(field) == "study_cells"
                                ? RowFromJson(study::CellFields(), row,
                                              &attempt.study.cells.emplace_back())
                                : RowFromJson(study::ReferenceFields(), row,
                                              &attempt.study.references.emplace_back());
            if (!ok) return jr.Error(field);
            continue;
          }
          // Version 1: protobuf's JSON mapping of the rows.
          google::protobuf::util::JsonParseOptions options;
          options.ignore_unknown_fields = false;
          if (std::string(field) == "study_cells") {
            v1::StudyCellRow proto;
            if (!google::protobuf::util::JsonStringToMessage(row.dump(), &proto, options).ok())
              return jr.Error(field);
            attempt.study.cells.push_back(FromProto(proto));
          } else {
            v1::StudyReferenceRow proto;
            if (!google::protobuf::util::JsonStringToMessage(row.dump(), &proto, options).ok())
              return jr.Error(field);
            attempt.study.references.push_back(FromProto(proto));
          }
        }
      }
      job.attempts.push_back(std::move(attempt));
    }
    archive.jobs.push_back(std::move(job));
  }
  return archive;
}

#undef TG_READ

}  // namespace totalgrad::service
