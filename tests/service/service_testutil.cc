#include "tests/service/service_testutil.h"

#include "absl/strings/str_cat.h"

namespace totalgrad::testing {

storage::NewSweep MakeSweep(const std::string& name, int jobs, int episodes,
                            const std::string& spec_hash) {
  storage::NewSweep sweep;
  sweep.name = name;
  sweep.description = "test sweep";
  sweep.canonical_spec = absl::StrCat("{\"name\":\"", name, "\"}");
  sweep.spec_hash = spec_hash;
  sweep.coordinator_build = "test-build";
  sweep.max_attempts = 3;
  sweep.max_lost_leases = 20;
  for (int i = 0; i < jobs; ++i) {
    storage::NewJob job;
    job.method = "RP";
    job.seed = absl::StrCat(i + 1);
    job.variant = "noise_k=1";
    job.options = {{"method", "RP"}, {"seed", job.seed}, {"noise_k", "1"}};
    job.episodes_expected = episodes;
    sweep.jobs.push_back(job);
  }
  return sweep;
}

storage::NewJob MakeStudyJob(const std::string& payload) {
  storage::NewJob job;
  job.kind = storage::JobKind::kStudy;
  job.method = "study";
  job.seed = "7";
  job.variant = "tiny";
  job.payload = payload;
  return job;
}

storage::Episode MakeEpisode(int episode, double cost) {
  storage::Episode e;
  e.episode = episode;
  e.real_cost = cost;
  if (episode > 0) {
    e.eval_cost_mean = cost + 0.5;
    e.eval_cost_std = 1.0;
    e.predicted_cost = cost - 0.5;
  }
  e.optimisation_seconds = 0.25;
  e.details_json = "{}";
  return e;
}

storage::WorkerIdentity MakeWorker(const std::string& id) {
  storage::WorkerIdentity worker;
  worker.worker_id = id;
  worker.host = "testhost";
  worker.build = "test-worker-build";
  worker.slots = 1;
  return worker;
}

void FaultyStore::FailNext(const std::string& method, absl::Status error, When when) {
  std::lock_guard<std::mutex> lock(mutex_);
  faults_[method] = {std::move(error), when};
}

int FaultyStore::faults_fired() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return fired_;
}

std::optional<FaultyStore::Fault> FaultyStore::Take(const std::string& method) {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = faults_.find(method);
  if (it == faults_.end()) return std::nullopt;
  Fault fault = it->second;
  faults_.erase(it);
  ++fired_;
  return fault;
}

// Forwards `call` unless a fault is armed for `method`.
#define TG_FORWARD(method, call)                                     \
  do {                                                               \
    std::optional<Fault> fault = Take(method);                       \
    if (fault && fault->when == When::kBeforeCommit) return fault->error; \
    auto result = (call);                                            \
    if (fault) return fault->error;                                  \
    return result;                                                   \
  } while (0)

absl::StatusOr<storage::SweepRecord> FaultyStore::CreateSweep(const storage::NewSweep& sweep,
                                                              int64_t now_ms, bool* created) {
  TG_FORWARD("CreateSweep", target_->CreateSweep(sweep, now_ms, created));
}
absl::Status FaultyStore::SetSweepState(const std::string& name, storage::SweepState state,
                                        int64_t now_ms) {
  TG_FORWARD("SetSweepState", target_->SetSweepState(name, state, now_ms));
}
absl::StatusOr<storage::SweepDiskUse> FaultyStore::PruneCheckpoints(const std::string& name,
                                                                    storage::PruneScope scope,
                                                                    int64_t now_ms) {
  TG_FORWARD("PruneCheckpoints", target_->PruneCheckpoints(name, scope, now_ms));
}

absl::StatusOr<storage::SweepContents> FaultyStore::DeleteSweep(
    const std::string& name, const storage::SweepContents& expected, int64_t now_ms) {
  TG_FORWARD("DeleteSweep", target_->DeleteSweep(name, expected, now_ms));
}
absl::Status FaultyStore::StartAttempt(const storage::LeaseKey& key,
                                       const storage::WorkerIdentity& worker, int64_t now_ms,
                                       int64_t lease_expires_ms) {
  TG_FORWARD("StartAttempt", target_->StartAttempt(key, worker, now_ms, lease_expires_ms));
}
absl::StatusOr<std::optional<storage::LeaseKey>> FaultyStore::ClaimJob(
    const storage::ClaimRequest& request) {
  TG_FORWARD("ClaimJob", target_->ClaimJob(request));
}
absl::StatusOr<storage::ResultTotals> FaultyStore::StoreResults(
    const storage::LeaseKey& key, const std::string& worker_id,
    const storage::JobResults& results, int64_t now_ms, std::optional<int64_t> lease_expires_ms) {
  TG_FORWARD("StoreResults",
             target_->StoreResults(key, worker_id, results, now_ms, lease_expires_ms));
}
absl::Status FaultyStore::StoreCheckpoint(const storage::LeaseKey& key,
                                          const std::string& worker_id,
                                          const storage::Checkpoint& checkpoint, int64_t now_ms) {
  TG_FORWARD("StoreCheckpoint", target_->StoreCheckpoint(key, worker_id, checkpoint, now_ms));
}
absl::StatusOr<storage::EndOutcome> FaultyStore::EndAttempt(const storage::AttemptEnd& end) {
  TG_FORWARD("EndAttempt", target_->EndAttempt(end));
}
absl::StatusOr<int> FaultyStore::GrowSweep(const storage::NewSweep& grown, int64_t now_ms) {
  TG_FORWARD("GrowSweep", target_->GrowSweep(grown, now_ms));
}
absl::StatusOr<storage::ImportResult> FaultyStore::ImportJobStream(
    const std::optional<storage::NewSweep>& create, const std::string& sweep_name,
    const storage::ImportedJobProducer& jobs, const std::string& source, int64_t now_ms) {
  TG_FORWARD("ImportJobs", target_->ImportJobStream(create, sweep_name, jobs, source, now_ms));
}
absl::Status FaultyStore::RetryJob(int64_t job_id, int64_t now_ms) {
  TG_FORWARD("RetryJob", target_->RetryJob(job_id, now_ms));
}
absl::StatusOr<int> FaultyStore::SupersedeJob(int64_t job_id, int64_t by_job_id, int64_t now_ms) {
  TG_FORWARD("SupersedeJob", target_->SupersedeJob(job_id, by_job_id, now_ms));
}
absl::StatusOr<int> FaultyStore::ExtendOpenLeases(int64_t lease_expires_ms, int64_t now_ms,
                                                   const std::string& reason) {
  TG_FORWARD("ExtendOpenLeases", target_->ExtendOpenLeases(lease_expires_ms, now_ms, reason));
}
absl::Status FaultyStore::TouchWorker(const storage::WorkerIdentity& worker, int64_t now_ms) {
  TG_FORWARD("TouchWorker", target_->TouchWorker(worker, now_ms));
}
absl::Status FaultyStore::SetWorkerDraining(const std::string& worker_id, bool draining,
                                            int64_t now_ms) {
  TG_FORWARD("SetWorkerDraining", target_->SetWorkerDraining(worker_id, draining, now_ms));
}
absl::StatusOr<storage::SweepRecord> FaultyStore::GetSweep(const std::string& name) {
  TG_FORWARD("GetSweep", target_->GetSweep(name));
}
absl::StatusOr<std::vector<storage::SweepRecord>> FaultyStore::ListSweeps() {
  TG_FORWARD("ListSweeps", target_->ListSweeps());
}
absl::StatusOr<storage::JobRecord> FaultyStore::GetJob(int64_t job_id) {
  TG_FORWARD("GetJob", target_->GetJob(job_id));
}
absl::StatusOr<storage::JobStatus> FaultyStore::GetJobStatus(int64_t job_id) {
  TG_FORWARD("GetJobStatus", target_->GetJobStatus(job_id));
}
absl::StatusOr<std::vector<storage::JobRecord>> FaultyStore::ListJobs(
    const storage::JobFilter& f) {
  TG_FORWARD("ListJobs", target_->ListJobs(f));
}
absl::StatusOr<std::vector<storage::AttemptRecord>> FaultyStore::ListAttempts(int64_t job_id) {
  TG_FORWARD("ListAttempts", target_->ListAttempts(job_id));
}
absl::StatusOr<std::vector<storage::EventRecord>> FaultyStore::ListEvents(int64_t job_id) {
  TG_FORWARD("ListEvents", target_->ListEvents(job_id));
}
absl::StatusOr<std::optional<storage::CheckpointRecord>> FaultyStore::GetCheckpoint(
    int64_t job_id, int attempt) {
  return target_->GetCheckpoint(job_id, attempt);
}
absl::StatusOr<std::vector<storage::ClaimCandidate>> FaultyStore::ListClaimCandidates(int limit) {
  TG_FORWARD("ListClaimCandidates", target_->ListClaimCandidates(limit));
}
absl::StatusOr<std::vector<storage::LeaseKey>> FaultyStore::ListExpiredLeases(int64_t now_ms) {
  TG_FORWARD("ListExpiredLeases", target_->ListExpiredLeases(now_ms));
}
absl::StatusOr<std::vector<storage::WorkerRecord>> FaultyStore::ListWorkers() {
  TG_FORWARD("ListWorkers", target_->ListWorkers());
}
absl::StatusOr<storage::WorkerRecord> FaultyStore::GetWorker(const std::string& worker_id) {
  TG_FORWARD("GetWorker", target_->GetWorker(worker_id));
}
absl::StatusOr<std::vector<results::CompletedTrial>> FaultyStore::ListTrialResults(
    const std::string& sweep_name) {
  TG_FORWARD("ListTrialResults", target_->ListTrialResults(sweep_name));
}
absl::Status FaultyStore::ExportEpisodes(
    const std::string& sweep_name, bool all_attempts, int batch_size,
    const std::function<absl::Status(std::vector<storage::EpisodeRowRecord>)>& sink) {
  TG_FORWARD("ExportEpisodes", target_->ExportEpisodes(sweep_name, all_attempts, batch_size, sink));
}
absl::Status FaultyStore::ListStudyRows(const std::string& sweep_name, bool all_attempts,
                                        std::vector<storage::StudyCellRecord>* cells,
                                        std::vector<storage::StudyReferenceRecord>* references) {
  TG_FORWARD("ListStudyRows", target_->ListStudyRows(sweep_name, all_attempts, cells, references));
}
absl::StatusOr<storage::StoreCounts> FaultyStore::Counts() {
  TG_FORWARD("Counts", target_->Counts());
}
absl::StatusOr<int64_t> FaultyStore::Backup(const std::string& path) {
  TG_FORWARD("Backup", target_->Backup(path));
}

}  // namespace totalgrad::testing
