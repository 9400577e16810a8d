#include "server/service/control_service.h"

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "absl/strings/str_cat.h"
#include "runtime/status_macros.h"
#include "server/service/archive_spool.h"
#include "server/service/message_budget.h"
#include "server/service/sweep_archive.h"
#include "server/service/convert.h"
#include "server/sweep/sweep_spec.h"
#include "core/learner/trial_options.h"

namespace totalgrad::service {

namespace {
// A stream whose client stopped reading (cancelled, or its deadline passed).
grpc::Status ClientWentAway() {
  return grpc::Status(grpc::StatusCode::CANCELLED, "the client went away during the stream");
}

// A sweep's completed trials as ListTrialResults and ExportTrialResults both
// answer them.
struct TrialResultsOfSweep {
  storage::SweepRecord sweep;
  std::vector<results::CompletedTrial> results;
};

absl::StatusOr<TrialResultsOfSweep> ReadTrialResults(storage::Store* store,
                                                     const std::string& sweep_name) {
  absl::StatusOr<storage::SweepRecord> sweep = store->GetSweep(sweep_name);
  if (!sweep.ok()) return sweep.status();
  absl::StatusOr<std::vector<results::CompletedTrial>> results =
      store->ListTrialResults(sweep_name);
  if (!results.ok()) return results.status();
  return TrialResultsOfSweep{*std::move(sweep), *std::move(results)};
}

// A sweep's study rows as ListStudyRows and ExportStudyRows both answer them.
struct StudyRowsOfSweep {
  storage::SweepRecord sweep;
  std::vector<storage::StudyCellRecord> cells;
  std::vector<storage::StudyReferenceRecord> references;
};

absl::StatusOr<StudyRowsOfSweep> ReadStudyRows(storage::Store* store,
                                               const v1::ListStudyRowsRequest& request) {
  StudyRowsOfSweep rows;
  absl::StatusOr<storage::SweepRecord> sweep = store->GetSweep(request.sweep_name());
  if (!sweep.ok()) return sweep.status();
  rows.sweep = *std::move(sweep);
  const absl::Status status = store->ListStudyRows(request.sweep_name(), request.all_attempts(),
                                                   &rows.cells, &rows.references);
  if (!status.ok()) return status;
  return rows;
}

}  // namespace

#define TG_AUTHORIZE(context)                                                \
  do {                                                                       \
    const absl::Status auth_status = auth_->Check(*(context), Role::kUser);  \
    if (!auth_status.ok()) return ToGrpcStatus(auth_status);                 \
  } while (0)

grpc::Status ControlServiceImpl::SubmitSweep(grpc::ServerContext* context,
                                             const v1::SubmitSweepRequest* request,
                                             v1::SubmitSweepResponse* response) {
  TG_AUTHORIZE(context);
  absl::StatusOr<storage::NewSweep> sweep = PrepareSubmission(*request, options_.build);
  if (!sweep.ok()) return ToGrpcStatus(sweep.status());
  if (request->dry_run()) {
    storage::SweepRecord preview;
    preview.name = sweep->name;
    preview.description = sweep->description;
    preview.canonical_spec = sweep->canonical_spec;
    preview.spec_hash = sweep->spec_hash;
    preview.coordinator_build = sweep->coordinator_build;
    preview.max_attempts = sweep->max_attempts;
    preview.max_lost_leases = sweep->max_lost_leases;
    preview.max_concurrent = sweep->max_concurrent;
    preview.source_name = sweep->source_name;
    preview.jobs_total = preview.jobs_queued = static_cast<int>(sweep->job_count());
    // Counted when the submission was checked: no third expansion of its jobs.
    preview.episodes_expected = sweep->episodes_expected();
    ToProto(preview, response->mutable_sweep());
    response->set_created(false);
    return grpc::Status::OK;
  }
  // A sweep of this name with another spec: the submission may grow it.
  absl::StatusOr<storage::SweepRecord> existing = store_->GetSweep(sweep->name);
  if (existing.ok() && existing->spec_hash != sweep->spec_hash &&
      std::find(sweep->equivalent_spec_hashes.begin(), sweep->equivalent_spec_hashes.end(),
                existing->spec_hash) == sweep->equivalent_spec_hashes.end()) {
    absl::StatusOr<sweep::SweepSpec> stored = sweep::SpecFromCanonicalJson(existing->canonical_spec);
    if (!stored.ok()) return ToGrpcStatus(stored.status());
    absl::StatusOr<sweep::SweepSpec> submitted = sweep::SpecFromCanonicalJson(sweep->canonical_spec);
    if (!submitted.ok()) return ToGrpcStatus(submitted.status());
    absl::StatusOr<sweep::SweepSpec> merged = sweep::UnionOfSweeps(*stored, *submitted);
    if (!merged.ok()) return ToGrpcStatus(merged.status());
    v1::SubmitSweepRequest union_request;
    ToProto(*merged, union_request.mutable_spec());
    union_request.set_source_name(request->source_name());
    union_request.set_source_text(request->source_text());
    absl::StatusOr<storage::NewSweep> grown = PrepareSubmission(union_request, options_.build);
    if (!grown.ok()) return ToGrpcStatus(grown.status());
    int added = 0;
    if (grown->spec_hash != existing->spec_hash) {
      absl::StatusOr<int> result = scheduler_->GrowSweep(*grown);
      if (!result.ok()) return ToGrpcStatus(result.status());
      added = *result;
    }
    absl::StatusOr<storage::SweepRecord> record = store_->GetSweep(sweep->name);
    if (!record.ok()) return ToGrpcStatus(record.status());
    ToProto(*record, response->mutable_sweep());
    response->set_created(false);
    response->set_jobs_added(added);
    return grpc::Status::OK;
  }
  bool created = false;
  absl::StatusOr<storage::SweepRecord> record = scheduler_->SubmitSweep(*sweep, &created);
  if (!record.ok()) return ToGrpcStatus(record.status());
  ToProto(*record, response->mutable_sweep());
  response->set_created(created);
  return grpc::Status::OK;
}

grpc::Status ControlServiceImpl::ListSweeps(grpc::ServerContext* context,
                                            const v1::ListSweepsRequest* request,
                                            v1::ListSweepsResponse* response) {
  TG_AUTHORIZE(context);
  absl::StatusOr<std::vector<storage::SweepRecord>> sweeps = store_->ListSweeps();
  if (!sweeps.ok()) return ToGrpcStatus(sweeps.status());
  for (const auto& sweep : *sweeps) ToProto(sweep, response->add_sweeps());
  return grpc::Status::OK;
}

grpc::Status ControlServiceImpl::GetSweep(grpc::ServerContext* context,
                                          const v1::SweepRequest* request,
                                          v1::SweepInfo* response) {
  TG_AUTHORIZE(context);
  absl::StatusOr<storage::SweepRecord> sweep = store_->GetSweep(request->name());
  if (!sweep.ok()) return ToGrpcStatus(sweep.status());
  ToProto(*sweep, response);
  return grpc::Status::OK;
}

grpc::Status ControlServiceImpl::SetState(grpc::ServerContext* context,
                                          const v1::SweepRequest* request,
                                          storage::SweepState state, v1::SweepInfo* response) {
  TG_AUTHORIZE(context);
  absl::StatusOr<storage::SweepRecord> sweep = scheduler_->SetSweepState(request->name(), state);
  if (!sweep.ok()) return ToGrpcStatus(sweep.status());
  ToProto(*sweep, response);
  return grpc::Status::OK;
}

grpc::Status ControlServiceImpl::CancelSweep(grpc::ServerContext* context,
                                             const v1::SweepRequest* request,
                                             v1::SweepInfo* response) {
  return SetState(context, request, storage::SweepState::kCancelled, response);
}
grpc::Status ControlServiceImpl::PauseSweep(grpc::ServerContext* context,
                                            const v1::SweepRequest* request,
                                            v1::SweepInfo* response) {
  return SetState(context, request, storage::SweepState::kPaused, response);
}
grpc::Status ControlServiceImpl::ResumeSweep(grpc::ServerContext* context,
                                             const v1::SweepRequest* request,
                                             v1::SweepInfo* response) {
  return SetState(context, request, storage::SweepState::kRunning, response);
}

grpc::Status ControlServiceImpl::DeleteSweep(grpc::ServerContext* context,
                                             const v1::DeleteSweepRequest* request,
                                             v1::DeleteSweepResponse* response) {
  TG_AUTHORIZE(context);
  if (!request->has_expected()) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                        "expected: the counts of the sweep's archive are required (write the "
                        "archive first: totalgrad sweep delete does)");
  }
  storage::SweepContents expected;
  expected.jobs = request->expected().jobs();
  expected.attempts = request->expected().attempts();
  expected.episodes = request->expected().episodes();
  expected.study_rows = request->expected().study_rows();
  absl::StatusOr<storage::SweepContents> deleted =
      scheduler_->DeleteSweep(request->name(), expected);
  if (!deleted.ok()) return ToGrpcStatus(deleted.status());
  v1::SweepContents* out = response->mutable_deleted();
  out->set_jobs(deleted->jobs);
  out->set_attempts(deleted->attempts);
  out->set_episodes(deleted->episodes);
  out->set_study_rows(deleted->study_rows);
  return grpc::Status::OK;
}

grpc::Status ControlServiceImpl::PruneSweep(grpc::ServerContext* context,
                                            const v1::PruneSweepRequest* request,
                                            v1::PruneSweepResponse* response) {
  TG_AUTHORIZE(context);
  const std::optional<storage::PruneScope> scope = FromProto(request->scope());
  if (!scope) return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "scope: unknown value");
  absl::StatusOr<storage::SweepDiskUse> use =
      store_->PruneCheckpoints(request->name(), *scope, clock_->NowMs());
  if (!use.ok()) return ToGrpcStatus(use.status());
  ToProto(*use, response);
  return grpc::Status::OK;
}

grpc::Status ControlServiceImpl::ListJobs(grpc::ServerContext* context,
                                          const v1::ListJobsRequest* request,
                                          v1::ListJobsResponse* response) {
  TG_AUTHORIZE(context);
  if (request->page_size() < 0 || request->page_size() > 10000) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "page_size must be in 0..10000");
  }
  storage::JobFilter filter;
  filter.sweep_name = request->sweep_name();
  filter.after_job_id = request->after_job_id();
  filter.limit = request->page_size() == 0 ? 1000 : request->page_size();
  for (int state : request->states()) {
    std::optional<storage::JobState> parsed = FromProto(static_cast<v1::JobState>(state));
    if (!parsed) {
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                          absl::StrCat("states: ", state, " is not a job state"));
    }
    filter.states.push_back(*parsed);
  }
  absl::StatusOr<std::vector<storage::JobRecord>> jobs = store_->ListJobs(filter);
  if (!jobs.ok()) return ToGrpcStatus(jobs.status());
  // The page ends at page_size jobs or at the byte budget, whichever first.
  MessageBudget budget;
  for (size_t i = 0; i < jobs->size(); ++i) {
    v1::JobInfo* job = response->add_jobs();
    ToProto((*jobs)[i], job);
    budget.Add(*job);
    const bool more = i + 1 < jobs->size() || static_cast<int>(jobs->size()) == filter.limit;
    if (!more) break;
    if (budget.Full() || i + 1 == jobs->size()) {
      response->set_next_after_job_id((*jobs)[i].id);
      break;
    }
  }
  return grpc::Status::OK;
}

grpc::Status ControlServiceImpl::RetryJob(grpc::ServerContext* context,
                                          const v1::JobRequest* request, v1::JobInfo* response) {
  TG_AUTHORIZE(context);
  absl::StatusOr<storage::JobRecord> job = scheduler_->RetryJob(request->job_id());
  if (!job.ok()) return ToGrpcStatus(job.status());
  ToProto(*job, response);
  return grpc::Status::OK;
}

grpc::Status ControlServiceImpl::SupersedeJob(grpc::ServerContext* context,
                                              const v1::SupersedeJobRequest* request,
                                              v1::JobInfo* response) {
  TG_AUTHORIZE(context);
  // The same trial: every option that decides the episodes equal, as the
  // worker reads them (a key stored before it existed reads as its old value).
  std::optional<learner::TrialOptions> options[2];
  for (int i = 0; i < 2; ++i) {
    const int64_t id = i == 0 ? request->job_id() : request->by_job_id();
    absl::StatusOr<storage::JobRecord> job = store_->GetJob(id);
    if (!job.ok()) return ToGrpcStatus(job.status());
    absl::StatusOr<learner::TrialOptions> parsed = learner::TrialOptionsFromStoredPairs(job->options);
    if (!parsed.ok()) {
      return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION,
                          absl::StrCat("job ", id, ": its options do not parse: ",
                                       parsed.status().message()));
    }
    options[i] = *std::move(parsed);
  }
  if (absl::Status same = learner::SameEpisodes(*options[0], *options[1]); !same.ok()) {
    return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION,
                        absl::StrCat("job ", request->by_job_id(), " is not a re-run of job ",
                                     request->job_id(), ": ", same.message()));
  }
  absl::StatusOr<storage::JobRecord> job =
      scheduler_->SupersedeJob(request->job_id(), request->by_job_id());
  if (!job.ok()) return ToGrpcStatus(job.status());
  ToProto(*job, response);
  return grpc::Status::OK;
}

grpc::Status ControlServiceImpl::GetJobLog(grpc::ServerContext* context,
                                           const v1::JobRequest* request,
                                           v1::GetJobLogResponse* response) {
  TG_AUTHORIZE(context);
  absl::StatusOr<storage::JobRecord> job = store_->GetJob(request->job_id());
  if (!job.ok()) return ToGrpcStatus(job.status());
  absl::StatusOr<std::vector<storage::AttemptRecord>> attempts =
      store_->ListAttempts(request->job_id());
  if (!attempts.ok()) return ToGrpcStatus(attempts.status());
  absl::StatusOr<std::vector<storage::EventRecord>> events = store_->ListEvents(request->job_id());
  if (!events.ok()) return ToGrpcStatus(events.status());
  ToProto(*job, response->mutable_job());
  for (const auto& attempt : *attempts) ToProto(attempt, response->add_attempts());
  for (const auto& event : *events) ToProto(event, response->add_events());
  return grpc::Status::OK;
}

grpc::Status ControlServiceImpl::GetJobArtifacts(grpc::ServerContext* context,
                                                 const v1::JobRequest* request,
                                                 v1::GetJobArtifactsResponse* response) {
  TG_AUTHORIZE(context);
  absl::StatusOr<storage::JobRecord> job = store_->GetJob(request->job_id());
  if (!job.ok()) return ToGrpcStatus(job.status());
  // A completed job's result is its completed attempt's final state.
  absl::StatusOr<std::optional<storage::CheckpointRecord>> checkpoint =
      store_->GetCheckpoint(job->id, job->completed_attempt);
  if (!checkpoint.ok()) return ToGrpcStatus(checkpoint.status());
  if (!checkpoint->has_value()) {
    return grpc::Status(grpc::StatusCode::NOT_FOUND,
                        absl::StrCat("job ", job->id, " has no trial checkpoint (",
                                     job->kind == storage::JobKind::kStudy
                                         ? "a study job"
                                         : "no episode reported one: none finished, or an older "
                                           "worker ran it",
                                     ")"));
  }
  ToProto(*job, response->mutable_job());
  response->set_attempt((**checkpoint).key.attempt);
  response->set_worker_build((**checkpoint).worker_build);
  ToProto((**checkpoint).checkpoint, response->mutable_checkpoint());
  return grpc::Status::OK;
}

grpc::Status ControlServiceImpl::ListTrialResults(grpc::ServerContext* context,
                                                  const v1::SweepRequest* request,
                                                  v1::ListTrialResultsResponse* response) {
  TG_AUTHORIZE(context);
  const absl::StatusOr<TrialResultsOfSweep> read = ReadTrialResults(store_, request->name());
  if (!read.ok()) return ToGrpcStatus(read.status());
  ToProto(read->sweep, response->mutable_sweep());
  for (const auto& result : read->results) ToProto(result, response->add_results());
  return grpc::Status::OK;
}

grpc::Status ControlServiceImpl::ExportTrialResults(
    grpc::ServerContext* context, const v1::SweepRequest* request,
    grpc::ServerWriter<v1::ListTrialResultsResponse>* writer) {
  TG_AUTHORIZE(context);
  const absl::StatusOr<TrialResultsOfSweep> read = ReadTrialResults(store_, request->name());
  if (!read.ok()) return ToGrpcStatus(read.status());
  BatchWriter<v1::ListTrialResultsResponse> batches(writer);
  ToProto(read->sweep, batches.batch()->mutable_sweep());
  for (const auto& result : read->results) {
    v1::TrialResult* row = batches.batch()->add_results();
    ToProto(result, row);
    if (!batches.Added(*row)) return ClientWentAway();
  }
  return batches.Finish() ? grpc::Status::OK : ClientWentAway();
}

grpc::Status ControlServiceImpl::ExportEpisodes(
    grpc::ServerContext* context, const v1::ExportEpisodesRequest* request,
    grpc::ServerWriter<v1::ExportEpisodesResponse>* writer) {
  TG_AUTHORIZE(context);
  // Batches of at most 500 rows (the store's) and of about the byte budget
  // (episode details reach 64 KiB a row).
  BatchWriter<v1::ExportEpisodesResponse> batches(writer);
  const absl::Status status = store_->ExportEpisodes(
      request->sweep_name(), request->all_attempts(), /*batch_size=*/500,
      [&](std::vector<storage::EpisodeRowRecord> rows) -> absl::Status {
        for (const auto& row : rows) {
          v1::EpisodeRow* added = batches.batch()->add_rows();
          ToProto(row, added);
          if (!batches.Added(*added)) {
            return absl::CancelledError("the client went away during the export");
          }
        }
        return batches.Finish() ? absl::OkStatus()
                                : absl::CancelledError("the client went away during the export");
      });
  return ToGrpcStatus(status);
}

grpc::Status ControlServiceImpl::ListStudyRows(grpc::ServerContext* context,
                                               const v1::ListStudyRowsRequest* request,
                                               v1::ListStudyRowsResponse* response) {
  TG_AUTHORIZE(context);
  const absl::StatusOr<StudyRowsOfSweep> rows = ReadStudyRows(store_, *request);
  if (!rows.ok()) return ToGrpcStatus(rows.status());
  ToProto(rows->sweep, response->mutable_sweep());
  for (const auto& cell : rows->cells) ToProto(cell, response->add_cells());
  for (const auto& reference : rows->references) ToProto(reference, response->add_references());
  return grpc::Status::OK;
}

grpc::Status ControlServiceImpl::ExportStudyRows(
    grpc::ServerContext* context, const v1::ListStudyRowsRequest* request,
    grpc::ServerWriter<v1::ListStudyRowsResponse>* writer) {
  TG_AUTHORIZE(context);
  const absl::StatusOr<StudyRowsOfSweep> rows = ReadStudyRows(store_, *request);
  if (!rows.ok()) return ToGrpcStatus(rows.status());
  BatchWriter<v1::ListStudyRowsResponse> batches(writer);
  ToProto(rows->sweep, batches.batch()->mutable_sweep());
  for (const auto& cell : rows->cells) {
    v1::StudyCellRow* row = batches.batch()->add_cells();
    ToProto(cell, row);
    if (!batches.Added(*row)) return ClientWentAway();
  }
  for (const auto& reference : rows->references) {
    v1::StudyReferenceRow* row = batches.batch()->add_references();
    ToProto(reference, row);
    if (!batches.Added(*row)) return ClientWentAway();
  }
  return batches.Finish() ? grpc::Status::OK : ClientWentAway();
}

grpc::Status ControlServiceImpl::ListWorkers(grpc::ServerContext* context,
                                             const v1::ListWorkersRequest* request,
                                             v1::ListWorkersResponse* response) {
  TG_AUTHORIZE(context);
  absl::StatusOr<std::vector<storage::WorkerRecord>> workers = store_->ListWorkers();
  if (!workers.ok()) return ToGrpcStatus(workers.status());
  const int64_t now = clock_->NowMs();
  const int64_t timeout = absl::ToInt64Milliseconds(scheduler_->options().lease_timeout);
  for (const auto& worker : *workers) ToProto(worker, now, timeout, response->add_workers());
  return grpc::Status::OK;
}

grpc::Status ControlServiceImpl::DrainWorker(grpc::ServerContext* context,
                                             const v1::DrainWorkerRequest* request,
                                             v1::WorkerInfo* response) {
  TG_AUTHORIZE(context);
  absl::StatusOr<storage::WorkerRecord> worker = scheduler_->DrainWorker(request->worker_id());
  if (!worker.ok()) return ToGrpcStatus(worker.status());
  ToProto(*worker, clock_->NowMs(),
          absl::ToInt64Milliseconds(scheduler_->options().lease_timeout), response);
  return grpc::Status::OK;
}

grpc::Status ControlServiceImpl::Health(grpc::ServerContext* context,
                                        const v1::HealthRequest* request,
                                        v1::HealthResponse* response) {
  TG_AUTHORIZE(context);
  const absl::Status health =
      health_check_ ? health_check_()
                    : (serving_ && !scheduler_->shut_down()
                           ? absl::OkStatus()
                           : absl::UnavailableError("not serving (starting or shutting down)"));
  response->set_serving(health.ok());
  if (!health.ok()) response->set_not_serving_reason(std::string(health.message()));
  response->set_build(options_.build);
  response->set_database(options_.database);
  response->set_now_unix_ms(clock_->NowMs());
  absl::StatusOr<storage::StoreCounts> counts = store_->Counts();
  if (!counts.ok()) {
    // The counts need the database; the answer still says why it is not
    // serving when that is the reason.
    if (!health.ok()) return grpc::Status::OK;
    return ToGrpcStatus(counts.status());
  }
  absl::StatusOr<std::vector<storage::WorkerRecord>> workers = store_->ListWorkers();
  if (!workers.ok()) return ToGrpcStatus(workers.status());
  const int64_t now = clock_->NowMs();
  const int64_t timeout = absl::ToInt64Milliseconds(scheduler_->options().lease_timeout);
  int active = 0;
  for (const auto& worker : *workers) {
    if (!worker.draining && now - worker.last_seen_ms <= timeout) ++active;
  }
  response->set_sweeps(counts->sweeps);
  response->set_jobs_queued(counts->jobs_queued);
  response->set_jobs_running(counts->jobs_running);
  response->set_workers_active(active);
  return grpc::Status::OK;
}

grpc::Status ControlServiceImpl::Backup(grpc::ServerContext* context,
                                        const v1::BackupRequest* request,
                                        v1::BackupResponse* response) {
  TG_AUTHORIZE(context);
  if (options_.backup_dir.empty()) {
    return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION,
                        "the coordinator was started without --backup-dir");
  }
  const std::string& name = request->file_name();
  const bool plain = !name.empty() && name.size() <= 255 && name != "." && name != ".." &&
                     name.find('/') == std::string::npos && name.find('\0') == std::string::npos;
  if (!plain) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                        "file_name must be a plain file name (no '/', not '.' or '..')");
  }
  const std::string path = (std::filesystem::path(options_.backup_dir) / name).string();
  absl::StatusOr<int64_t> bytes = store_->Backup(path);
  if (!bytes.ok()) return ToGrpcStatus(bytes.status());
  response->set_path(path);
  response->set_bytes(*bytes);
  return grpc::Status::OK;
}

grpc::Status ControlServiceImpl::ImportSweep(grpc::ServerContext* context,
                                             grpc::ServerReader<v1::ImportSweepChunk>* reader,
                                             v1::ImportSweepResponse* response) {
  TG_AUTHORIZE(context);
  // The archive is kept on disk, not in memory (ArchiveSpool); the bound
  // is on that disk use (16 GiB: a 100,000-job sweep is ~250 MB, with each
  // trial's checkpoint a few GB).
  constexpr size_t kMaxArchiveBytes = size_t{16} << 30;
  std::string source = "an archive";
  ArchiveSpool spool;
  if (absl::Status opened = spool.Open(options_.database); !opened.ok()) {
    return ToGrpcStatus(opened);
  }
  v1::ImportSweepChunk chunk;
  while (reader->Read(&chunk)) {
    if (!chunk.source_name().empty()) source = chunk.source_name();
    if (spool.bytes() + chunk.data().size() > kMaxArchiveBytes) {
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                          absl::StrCat("the archive exceeds ", kMaxArchiveBytes, " bytes"));
    }
    if (absl::Status kept = spool.Append(chunk.data()); !kept.ok()) return ToGrpcStatus(kept);
  }
  if (context->IsCancelled()) return ClientWentAway();
  if (absl::Status kept = spool.Close(); !kept.ok()) return ToGrpcStatus(kept);
  absl::StatusOr<SweepArchiveOpening> archive;
  {
    absl::StatusOr<std::ifstream> in = spool.Read();
    if (!in.ok()) return ToGrpcStatus(in.status());
    archive = ReadSweepArchiveOpening(*in);
  }
  if (!archive.ok()) return ToGrpcStatus(archive.status());
  // A sweep of that name here must be this one; otherwise it is created from
  // the canonical spec, and this build must expand it to the same jobs.
  std::optional<storage::NewSweep> create;
  absl::StatusOr<storage::SweepRecord> existing = store_->GetSweep(archive->name);
  if (existing.ok()) {
    if (existing->spec_hash != archive->spec_hash) {
      return grpc::Status(grpc::StatusCode::ALREADY_EXISTS,
                          absl::StrCat("a different sweep named '", archive->name,
                                       "' exists here (spec hash ",
                                       existing->spec_hash.substr(0, 12), ", archive ",
                                       archive->spec_hash.substr(0, 12), ")"));
    }
  } else if (existing.status().code() == absl::StatusCode::kNotFound) {
    absl::StatusOr<sweep::SweepSpec> spec = sweep::SpecFromCanonicalJson(archive->canonical_spec);
    if (!spec.ok()) return ToGrpcStatus(spec.status());
    v1::SubmitSweepRequest request;
    ToProto(*spec, request.mutable_spec());
    request.set_source_name(source);
    absl::StatusOr<storage::NewSweep> prepared = PrepareSubmission(request, options_.build);
    if (!prepared.ok()) return ToGrpcStatus(prepared.status());
    if (prepared->spec_hash != archive->spec_hash) {
      return grpc::Status(
          grpc::StatusCode::FAILED_PRECONDITION,
          absl::StrCat("this build expands the archived spec of '", archive->name,
                       "' to another hash (", prepared->spec_hash.substr(0, 12), " vs ",
                       archive->spec_hash.substr(0, 12),
                       "): its jobs would not be the archive's; import it with the build that "
                       "wrote it (",
                       "see the archive's exported_by)"));
    }
    create = *std::move(prepared);
    create->created_ms = archive->created_ms;  // the archived sweep's own time, when kept
  } else {
    return ToGrpcStatus(existing.status());
  }
  // The jobs, read from the kept archive one at a time inside the import's
  // transaction (a job that does not read rolls it back).
  const int version = archive->version;
  const storage::ImportedJobProducer jobs =
      [&spool, version](const std::function<absl::Status(const storage::ImportedJob&)>& each) {
        ASSIGN_OR_RETURN(std::ifstream in, spool.Read());
        return ForEachArchivedJob(in, version,
                                  [&each](storage::ImportedJob& job) { return each(job); });
      };
  absl::StatusOr<storage::ImportResult> result =
      scheduler_->ImportSweep(create, archive->name, jobs, source);
  if (!result.ok()) return ToGrpcStatus(result.status());
  if (result->sweep_created && archive->state != storage::SweepState::kRunning) {
    absl::StatusOr<storage::SweepRecord> state = scheduler_->SetSweepState(archive->name, archive->state);
    if (!state.ok()) return ToGrpcStatus(state.status());
  }
  absl::StatusOr<storage::SweepRecord> record = store_->GetSweep(archive->name);
  if (!record.ok()) return ToGrpcStatus(record.status());
  ToProto(*record, *result, response);
  return grpc::Status::OK;
}

#undef TG_AUTHORIZE

}  // namespace totalgrad::service
