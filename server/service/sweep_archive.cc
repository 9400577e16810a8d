#include "server/service/sweep_archive.h"

#include <google/protobuf/util/json_util.h>

#include <functional>
#include <initializer_list>
#include <istream>
#include <sstream>
#include <limits>
#include <optional>

#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "core/study/study.h"
#include "io/record_format.h"
#include "runtime/record_proto.h"
#include "runtime/status_macros.h"
#include "server/service/convert.h"
#include "server/service/options_as_run.h"
#include "server/storage/job_kinds.h"
#include "server/storage/service_records.h"

namespace totalgrad::service {
namespace {

// A study row of an archive: {"index", ...the record's fields}.
template <typename Record, typename Row>
nlohmann::ordered_json RowJson(const record::FieldTable<Record>& table, const Row& row) {
  Record record;
  record_proto::RecordFromProto(table, row, &record);
  nlohmann::ordered_json object = {{"index", row.index()}};
  io::AppendRecordJson(table, record, &object);
  return object;
}

// An episode of an archive: its record (learner::EpisodeFields()), then when
// it was reported and its details.
nlohmann::ordered_json EpisodeJson(const v1::EpisodeRow& row) {
  const v1::EpisodeReport& e = row.report();
  learner::EpisodeSummary summary;
  record_proto::RecordFromProto(learner::EpisodeFields(), e, &summary);
  nlohmann::ordered_json episode = io::RecordToJson(learner::EpisodeFields(), summary);
  episode["reported_unix_ms"] = row.reported_unix_ms();
  const nlohmann::ordered_json details =
      nlohmann::ordered_json::parse(e.details_json(), nullptr, false);
  episode["details"] = details.is_discarded() ? nlohmann::ordered_json(e.details_json()) : details;
  return episode;
}

// ---- Reading version 3: every record through its table ----

// "archive: jobs[3].attempt_log[0]: not an object". `where` is the path of
// the value in the document ("" for the document itself).
absl::Status Malformed(const std::string& where, absl::string_view why) {
  return absl::InvalidArgumentError(absl::StrCat("archive: ", where, ": ", why));
}

std::string Member(const std::string& where, absl::string_view key) {
  return where.empty() ? std::string(key) : absl::StrCat(where, ".", key);
}

// Reads the record at `where` through its table (io/record_format.h):
// InvalidArgument "archive: <where>.<key>: <why>" for a mistyped value.
template <typename R>
absl::Status ReadRecord(const record::FieldTable<R>& table, const nlohmann::json& object,
                        const std::string& where, R* r) {
  if (!object.is_object()) return Malformed(where, "not an object");
  return io::RecordFromJson(table, object, absl::StrCat("archive: ", where, "."), r);
}

// A table's reader keeps the record's default for a missing key (a file
// written before the field existed). The keys the import takes must be
// there: a default would import another job, or another verdict, silently.
absl::Status Require(const nlohmann::json& object, const std::string& where,
                     std::initializer_list<const char*> keys) {
  for (const char* key : keys) {
    if (!object.contains(key)) return Malformed(Member(where, key), "missing");
  }
  return absl::OkStatus();
}

absl::StatusOr<int64_t> Integer(const nlohmann::json& object, const std::string& where,
                                const char* key) {
  const auto it = object.find(key);
  if (it == object.end()) return Malformed(Member(where, key), "missing");
  if (!it->is_number_integer()) return Malformed(Member(where, key), "not an integer");
  return it->get<int64_t>();
}

// The array at `key`; nullptr when it is absent and not `required`.
absl::StatusOr<const nlohmann::json*> Array(const nlohmann::json& object, const std::string& where,
                                            const char* key, bool required) {
  const auto it = object.find(key);
  if (it == object.end()) {
    if (required) return Malformed(Member(where, key), "missing");
    return nullptr;
  }
  if (!it->is_array()) return Malformed(Member(where, key), "not an array");
  return &*it;
}

// A study row: {"index", ...the record's fields} (RowJson).
template <typename Record, typename Stored>
absl::Status ReadRow(const record::FieldTable<Record>& table, const nlohmann::json& row,
                     const std::string& where, Stored* stored) {
  if (!row.is_object()) return Malformed(where, "not an object");
  ASSIGN_OR_RETURN(const int64_t index, Integer(row, where, "index"));
  stored->index = static_cast<int>(index);
  return ReadRecord<Record>(table, row, where, stored);
}

// One object of a job's attempt_log: the attempt's record
// (storage::ImportedAttemptFields(), every field of which the import takes,
// so every one must be there), its episodes and its study rows.
// The attempt's own fields, named alike in every version (versions before 4
// have no origin: read as "", it ran where it was stored).
absl::Status ReadAttemptRecord(const nlohmann::json& object, const std::string& where,
                               int64_t version, storage::ImportedAttempt* attempt) {
  RETURN_IF_ERROR(ReadRecord(storage::ImportedAttemptFields(), object, where, attempt));
  for (const auto& field : storage::ImportedAttemptFields()) {
    if (version < 4 && absl::string_view(field.name) == "origin") continue;
    RETURN_IF_ERROR(Require(object, where, {field.name}));
  }
  return absl::OkStatus();
}

absl::Status ReadAttempt(const nlohmann::json& object, const std::string& where, int version,
                         storage::ImportedAttempt* attempt) {
  RETURN_IF_ERROR(ReadAttemptRecord(object, where, version, attempt));
  // Version 4: the attempt's checkpoint, when the export kept it.
  if (const auto it = object.find("checkpoint"); it != object.end()) {
    const std::string at = Member(where, "checkpoint");
    if (!it->is_object()) return Malformed(at, "not an object");
    ASSIGN_OR_RETURN(const int64_t episode, Integer(*it, at, "episode"));
    ASSIGN_OR_RETURN(const int64_t format_version, Integer(*it, at, "format_version"));
    const auto data = it->find("data_base64");
    if (data == it->end() || !data->is_string())
      return Malformed(Member(at, "data_base64"), "missing or not a string");
    storage::Checkpoint checkpoint;
    checkpoint.episode = static_cast<int>(episode);
    checkpoint.format_version = static_cast<int>(format_version);
    if (!absl::Base64Unescape(data->get<std::string>(), &checkpoint.data) ||
        checkpoint.data.empty()) {
      return Malformed(Member(at, "data_base64"), "not base64 of a checkpoint");
    }
    attempt->checkpoint = std::move(checkpoint);
  }
  ASSIGN_OR_RETURN(const nlohmann::json* episodes, Array(object, where, "episodes", true));
  for (size_t k = 0; k < episodes->size(); ++k) {
    const nlohmann::json& e = (*episodes)[k];
    const std::string at = absl::StrCat(where, ".episodes[", k, "]");
    storage::Episode episode;
    RETURN_IF_ERROR(ReadRecord<learner::EpisodeSummary>(learner::EpisodeFields(), e, at, &episode));
    RETURN_IF_ERROR(Require(e, at, {"episode"}));
    ASSIGN_OR_RETURN(const int64_t reported, Integer(e, at, "reported_unix_ms"));
    if (e.contains("details")) {
      episode.details_json =
          e["details"].is_string() ? e["details"].get<std::string>() : e["details"].dump();
    }
    attempt->episodes.emplace_back(std::move(episode), reported);
  }
  ASSIGN_OR_RETURN(const nlohmann::json* cells, Array(object, where, "study_cells", false));
  for (size_t k = 0; cells != nullptr && k < cells->size(); ++k) {
    RETURN_IF_ERROR(ReadRow(study::CellFields(), (*cells)[k],
                            absl::StrCat(where, ".study_cells[", k, "]"),
                            &attempt->study.cells.emplace_back()));
  }
  ASSIGN_OR_RETURN(const nlohmann::json* references,
                   Array(object, where, "study_references", false));
  for (size_t k = 0; references != nullptr && k < references->size(); ++k) {
    RETURN_IF_ERROR(ReadRow(study::ReferenceFields(), (*references)[k],
                            absl::StrCat(where, ".study_references[", k, "]"),
                            &attempt->study.references.emplace_back()));
  }
  return absl::OkStatus();
}

// Version 3. Of the sweep's record the import takes its name, spec, hash
// and state (the coordinator recreates the rest from the spec, and counts
// its own jobs); of a job's record its identity (kind, method, seed,
// variant) and verdict; the other fields (job_id, ordinal, the counts,
// worker_id, ...) are informative: checked for their type, then ignored.
absl::Status ReadVersion3Opening(const nlohmann::json& doc, int version,
                                 SweepArchiveOpening* opening) {
  if (!doc.contains("sweep")) return Malformed("sweep", "missing");
  const nlohmann::json& sweep_object = doc["sweep"];
  storage::SweepRecord sweep;
  RETURN_IF_ERROR(ReadRecord(storage::SweepFields(), sweep_object, "sweep", &sweep));
  RETURN_IF_ERROR(Require(sweep_object, "sweep", {"name", "canonical_spec", "spec_hash", "state"}));
  opening->name = sweep.name;
  opening->canonical_spec = sweep.canonical_spec;
  opening->spec_hash = sweep.spec_hash;
  opening->state = sweep.state;
  // The sweep keeps its first submission's time (version 4 must say it;
  // version 3 wrote it too, but its imports took their own time).
  if (version >= 4) RETURN_IF_ERROR(Require(sweep_object, "sweep", {"created_unix_ms"}));
  if (sweep_object.contains("created_unix_ms")) opening->created_ms = sweep.created_ms;
  return Array(doc, "", "jobs", true).status();
}

absl::StatusOr<storage::ImportedJob> ParseVersion3Job(const nlohmann::json& j, size_t index,
                                                      int version) {
  const std::string where = absl::StrCat("jobs[", index, "]");
  storage::JobRecord record;
  RETURN_IF_ERROR(ReadRecord(storage::JobFields(), j, where, &record));
  RETURN_IF_ERROR(Require(j, where,
                          {"kind", "method", "seed", "variant", "state", "failures",
                           "lost_leases", "last_error", "success", "final_eval_cost"}));
  storage::ImportedJob job;
  job.record = std::move(record);
  // (The variant identifies the job; its options, read with its table, say
  // what its trial ran: ImportedJob::options_as_run.) The archive's own
  // keys: the completed attempt and the attempt log.
  ASSIGN_OR_RETURN(const int64_t completed, Integer(j, where, "completed_attempt"));
  job.completed_attempt = static_cast<int>(completed);
  ASSIGN_OR_RETURN(const nlohmann::json* log, Array(j, where, "attempt_log", true));
  for (size_t k = 0; k < log->size(); ++k) {
    RETURN_IF_ERROR(ReadAttempt((*log)[k], absl::StrCat(where, ".attempt_log[", k, "]"),
                                version, &job.attempts.emplace_back()));
  }
  return job;
}

// ---- Reading versions 1 and 2: a frozen exchange format, read as it was ----

// A study row that RowJson wrote into *stored (a storage row: the record
// and its index). False when it is not one.
template <typename Record, typename Stored>
bool RowFromJson(const record::FieldTable<Record>& table, const nlohmann::json& row,
                 Stored* stored) {
  if (!row.is_object() || !row.contains("index") || !row["index"].is_number_integer()) return false;
  stored->index = row["index"].get<int>();
  return io::RecordFromJson<Record>(table, row, "", stored).ok();
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

// One attempt of a version 1 or 2 archive's job, with its episodes and
// study rows; errors name the job (`jr`).
// `where` names the attempt ("jobs[3].attempt_log[0]").
absl::StatusOr<storage::ImportedAttempt> ParseVersion1Or2Attempt(const nlohmann::json& a,
                                                                const std::string& where,
                                                                const Reader& jr,
                                                                int64_t version) {
  storage::ImportedAttempt attempt;
  RETURN_IF_ERROR(ReadAttemptRecord(a, where, version, &attempt));
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
      episode.episode = static_cast<int>(episode_number);
      ASSIGN_OR_RETURN(episode.real_cost, jr.Real(e, "real_cost"));
      ASSIGN_OR_RETURN(episode.eval_cost_mean, jr.Real(e, "eval_cost_mean"));
      ASSIGN_OR_RETURN(episode.eval_cost_std, jr.Real(e, "eval_cost_std"));
      ASSIGN_OR_RETURN(episode.predicted_cost, jr.Real(e, "predicted_cost"));
      ASSIGN_OR_RETURN(episode.optimisation_seconds, jr.Real(e, "wall_seconds"));
      ASSIGN_OR_RETURN(episode.cpu_seconds, jr.Real(e, "cpu_seconds"));
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
  return attempt;
}

absl::Status ReadVersion1Or2Opening(const nlohmann::json& doc, SweepArchiveOpening* opening) {
  const Reader top("");
  if (!doc.contains("sweep") || !doc["sweep"].is_object()) return top.Error("sweep");
  const nlohmann::json& sweep = doc["sweep"];
  const Reader sr("sweep: ");
  TG_READ(name, sr.String(sweep, "name"));
  TG_READ(spec, sr.String(sweep, "canonical_spec"));
  TG_READ(hash, sr.String(sweep, "spec_hash"));
  TG_READ(state, sr.String(sweep, "state"));
  opening->name = name;
  opening->canonical_spec = spec;
  opening->spec_hash = hash;
  const std::optional<storage::SweepState> sweep_state = storage::ParseSweepState(state);
  if (!sweep_state) return sr.Error("state");
  opening->state = *sweep_state;
  if (sweep.contains("created_unix_ms")) {  // the first submission's time
    ASSIGN_OR_RETURN(opening->created_ms, sr.Integer(sweep, "created_unix_ms"));
  }
  if (!doc.contains("jobs") || !doc["jobs"].is_array()) return top.Error("jobs");
  return absl::OkStatus();
}

absl::StatusOr<storage::ImportedJob> ParseVersion1Or2Job(const nlohmann::json& j, size_t index,
                                                         int64_t version) {
  const Reader jr(absl::StrCat("jobs[", index, "]: "));
  if (!j.is_object()) return jr.Error("{}");
  storage::ImportedJob job;
  TG_READ(kind, jr.String(j, "kind"));
  // The kinds' names are the job-kind table's (server/storage/job_kinds.h).
  const std::optional<storage::JobKind> parsed_kind = storage::ParseJobKind(kind);
  if (!parsed_kind) return jr.Error("kind");
  job.record.kind = *parsed_kind;
  TG_READ(method, jr.String(j, "method"));
  job.record.method = method;
  if (!j.contains("seed")) return jr.Error("seed");
  if (j["seed"].is_number_integer()) job.record.seed = std::to_string(j["seed"].get<int64_t>());
  else if (j["seed"].is_string()) job.record.seed = j["seed"].get<std::string>();
  else return jr.Error("seed");
  TG_READ(variant, jr.String(j, "variant"));
  job.record.variant = variant;
  TG_READ(job_state, jr.String(j, "state"));
  const std::optional<storage::JobState> parsed_state = storage::ParseJobState(job_state);
  if (!parsed_state) return jr.Error("state");
  job.record.state = *parsed_state;
  TG_READ(failures, jr.Integer(j, "failures"));
  TG_READ(lost, jr.Integer(j, "lost_leases"));
  TG_READ(last_error, jr.String(j, "last_error"));
  TG_READ(final_cost, jr.Real(j, "final_eval_cost"));
  TG_READ(completed, jr.Integer(j, "completed_attempt"));
  if (!j.contains("success") || !j["success"].is_boolean()) return jr.Error("success");
  job.record.failures = static_cast<int>(failures);
  job.record.lost_leases = static_cast<int>(lost);
  job.record.last_error = last_error;
  job.record.final_eval_cost = final_cost;
  job.completed_attempt = static_cast<int>(completed);
  job.record.success = j["success"].get<bool>();
  // The job's options: an object of texts, or [key, text] pairs.
  if (const auto options = j.find("options"); options != j.end()) {
    if (options->is_object()) {
      for (const auto& [key, value] : options->items()) {
        if (!value.is_string()) return jr.Error("options");
        job.record.options.emplace_back(key, value.get<std::string>());
      }
    } else if (options->is_array()) {
      for (const nlohmann::json& pair : *options) {
        if (!pair.is_array() || pair.size() != 2 || !pair[0].is_string() || !pair[1].is_string())
          return jr.Error("options");
        job.record.options.emplace_back(pair[0].get<std::string>(), pair[1].get<std::string>());
      }
    } else {
      return jr.Error("options");
    }
  }
  if (!j.contains("attempt_log") || !j["attempt_log"].is_array()) return jr.Error("attempt_log");
  for (size_t k = 0; k < j["attempt_log"].size(); ++k) {
    absl::StatusOr<storage::ImportedAttempt> attempt = ParseVersion1Or2Attempt(
        j["attempt_log"][k], absl::StrCat("jobs[", index, "].attempt_log[", k, "]"), jr, version);
    if (!attempt.ok()) return attempt.status();
    job.attempts.push_back(*std::move(attempt));
  }
  return job;
}

// ---- Reading an archive as a stream: one job in memory at a time ----

// Parses `in` with nlohmann's callback parser, handing each element of the
// top-level "jobs" array to `job` as it ends and then dropping it from the
// document (the callback returns false), so the document holds everything
// but the jobs. `job` returns false to stop: the rest of the input is then
// skipped (the stream is moved to its end, so the parse ends there) and the
// parse's own verdict is ignored. Returns the document (jobs: an empty array)
// or nullopt when the text is not JSON.
std::optional<nlohmann::json> ParseDroppingJobs(
    std::istream& in, const std::function<bool(nlohmann::json&)>& job) {
  std::string key_at_top;
  bool in_jobs = false, stopped = false;
  const nlohmann::json::parser_callback_t callback =
      [&](int depth, nlohmann::json::parse_event_t event, nlohmann::json& parsed) -> bool {
    using Event = nlohmann::json::parse_event_t;
    if (stopped) return false;
    if (depth == 1) {
      if (event == Event::key) key_at_top = parsed.get<std::string>();
      if (event == Event::array_start) in_jobs = key_at_top == "jobs";
      if (event == Event::array_end) in_jobs = false;
      return true;
    }
    // An element of "jobs" ends: an object or array closing at depth 2, or
    // a scalar (a value event at depth 2).
    const bool element_ends =
        depth == 2 && in_jobs &&
        (event == Event::object_end || event == Event::array_end || event == Event::value);
    if (!element_ends) return true;
    if (!job(parsed)) {
      stopped = true;
      in.rdbuf()->pubseekoff(0, std::ios::end, std::ios::in);
    }
    return false;
  };
  nlohmann::json doc = nlohmann::json::parse(in, callback, /*allow_exceptions=*/false);
  if (stopped) return nlohmann::json::object();
  if (doc.is_discarded()) return std::nullopt;
  return doc;
}

}  // namespace

nlohmann::ordered_json SweepArchiveOpeningJson(const v1::SweepInfo& sweep,
                                               const std::string& exported_by,
                                               int64_t exported_ms) {
  nlohmann::ordered_json doc;
  doc["format"] = kSweepArchiveFormat;
  doc["version"] = kSweepArchiveVersion;
  doc["exported_by"] = exported_by;
  doc["exported_unix_ms"] = exported_ms;
  // The sweep's, the jobs' and the attempts' records, read from their protos
  // by name (convert.cc) and written through their tables
  // (server/storage/service_records.h): no field is named here.
  doc["sweep"] = io::RecordToJson(storage::SweepFields(), FromProto(sweep));
  return doc;
}

nlohmann::ordered_json ArchiveJobJson(const ArchiveJobInput& input) {
  const storage::JobRecord record = FromProto(input.job);
  nlohmann::ordered_json job = io::RecordToJson(storage::JobFields(), record);
  int completed_attempt = 0;
  nlohmann::ordered_json attempts = nlohmann::ordered_json::array();
  for (const v1::AttemptInfo& attempt : input.attempts) {
    if (attempt.state() == v1::ATTEMPT_STATE_COMPLETED) completed_attempt = attempt.attempt();
    nlohmann::ordered_json entry =
        io::RecordToJson(storage::ImportedAttemptFields(), FromProto(attempt));
    nlohmann::ordered_json episodes = nlohmann::ordered_json::array();
    for (const v1::EpisodeRow& row : input.episodes) {
      if (row.attempt() == attempt.attempt()) episodes.push_back(EpisodeJson(row));
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
    entry["episodes"] = std::move(episodes);
    entry["study_cells"] = std::move(cells);
    entry["study_references"] = std::move(references);
    if (const auto checkpoint = input.checkpoints.find(attempt.attempt());
        checkpoint != input.checkpoints.end()) {
      entry["checkpoint"] = {{"episode", checkpoint->second.episode()},
                             {"format_version", checkpoint->second.format_version()},
                             {"data_base64", absl::Base64Escape(checkpoint->second.data())}};
    }
    attempts.push_back(std::move(entry));
  }
  // What the job's table leaves out (service_records.h) and the archive needs.
  job["completed_attempt"] = input.job.state() == v1::JOB_STATE_COMPLETED ? completed_attempt : 0;
  job["attempt_log"] = std::move(attempts);
  return job;
}

nlohmann::ordered_json SweepArchiveToJson(const v1::SweepInfo& sweep,
                                          const std::vector<ArchiveJobInput>& jobs,
                                          const std::string& exported_by, int64_t exported_ms) {
  nlohmann::ordered_json doc = SweepArchiveOpeningJson(sweep, exported_by, exported_ms);
  nlohmann::ordered_json job_array = nlohmann::ordered_json::array();
  for (const ArchiveJobInput& input : jobs) job_array.push_back(ArchiveJobJson(input));
  doc["jobs"] = std::move(job_array);
  return doc;
}

absl::StatusOr<SweepArchiveOpening> ReadSweepArchiveOpening(std::istream& in) {
  const std::optional<nlohmann::json> doc =
      ParseDroppingJobs(in, [](nlohmann::json&) { return true; });
  if (!doc.has_value() || !doc->is_object())
    return absl::InvalidArgumentError("archive: not a JSON document");
  const Reader top("");
  TG_READ(format, top.String(*doc, "format"));
  if (format != kSweepArchiveFormat)
    return absl::InvalidArgumentError(absl::StrCat("archive: format '", format, "' is not '",
                                                   kSweepArchiveFormat, "'"));
  TG_READ(version, top.Integer(*doc, "version"));
  if (version < 1 || version > kSweepArchiveVersion)
    return absl::InvalidArgumentError(absl::StrCat("archive: version ", version,
                                                   "; this build reads versions 1 to ",
                                                   kSweepArchiveVersion));
  SweepArchiveOpening opening;
  opening.version = static_cast<int>(version);
  if (version >= 3) {
    RETURN_IF_ERROR(ReadVersion3Opening(*doc, opening.version, &opening));
  } else {
    RETURN_IF_ERROR(ReadVersion1Or2Opening(*doc, &opening));
  }
  return opening;
}

absl::Status ForEachArchivedJob(std::istream& in, int version,
                                const std::function<absl::Status(storage::ImportedJob&)>& visit) {
  absl::Status status;
  size_t index = 0;
  const std::optional<nlohmann::json> doc = ParseDroppingJobs(in, [&](nlohmann::json& j) {
    absl::StatusOr<storage::ImportedJob> job =
        version >= 3 ? ParseVersion3Job(j, index, version) : ParseVersion1Or2Job(j, index, version);
    ++index;
    status = job.ok() ? SetOptionsAsRun(&*job) : job.status();
    if (status.ok()) status = visit(*job);
    return status.ok();
  });
  RETURN_IF_ERROR(status);
  if (!doc.has_value()) return absl::InvalidArgumentError("archive: not a JSON document");
  return absl::OkStatus();
}

absl::StatusOr<ParsedSweepArchive> ParseSweepArchive(const std::string& text) {
  std::istringstream in(text);
  ASSIGN_OR_RETURN(SweepArchiveOpening opening, ReadSweepArchiveOpening(in));
  ParsedSweepArchive archive;
  static_cast<SweepArchiveOpening&>(archive) = std::move(opening);
  in.clear();
  in.seekg(0);
  RETURN_IF_ERROR(ForEachArchivedJob(in, archive.version, [&](storage::ImportedJob& job) {
    archive.jobs.push_back(std::move(job));
    return absl::OkStatus();
  }));
  return archive;
}

#undef TG_READ

}  // namespace totalgrad::service
