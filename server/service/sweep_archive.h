// Sweep archives: one sweep with its jobs, every attempt (worker, build,
// times, outcome) and every stored episode and study row, as one JSON
// document. `totalgrad results export SWEEP -f json` writes one (client side,
// from the ControlService's read calls); `totalgrad results import FILE` sends
// it to another coordinator, which takes over the jobs it has not completed
// (ControlService.ImportSweep, storage::Store::ImportJobs). So a sweep can move
// between machines and sessions: import it into a fresh coordinator, resubmit
// the sweep file, and only the jobs still missing run.
//
// Format (version 4; docs/results_schema.md, "Sweep archives"). Each
// record is its field table's JSON (io/record_format.h): every field of the
// table, in its order, named as the proto field (job_id, sweep_name,
// created_unix_ms); NaN is null, enumerators are their names ("completed",
// "lease_lost", "study"), a seed is its text ("7").
//   {"format": "totalgrad-sweep-archive", "version": 4,
//    "exported_by": BUILD, "exported_unix_ms": MS,
//    "sweep": {...storage::SweepFields(): "name", "description", "state",
//              "finished", "jobs_total", ..., "canonical_spec" (text)},
//    "jobs": [{...storage::JobFields(): "job_id", "sweep_name", "kind",
//              "ordinal", "method", "seed", "variant",
//              "options" ([[KEY, TEXT], ...]), "state", ...,
//              "final_eval_cost", "last_error",
//              then what that table leaves out: "completed_attempt" (0: none),
//              "attempt_log": [{...storage::ImportedAttemptFields():
//                  "attempt", "state", "worker_id", "worker_host",
//                  "worker_build", "started_unix_ms", "ended_unix_ms", "error",
//                  "origin", then optionally "checkpoint": {"episode",
//                  "format_version", "data_base64"},
//                  "episodes": [{...learner::EpisodeFields(),
//                      "reported_unix_ms", "details": {...}}],
//                  "study_cells": [{"index", ...study::CellFields()}],
//                  "study_references": [{"index", ...study::ReferenceFields()}]}]}]}
// A field added to one of these tables is written and read with no change
// here (the study rows are the objects of a study's results.json). Reading
// takes from the sweep its name, canonical_spec, spec_hash and state; from a
// job its kind, method, seed, variant, state, failures, lost_leases,
// last_error, success, final_eval_cost (these must be present),
// completed_attempt and attempt_log; every field of an attempt; a completed
// trial's options, as what it ran (storage::ImportedJob::options_as_run,
// options_as_run.h; in every version, an object of texts in 1 and 2); the
// rest (counts, finished, ids, ordinal, episodes_stored/expected,
// worker_id) is informative: type-checked, then ignored, as the importing
// coordinator has its own. Unknown keys are ignored.
// Versions 2 (the same objects with their own hand-named keys: the sweep's
// limits, build and source but no counts; a job without job_id, sweep_name,
// ordinal, episodes_* and worker_id, its seed an integer when it is one) and
// 1 (as 2, with episodes naming optimisation_seconds "wall_seconds" and
// study rows in protobuf's JSON mapping of StudyCellRow /
// StudyReferenceRow) are read as before.
#ifndef TOTALGRAD_SERVER_SERVICE_SWEEP_ARCHIVE_H_
#define TOTALGRAD_SERVER_SERVICE_SWEEP_ARCHIVE_H_

#include <cstdint>
#include <functional>
#include <istream>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/status/statusor.h"
#include "server/storage/store.h"
#include "totalgrad/v1/control_service.pb.h"
#include "totalgrad/v1/types.pb.h"

namespace totalgrad::service {

inline constexpr char kSweepArchiveFormat[] = "totalgrad-sweep-archive";
// 3: the sweep, jobs and attempts as their records' JSON (their field
// tables); 2: episodes and study rows as their records' JSON (issue 13); 1:
// the layout before.
// 4 (issue 25): an attempt's origin, optionally its checkpoint, and the
// sweep's submission time kept on import (3 is read as before: no origin,
// no checkpoints, the import's own time).
inline constexpr int kSweepArchiveVersion = 4;

// What the archive says of one job, as the read calls return it.
struct ArchiveJobInput {
  v1::JobInfo job;
  std::vector<v1::AttemptInfo> attempts;
  std::vector<v1::EpisodeRow> episodes;  // every attempt's
  std::vector<v1::StudyCellRow> cells;
  std::vector<v1::StudyReferenceRow> references;
  // Checkpoints to keep, by attempt number (results export --checkpoints:
  // each completed trial's final state).
  std::map<int, v1::TrialCheckpoint> checkpoints;
};

// The archive's members before "jobs": format, version, exported_by,
// exported_unix_ms and the sweep's record.
nlohmann::ordered_json SweepArchiveOpeningJson(const v1::SweepInfo& sweep,
                                               const std::string& exported_by,
                                               int64_t exported_ms);

// One element of the archive's "jobs": the job's record, its completed
// attempt and its attempt log with each attempt's episodes, study rows and
// kept checkpoint. Rows of an attempt not in job.attempts are left out.
nlohmann::ordered_json ArchiveJobJson(const ArchiveJobInput& job);

// The whole document in memory (tests; the CLI writes an archive job by job
// with SweepArchiveWriter, sweep_archive_writer.h).
nlohmann::ordered_json SweepArchiveToJson(const v1::SweepInfo& sweep,
                                          const std::vector<ArchiveJobInput>& jobs,
                                          const std::string& exported_by, int64_t exported_ms);

// What an archive says before its jobs: its version and the sweep.
struct SweepArchiveOpening {
  int version = kSweepArchiveVersion;
  std::string name;
  std::string canonical_spec;
  std::string spec_hash;
  storage::SweepState state = storage::SweepState::kRunning;
  int64_t created_ms = 0;  // the sweep's first submission time when the archive says it; 0: unknown
};

// Reading an archive as a stream, so that its size does not bound what can
// be imported (issue 28: a 100,000-job archive is ~250 MB of JSON, several
// GB as one parsed document). JSON does not order an object's members, so
// the opening is read in a pass of its own (the jobs parsed and dropped one
// by one), and the jobs in a second pass over the same bytes.
//
// Reads `in` to its end: InvalidArgument for text that is not one JSON
// document, another format or version, or naming the value of the opening
// (sweep) that is missing or mistyped. Needs nothing of the jobs but that
// "jobs" is an array.
absl::StatusOr<SweepArchiveOpening> ReadSweepArchiveOpening(std::istream& in);

// Calls `visit` with each job of the archive in `in` (of `version`, as
// ReadSweepArchiveOpening read it), in order, holding one job in memory at a
// time. Stops at the first job that does not read (InvalidArgument naming
// where, as ParseSweepArchive) or that `visit` refuses, and returns that
// error; the rest of `in` is then skipped.
absl::Status ForEachArchivedJob(std::istream& in, int version,
                                const std::function<absl::Status(storage::ImportedJob&)>& visit);

// The whole archive in memory (tests and small archives).
struct ParsedSweepArchive : SweepArchiveOpening {
  std::vector<storage::ImportedJob> jobs;
};

// Reads an archive of version 1 to 4 (ReadSweepArchiveOpening, then
// ForEachArchivedJob). InvalidArgument for another format or version, or
// naming the value that is missing or mistyped: in versions 3 and 4 by its
// path and why ("archive: jobs[3].state: 'x' is not one of its names",
// "archive: jobs[0].attempt_log[1].episodes[2].real_cost: not a number or
// null", "archive: sweep.spec_hash: missing"); in versions 1 and 2 as before
// ("archive: jobs[3]: 'state' is missing or mistyped").
absl::StatusOr<ParsedSweepArchive> ParseSweepArchive(const std::string& text);

}  // namespace totalgrad::service

#endif  // TOTALGRAD_SERVER_SERVICE_SWEEP_ARCHIVE_H_
