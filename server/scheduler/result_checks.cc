// What a worker's results must satisfy before anything is stored, and the
// same checks on a sweep archive's completed jobs (result_checks.h).
#include "server/scheduler/result_checks.h"

#include <cmath>
#include <string>
#include <utility>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "runtime/status_macros.h"
#include "server/storage/job_kinds.h"

namespace totalgrad::scheduler {

using storage::Episode;
using storage::WorkerIdentity;

namespace {

// The start of every message about `job`.
std::string ArchivedJobName(const storage::ImportedJob& job) {
  return absl::StrCat("archive: job ", job.record.method, " seed ", job.record.seed, " ",
                      job.record.variant);
}

}  // namespace

absl::Status ValidateWorkerIdentity(const WorkerIdentity& worker) {
  if (worker.worker_id.empty()) return absl::InvalidArgumentError("worker_id is empty");
  if (worker.worker_id.size() > kMaxWorkerIdBytes) {
    return absl::InvalidArgumentError(
        absl::StrCat("worker_id is ", worker.worker_id.size(), " bytes; at most ",
                     kMaxWorkerIdBytes));
  }
  for (unsigned char c : worker.worker_id) {
    if (c < 0x20 || c == 0x7f) {
      return absl::InvalidArgumentError("worker_id contains a control character");
    }
  }
  if (worker.slots < 1 || worker.slots > 4096) {
    return absl::InvalidArgumentError(
        absl::StrCat("worker slots must be in 1..4096, got ", worker.slots));
  }
  if (worker.host.size() > 255 || worker.build.size() > 1024) {
    return absl::InvalidArgumentError("worker host (<= 255 bytes) or build (<= 1024) too long");
  }
  return absl::OkStatus();
}

absl::Status ValidateEpisode(const Episode& e) {
  // Every number of the record (learner::EpisodeFields()), as the worker
  // checks them before sending (worker.cc, NonFiniteReason).
  for (const auto& field : learner::EpisodeFields()) {
    if (field.type() != record::FieldType::kDouble) continue;
    if (std::isinf(field.Get<double>(e))) {
      return absl::InvalidArgumentError(absl::StrCat(
          "episode ", e.episode, ": ", field.name, " is infinite; a trial with a non-finite "
          "cost must be reported with Fail"));
    }
  }
  if (std::isnan(e.real_cost)) {
    return absl::InvalidArgumentError(
        absl::StrCat("episode ", e.episode, ": real_cost is missing (NaN)"));
  }
  if (e.details_json.size() > kMaxDetailsBytes) {
    return absl::InvalidArgumentError(absl::StrCat(
        "episode ", e.episode, ": details_json is ", e.details_json.size(), " bytes; at most ",
        kMaxDetailsBytes));
  }
  // Readers parse it (records' JSON, the dashboard): empty or one JSON value.
  if (!e.details_json.empty() && !nlohmann::json::accept(e.details_json)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "episode ", e.episode, ": details_json is not valid JSON (", e.details_json.size(),
        " bytes, starting '", e.details_json.substr(0, 40), "')"));
  }
  return absl::OkStatus();
}

absl::Status ValidateEpisodes(const std::vector<Episode>& episodes) {
  if (static_cast<int>(episodes.size()) > kMaxEpisodesPerCall) {
    return absl::InvalidArgumentError(absl::StrCat(
        episodes.size(), " episodes in one call; at most ", kMaxEpisodesPerCall));
  }
  for (const Episode& e : episodes) RETURN_IF_ERROR(ValidateEpisode(e));
  return absl::OkStatus();
}

absl::Status ValidateCheckpoint(const std::optional<storage::Checkpoint>& checkpoint) {
  if (!checkpoint) return absl::OkStatus();
  if (checkpoint->data.size() > kMaxCheckpointBytes) {
    return absl::InvalidArgumentError(absl::StrCat("checkpoint after episode ", checkpoint->episode,
                                                   " is ", checkpoint->data.size(),
                                                   " bytes; at most ", kMaxCheckpointBytes));
  }
  if (checkpoint->data.empty() || checkpoint->format_version < 1) {
    return absl::InvalidArgumentError("checkpoint without data or format version");
  }
  return absl::OkStatus();
}

absl::Status ValidateStudyRows(const storage::StudyRows& rows) {
  if (static_cast<int>(rows.size()) > kMaxStudyRowsPerCall) {
    return absl::InvalidArgumentError(absl::StrCat(rows.size(), " study rows in one call; at most ",
                                                   kMaxStudyRowsPerCall));
  }
  return ValidateStudyRowValues(rows);
}

absl::Status ValidateStudyRowValues(const storage::StudyRows& rows) {
  for (const storage::StudyCell& c : rows.cells) {
    const std::string where = absl::StrCat("study cell ", c.index);
    if (c.index < 0 || c.particles < 0 || c.horizon < 0 || c.replicates < 0 || c.nonfinite < 0 ||
        c.errors < 0) {
      return absl::InvalidArgumentError(absl::StrCat(where, ": a negative index or count"));
    }
    // Every text field of the record (study::CellFields()); the note is
    // derived from them.
    for (const auto& field : study::CellFields()) {
      if (field.type() == record::FieldType::kText &&
          field.Get<std::string>(c).size() > kMaxStudyTextBytes) {
        return absl::InvalidArgumentError(absl::StrCat(where, ": a text field over ",
                                                       kMaxStudyTextBytes, " bytes (", field.name,
                                                       ")"));
      }
    }
    if (c.k_lr_per_step.size() > kMaxStudyVectorSize) {
      return absl::InvalidArgumentError(absl::StrCat(where, ": k_lr_per_step too long"));
    }
  }
  for (const storage::StudyReference& r : rows.references) {
    const std::string where = absl::StrCat("study reference ", r.index);
    if (r.index < 0 || r.horizon < 0) {
      return absl::InvalidArgumentError(absl::StrCat(where, ": a negative index or horizon"));
    }
    if (r.note.size() > kMaxStudyTextBytes || r.used.size() > 1000 ||
        r.replicates.size() > 1000) {
      return absl::InvalidArgumentError(absl::StrCat(where, ": note or estimator list too long"));
    }
    if (static_cast<size_t>(r.gradient.size()) > kMaxStudyVectorSize ||
        static_cast<size_t>(r.standard_error.size()) > kMaxStudyVectorSize) {
      return absl::InvalidArgumentError(absl::StrCat(where, ": gradient too long"));
    }
  }
  return absl::OkStatus();
}

absl::Status ValidateResults(const storage::JobResults& results) {
  RETURN_IF_ERROR(ValidateEpisodes(results.episodes));
  return ValidateStudyRows(results.study);
}

absl::Status CheckImportedJob(const storage::ImportedJob& job) {
  // Only a completed job is taken over; the others bring nothing.
  if (job.record.state != storage::JobState::kCompleted || job.completed_attempt <= 0) {
    return absl::OkStatus();
  }
  const std::string name = ArchivedJobName(job);
  if (storage::KindInfo(job.record.kind).reports_verdict &&
      !std::isfinite(job.record.final_eval_cost)) {
    return absl::InvalidArgumentError(absl::StrCat(
        name, " is completed with a final_eval_cost that is not finite (",
        job.record.final_eval_cost, "); Complete refuses that"));
  }
  for (const storage::ImportedAttempt& attempt : job.attempts) {
    const std::string where = absl::StrCat(name, " attempt ", attempt.attempt, ": ");
    for (const auto& [episode, reported_ms] : attempt.episodes) {
      if (absl::Status bad = ValidateEpisode(episode); !bad.ok()) {
        return absl::InvalidArgumentError(absl::StrCat(where, bad.message()));
      }
    }
    if (absl::Status bad = ValidateStudyRowValues(attempt.study); !bad.ok()) {
      return absl::InvalidArgumentError(absl::StrCat(where, bad.message()));
    }
    if (absl::Status bad = ValidateCheckpoint(attempt.checkpoint); !bad.ok()) {
      return absl::InvalidArgumentError(absl::StrCat(where, bad.message()));
    }
  }
  return absl::OkStatus();
}

}  // namespace totalgrad::scheduler
