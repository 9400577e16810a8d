#include "server/service/convert.h"

#include <cmath>

#include "runtime/record_proto.h"
#include "runtime/status_origin.h"
#include "server/storage/service_records.h"
#include "server/sweep/sweep_proto.h"

#include <string>

namespace totalgrad::service {

grpc::Status ToGrpcStatus(const absl::Status& status) {
  if (status.ok()) return grpc::Status::OK;
  // Marked as the coordinator's answer (status_origin.h): a client tells a
  // refusal (e.g. a full disk) from an unreachable coordinator.
  return rpc::CoordinatorStatus(static_cast<grpc::StatusCode>(status.code()),
                                std::string(status.message()));
}

storage::WorkerIdentity FromProto(const v1::WorkerIdentity& worker) {
  storage::WorkerIdentity identity;
  identity.worker_id = worker.worker_id();
  identity.host = worker.host();
  identity.build = worker.build();
  identity.slots = worker.slots();
  identity.study_jobs = worker.study_jobs();
  identity.instance = worker.instance();
  identity.takes_over = worker.takes_over();
  return identity;
}

// The study rows are core's records: their fields go by name through the
// records' field tables (runtime/record_proto.h); only the row's key
// is named here.
storage::StudyCell FromProto(const v1::StudyCellRow& row) {
  storage::StudyCell c;
  c.index = row.index();
  record_proto::RecordFromProto<study::CellResult>(study::CellFields(), row, &c);
  return c;
}

storage::StudyReference FromProto(const v1::StudyReferenceRow& row) {
  storage::StudyReference r;
  r.index = row.index();
  record_proto::RecordFromProto<study::ReferenceGradient>(study::ReferenceFields(), row, &r);
  return r;
}

storage::StudyRows StudyRowsFromProto(
    const google::protobuf::RepeatedPtrField<v1::StudyCellRow>& cells,
    const google::protobuf::RepeatedPtrField<v1::StudyReferenceRow>& references) {
  storage::StudyRows rows;
  for (const auto& c : cells) rows.cells.push_back(FromProto(c));
  for (const auto& r : references) rows.references.push_back(FromProto(r));
  return rows;
}

storage::JobResults ResultsFromProto(const v1::HeartbeatRequest& request) {
  storage::JobResults results;
  results.episodes = FromProto(request.episodes());
  results.study = StudyRowsFromProto(request.study_cells(), request.study_references());
  return results;
}

storage::JobCompletion CompletionFromProto(const v1::CompleteRequest& request) {
  storage::JobCompletion completion;
  completion.results.episodes = FromProto(request.episodes());
  completion.results.study = StudyRowsFromProto(request.study_cells(), request.study_references());
  completion.totals.episodes = request.episodes_total();
  completion.totals.study_cells = request.study_cells_total();
  completion.totals.study_references = request.study_references_total();
  completion.success = request.success();
  completion.final_eval_cost = request.final_eval_cost();
  completion.checkpoint = CheckpointFromProto(request.has_checkpoint(), request.checkpoint());
  return completion;
}

void ToProto(const storage::StudyCell& c, v1::StudyCellRow* out) {
  out->set_index(c.index);
  record_proto::RecordToProto<study::CellResult>(study::CellFields(), c, out);
}

void ToProto(const storage::StudyReference& r, v1::StudyReferenceRow* out) {
  out->set_index(r.index);
  record_proto::RecordToProto<study::ReferenceGradient>(study::ReferenceFields(), r, out);
}

void ToProto(const storage::StudyCellRecord& record, v1::StudyCellRow* out) {
  ToProto(record.cell, out);
  out->set_job_id(record.job_id);
  out->set_attempt(record.attempt);
  out->set_study(record.study);
}

void ToProto(const storage::StudyReferenceRecord& record, v1::StudyReferenceRow* out) {
  ToProto(record.reference, out);
  out->set_job_id(record.job_id);
  out->set_attempt(record.attempt);
  out->set_study(record.study);
}

// Exhaustive (no default): a kind without its wire value does not compile.
v1::JobKind ToProto(JobKind kind) {
  switch (kind) {
    case JobKind::kTrial: return v1::JOB_KIND_TRIAL;
    case JobKind::kStudy: return v1::JOB_KIND_STUDY;
  }
  return v1::JOB_KIND_UNSPECIFIED;
}

// JOB_KIND_UNSPECIFIED is a trial: jobs of coordinators older than the field.
JobKind FromProto(v1::JobKind kind) {
  return kind == v1::JOB_KIND_STUDY ? JobKind::kStudy : JobKind::kTrial;
}

storage::LeaseKey FromProto(const v1::LeaseKey& key) { return {key.job_id(), key.attempt()}; }

// The episode's record by name (cpu_seconds, absent from older workers,
// reads as NaN), then the details text.
storage::Episode FromProto(const v1::EpisodeReport& report) {
  storage::Episode e;
  record_proto::RecordFromProto<learner::EpisodeSummary>(learner::EpisodeFields(), report, &e);
  e.details_json = report.details_json();
  return e;
}

std::vector<storage::Episode> FromProto(
    const google::protobuf::RepeatedPtrField<v1::EpisodeReport>& reports) {
  std::vector<storage::Episode> episodes;
  episodes.reserve(reports.size());
  for (const auto& report : reports) episodes.push_back(FromProto(report));
  return episodes;
}

sweep::SweepSpec FromProto(const v1::SweepSpec& spec) { return sweep::SweepSpecFromProto(spec); }

std::optional<storage::PruneScope> FromProto(v1::PruneScope scope) {
  switch (scope) {
    case v1::PRUNE_SCOPE_NONE: return storage::PruneScope::kNone;
    case v1::PRUNE_SCOPE_STALE: return storage::PruneScope::kStale;
    case v1::PRUNE_SCOPE_COMPLETED: return storage::PruneScope::kCompleted;
    default: return std::nullopt;
  }
}

void ToProto(const storage::SweepDiskUse& use, v1::PruneSweepResponse* out) {
  out->set_episodes(use.episodes);
  out->set_episode_details_bytes(use.episode_details_bytes);
  const auto copy = [](const storage::CheckpointUse& from, v1::CheckpointUse* to) {
    to->set_count(from.count);
    to->set_bytes(from.bytes);
  };
  copy(use.completed, out->mutable_completed());
  copy(use.stale, out->mutable_stale());
  copy(use.unfinished, out->mutable_unfinished());
  copy(use.removed, out->mutable_removed());
}

std::optional<storage::JobState> FromProto(v1::JobState state) {
  switch (state) {
    case v1::JOB_STATE_QUEUED: return storage::JobState::kQueued;
    case v1::JOB_STATE_RUNNING: return storage::JobState::kRunning;
    case v1::JOB_STATE_COMPLETED: return storage::JobState::kCompleted;
    case v1::JOB_STATE_FAILED: return storage::JobState::kFailed;
    case v1::JOB_STATE_CANCELLED: return storage::JobState::kCancelled;
    default: return std::nullopt;
  }
}

void ToProto(const sweep::SweepSpec& spec, v1::SweepSpec* out) { sweep::SweepSpecToProto(spec, out); }

v1::JobState ToProto(storage::JobState state) {
  switch (state) {
    case storage::JobState::kQueued: return v1::JOB_STATE_QUEUED;
    case storage::JobState::kRunning: return v1::JOB_STATE_RUNNING;
    case storage::JobState::kCompleted: return v1::JOB_STATE_COMPLETED;
    case storage::JobState::kFailed: return v1::JOB_STATE_FAILED;
    case storage::JobState::kCancelled: return v1::JOB_STATE_CANCELLED;
  }
  return v1::JOB_STATE_UNSPECIFIED;
}

v1::SweepState ToProto(storage::SweepState state) {
  switch (state) {
    case storage::SweepState::kRunning: return v1::SWEEP_STATE_RUNNING;
    case storage::SweepState::kPaused: return v1::SWEEP_STATE_PAUSED;
    case storage::SweepState::kCancelled: return v1::SWEEP_STATE_CANCELLED;
  }
  return v1::SWEEP_STATE_UNSPECIFIED;
}

v1::AttemptState ToProto(storage::AttemptState state) {
  switch (state) {
    case storage::AttemptState::kRunning: return v1::ATTEMPT_STATE_RUNNING;
    case storage::AttemptState::kCompleted: return v1::ATTEMPT_STATE_COMPLETED;
    case storage::AttemptState::kFailed: return v1::ATTEMPT_STATE_FAILED;
    case storage::AttemptState::kLeaseLost: return v1::ATTEMPT_STATE_LEASE_LOST;
    case storage::AttemptState::kReleased: return v1::ATTEMPT_STATE_RELEASED;
    case storage::AttemptState::kCancelled: return v1::ATTEMPT_STATE_CANCELLED;
  }
  return v1::ATTEMPT_STATE_UNSPECIFIED;
}

v1::Directive ToProto(scheduler::Directive directive) {
  switch (directive) {
    case scheduler::Directive::kContinue: return v1::DIRECTIVE_CONTINUE;
    case scheduler::Directive::kCancel: return v1::DIRECTIVE_CANCEL;
    case scheduler::Directive::kDrain: return v1::DIRECTIVE_DRAIN;
  }
  return v1::DIRECTIVE_UNSPECIFIED;
}

// Jobs and sweeps go by name through their field tables
// (server/storage/service_records.h), a job's options included.
void ToProto(const storage::SweepRecord& sweep, v1::SweepInfo* out) {
  record_proto::RecordToProto(storage::SweepFields(), sweep, out);
}

storage::SweepRecord FromProto(const v1::SweepInfo& info) {
  storage::SweepRecord sweep;
  record_proto::RecordFromProto(storage::SweepFields(), info, &sweep);
  return sweep;
}

void ToProto(const storage::JobRecord& job, v1::JobInfo* out) {
  record_proto::RecordToProto(storage::JobFields(), job, out);
}

storage::JobRecord FromProto(const v1::JobInfo& info) {
  storage::JobRecord job;
  record_proto::RecordFromProto(storage::JobFields(), info, &job);
  return job;
}

void ToProto(const storage::AttemptRecord& attempt, v1::AttemptInfo* out) {
  out->set_job_id(attempt.key.job_id);
  out->set_attempt(attempt.key.attempt);
  out->set_state(ToProto(attempt.state));
  out->set_worker_id(attempt.worker_id);
  out->set_worker_host(attempt.worker_host);
  out->set_worker_build(attempt.worker_build);
  out->set_started_unix_ms(attempt.started_ms);
  out->set_ended_unix_ms(attempt.ended_ms);
  if (attempt.state == storage::AttemptState::kRunning) {
    out->set_lease_expires_unix_ms(attempt.lease_expires_ms);
  }
  out->set_error(attempt.error);
  out->set_episodes_stored(attempt.episodes_stored);
  out->set_checkpoint_episode(attempt.checkpoint_episode);
  out->set_origin(attempt.origin);
}

storage::ImportedAttempt FromProto(const v1::AttemptInfo& info) {
  storage::ImportedAttempt attempt;
  record_proto::RecordFromProto(storage::ImportedAttemptFields(), info, &attempt);
  return attempt;
}

void ToProto(const storage::EventRecord& event, v1::Event* out) {
  out->set_unix_ms(event.ms);
  out->set_job_id(event.job_id);
  out->set_attempt(event.attempt);
  out->set_kind(event.kind);
  out->set_message(event.message);
}

void ToProto(const storage::WorkerRecord& worker, int64_t now_ms, int64_t lease_timeout_ms,
             v1::WorkerInfo* out) {
  out->set_worker_id(worker.identity.worker_id);
  out->set_host(worker.identity.host);
  out->set_build(worker.identity.build);
  out->set_slots(worker.identity.slots);
  out->set_running(worker.running);
  out->set_first_seen_unix_ms(worker.first_seen_ms);
  out->set_last_seen_unix_ms(worker.last_seen_ms);
  if (worker.draining) {
    out->set_state(v1::WORKER_STATE_DRAINING);
  } else if (now_ms - worker.last_seen_ms > lease_timeout_ms) {
    out->set_state(v1::WORKER_STATE_GONE);
  } else {
    out->set_state(v1::WORKER_STATE_ACTIVE);
  }
}

void ToProto(const results::CompletedTrial& result, v1::TrialResult* out) {
  record_proto::RecordToProto<results::CompletedTrial>(results::CompletedTrialResultFields(),
                                                       result, out);
}

void ToProto(const storage::Episode& episode, v1::EpisodeReport* out) {
  record_proto::RecordToProto<learner::EpisodeSummary>(learner::EpisodeFields(), episode, out);
  out->set_details_json(episode.details_json);
}

void ToProto(const storage::EpisodeRowRecord& row, v1::EpisodeRow* out) {
  out->set_job_id(row.job_id);
  out->set_attempt(row.attempt);
  out->set_method(row.method);
  out->set_seed(row.seed);
  out->set_variant(row.variant);
  ToProto(row.episode, out->mutable_report());
  out->set_reported_unix_ms(row.reported_ms);
  out->set_final_attempt(row.final_attempt);
}

void ToProto(const scheduler::Lease& lease, v1::Lease* out) {
  out->mutable_key()->set_job_id(lease.key.job_id);
  out->mutable_key()->set_attempt(lease.key.attempt);
  out->set_sweep_name(lease.job.sweep_name);
  out->set_method(lease.job.method);
  out->set_seed(lease.job.seed);
  out->set_variant(lease.job.variant);
  for (const auto& [key, value] : lease.job.options) {
    auto* option = out->add_options();
    option->set_key(key);
    option->set_value(value);
  }
  out->set_episodes_expected(lease.job.episodes_expected);
  out->set_kind(ToProto(lease.job.kind));
  if (lease.job.kind == storage::JobKind::kStudy) out->set_study_spec_json(lease.job.payload);
  out->set_heartbeat_interval_ms(static_cast<int32_t>(lease.heartbeat_interval_ms));
  out->set_lease_timeout_ms(static_cast<int32_t>(lease.lease_timeout_ms));
  if (lease.resume_from) {
    ToProto(lease.resume_from->checkpoint, out->mutable_resume_from());
    out->set_resume_from_attempt(lease.resume_from->key.attempt);
    out->set_resume_from_build(lease.resume_from->worker_build);
  }
}

std::optional<storage::Checkpoint> CheckpointFromProto(bool present,
                                                       const v1::TrialCheckpoint& checkpoint) {
  if (!present || checkpoint.data().empty()) return std::nullopt;
  return storage::Checkpoint{checkpoint.episode(), checkpoint.format_version(), checkpoint.data()};
}

void ToProto(const storage::Checkpoint& checkpoint, v1::TrialCheckpoint* out) {
  out->set_episode(checkpoint.episode);
  out->set_format_version(checkpoint.format_version);
  out->set_data(checkpoint.data);
}

void ToProto(const storage::SweepRecord& sweep, const storage::ImportResult& result,
             v1::ImportSweepResponse* out) {
  ToProto(sweep, out->mutable_sweep());
  out->set_sweep_created(result.sweep_created);
  out->set_jobs_imported(result.jobs_imported);
  out->set_jobs_already_complete(result.jobs_already_complete);
  out->set_jobs_not_completed(result.jobs_not_completed);
  out->set_jobs_running_here(result.jobs_running_here);
  out->set_jobs_unknown(result.jobs_unknown);
  out->set_episodes_imported(result.episodes_imported);
  out->set_study_rows_imported(result.study_rows_imported);
  out->set_checkpoints_imported(result.checkpoints_imported);
  out->set_jobs_keeping_options(result.jobs_keeping_options);
  for (const std::string& key : result.options_kept) out->add_options_kept(key);
}

}  // namespace totalgrad::service
