// Sweep archives: one sweep with its jobs, every attempt (worker, build,
// times, outcome) and every stored episode and study row, as one JSON
// document. `totalgrad results export SWEEP -f json` writes one (client side,
// from the ControlService's read calls); `totalgrad results import FILE` sends
// it to another coordinator, which takes over the jobs it has not completed
// (ControlService.ImportSweep, storage::Store::ImportJobs). So a sweep can move
// between machines and sessions: import it into a fresh coordinator, resubmit
// the sweep file, and only the jobs still missing run.
//
// Format (version 2; docs/results_schema.md, "Sweep archives"):
//   {"format": "totalgrad-sweep-archive", "version": 2,
//    "exported_by": BUILD, "exported_unix_ms": MS,
//    "sweep": {"name", "description", "state", "spec_hash", "canonical_spec" (text),
//              "coordinator_build", "created_unix_ms", "source_name",
//              "max_attempts", "max_lost_leases", "max_concurrent"},
//    "jobs": [{"kind": "trial"|"study", "method", "seed" (integer), "variant",
//              "options": {KEY: TEXT}, "state", "attempts", "failures",
//              "lost_leases", "last_error", "success", "final_eval_cost",
//              "completed_attempt" (0: none),
//              "attempt_log": [{"attempt", "state", "worker_id", "worker_host",
//                  "worker_build", "started_unix_ms", "ended_unix_ms", "error",
//                  "episodes": [{"episode", "real_cost", "eval_cost_mean",
//                      "eval_cost_std", "predicted_cost", "optimisation_seconds",
//                      "cpu_seconds" (the episode's record, learner::EpisodeFields()),
//                      "reported_unix_ms", "details": {...}}],
//                  "study_cells": [...], "study_references": [...]}]}]}
// Numbers that are NaN are null. A study row is {"index", ...} with its
// record's JSON (io/record_format.h over study::CellFields() /
// ReferenceFields(): the objects of a study's results.json). Version 1
// archives (episodes with "wall_seconds" for optimisation_seconds, study rows
// in protobuf's JSON mapping of StudyCellRow / StudyReferenceRow) are read
// as well.
#ifndef TOTALGRAD_SERVER_SERVICE_SWEEP_ARCHIVE_H_
#define TOTALGRAD_SERVER_SERVICE_SWEEP_ARCHIVE_H_

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/status/statusor.h"
#include "server/storage/store.h"
#include "totalgrad/v1/control_service.pb.h"
#include "totalgrad/v1/types.pb.h"

namespace totalgrad::service {

inline constexpr char kSweepArchiveFormat[] = "totalgrad-sweep-archive";
// 2: episodes and study rows as their records' JSON (issue 13); 1: the
// layout before.
inline constexpr int kSweepArchiveVersion = 2;

// What the archive says of one job, as the read calls return it.
struct ArchiveJobInput {
  v1::JobInfo job;
  std::vector<v1::AttemptInfo> attempts;
  std::vector<v1::EpisodeRow> episodes;  // every attempt's
  std::vector<v1::StudyCellRow> cells;
  std::vector<v1::StudyReferenceRow> references;
};

nlohmann::ordered_json SweepArchiveToJson(const v1::SweepInfo& sweep,
                                          const std::vector<ArchiveJobInput>& jobs,
                                          const std::string& exported_by, int64_t exported_ms);

struct ParsedSweepArchive {
  std::string name;
  std::string canonical_spec;
  std::string spec_hash;
  storage::SweepState state = storage::SweepState::kRunning;
  std::vector<storage::ImportedJob> jobs;
};

// InvalidArgument naming the field (and job) that is missing or mistyped, or
// another format or version.
absl::StatusOr<ParsedSweepArchive> ParseSweepArchive(const std::string& text);

}  // namespace totalgrad::service

#endif  // TOTALGRAD_SERVER_SERVICE_SWEEP_ARCHIVE_H_
