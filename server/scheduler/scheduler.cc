#include "server/scheduler/scheduler.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "runtime/status_macros.h"
#include "server/storage/job_kinds.h"

namespace totalgrad::scheduler {

using storage::AttemptEnd;
using storage::AttemptState;
using storage::EndOutcome;
using storage::Episode;
using storage::JobRecord;
using storage::JobState;
using storage::LeaseKey;
using storage::SweepState;
using storage::WorkerIdentity;

absl::Status SchedulerOptions::Validate() const {
  if (heartbeat_interval <= absl::ZeroDuration()) {
    return absl::InvalidArgumentError("heartbeat_interval must be > 0");
  }
  if (lease_timeout <= heartbeat_interval) {
    return absl::InvalidArgumentError(absl::StrCat(
        "lease_timeout (", absl::FormatDuration(lease_timeout),
        ") must be longer than heartbeat_interval (", absl::FormatDuration(heartbeat_interval),
        ")"));
  }
  if (max_acquire_wait < absl::ZeroDuration()) {
    return absl::InvalidArgumentError("max_acquire_wait must be >= 0");
  }
  if (claim_scan_limit < 1) return absl::InvalidArgumentError("claim_scan_limit must be >= 1");
  return absl::OkStatus();
}

Scheduler::Scheduler(storage::Store* store, Clock* clock, SchedulerOptions options)
    : store_(store),
      clock_(clock),
      options_(options),
      lease_origin_wall_ms_(clock->NowMs()),
      lease_origin_monotonic_ms_(clock->MonotonicMs()) {}

int64_t Scheduler::LeaseNowMs() {
  return lease_origin_wall_ms_ + (clock_->MonotonicMs() - lease_origin_monotonic_ms_);
}

int64_t Scheduler::LeaseExpiryFrom(int64_t lease_now_ms) const {
  return lease_now_ms + absl::ToInt64Milliseconds(options_.lease_timeout);
}

absl::StatusOr<int> Scheduler::Recover() {
  absl::MutexLock lock(&decision_mutex_);
  ASSIGN_OR_RETURN(int extended,
                   store_->ExtendOpenLeases(LeaseExpiryFrom(LeaseNowMs()), clock_->NowMs(),
                                            "on coordinator start"));
  last_expiry_end_monotonic_ms_ = clock_->MonotonicMs();
  return extended;
}

bool Scheduler::TouchDueLocked(const std::string& worker_id, int64_t now_ms) {
  auto [it, inserted] = last_touch_ms_.try_emplace(worker_id, now_ms);
  if (!inserted &&
      now_ms - it->second < absl::ToInt64Milliseconds(options_.worker_touch_interval)) {
    return false;
  }
  it->second = now_ms;
  return true;
}


absl::Status Scheduler::CheckInstanceLocked(const WorkerIdentity& worker) {
  if (worker.instance.empty()) return absl::OkStatus();  // an older worker: cannot tell
  const int64_t now = clock_->MonotonicMs();
  auto [it, inserted] = instances_.try_emplace(worker.worker_id);
  WorkerInstance& known = it->second;
  if (inserted || known.instance == worker.instance) {
    known.instance = worker.instance;
    known.host = worker.host;
    known.last_heard_monotonic_ms = now;
    return absl::OkStatus();
  }
  if (std::find(known.replaced.begin(), known.replaced.end(), worker.instance) !=
      known.replaced.end()) {
    return absl::AlreadyExistsError(absl::StrCat(
        "worker id '", worker.worker_id, "': this process was replaced by a newer process with "
        "the same id on host '", known.host, "'; every worker needs its own --worker-id"));
  }
  const int64_t silent_ms = now - known.last_heard_monotonic_ms;
  const bool previous_alive = silent_ms < absl::ToInt64Milliseconds(options_.lease_timeout);
  if (previous_alive && !(worker.takes_over && worker.host == known.host)) {
    return absl::AlreadyExistsError(absl::StrCat(
        "worker id '", worker.worker_id, "' is in use by another live worker process on host '",
        known.host, "' (heard from ", silent_ms, " ms ago); every worker needs its own "
        "--worker-id"));
  }
  known.replaced.push_back(known.instance);
  if (known.replaced.size() > 16) known.replaced.erase(known.replaced.begin());
  known.instance = worker.instance;
  known.host = worker.host;
  known.last_heard_monotonic_ms = now;
  return absl::OkStatus();
}

absl::StatusOr<std::optional<storage::CheckpointRecord>> Scheduler::ResumePoint(
    int64_t job_id, const std::string& worker_build) {
  ASSIGN_OR_RETURN(std::vector<storage::AttemptRecord> attempts, store_->ListAttempts(job_id));
  const storage::AttemptRecord* best = nullptr;
  for (const storage::AttemptRecord& a : attempts) {
    if (a.checkpoint_episode < 0 || a.worker_build != worker_build) continue;
    if (best == nullptr || a.checkpoint_episode >= best->checkpoint_episode) best = &a;
  }
  if (best != nullptr) return store_->GetCheckpoint(job_id, best->key.attempt);
  // None of its build: the furthest of any, which the worker names in its
  // log as it starts over.
  return store_->GetCheckpoint(job_id, 0);
}

namespace {
// Candidates read first per lease request (TryAcquire).
constexpr int kFirstClaimScan = 8;
}  // namespace

absl::StatusOr<bool> Scheduler::StaysDrainedLocked(const WorkerIdentity& worker) {
  absl::StatusOr<storage::WorkerRecord> record = store_->GetWorker(worker.worker_id);
  if (absl::IsNotFound(record.status())) return false;  // never seen: never drained
  if (!record.ok()) return record.status();
  if (!record->draining) return false;
  // Workers that send no instance (older builds) stay drained.
  if (worker.instance.empty()) return true;
  const auto drained = drained_instance_.find(worker.worker_id);
  if (drained != drained_instance_.end() && drained->second.empty()) {
    drained->second = worker.instance;  // drained before it was heard from
  }
  if (drained != drained_instance_.end() && drained->second == worker.instance) return true;
  // A new process under a drained id: the drain was its predecessor's.
  RETURN_IF_ERROR(store_->SetWorkerDraining(worker.worker_id, false, clock_->NowMs()));
  if (drained != drained_instance_.end()) drained_instance_.erase(drained);
  return false;
}

absl::StatusOr<std::optional<Lease>> Scheduler::TryAcquire(const WorkerIdentity& worker) {
  RETURN_IF_ERROR(ValidateWorkerIdentity(worker));
  const int64_t now = clock_->NowMs();
  bool drained = false;
  {
    // What is decided in memory: the worker's process and its drain.
    absl::MutexLock lock(&decision_mutex_);
    RETURN_IF_ERROR(CheckInstanceLocked(worker));
    ASSIGN_OR_RETURN(drained, StaysDrainedLocked(worker));
    last_touch_ms_[worker.worker_id] = now;
  }
  // A worker asking for work is alive: it is always recorded (not
  // throttled), so `worker list` shows idle workers too.
  if (drained) {
    RETURN_IF_ERROR(store_->TouchWorker(worker, now));
    return std::optional<Lease>();
  }
  // Which job is the store's decision, inside the lease's own transaction:
  // leases run beside each other, heartbeats and completions, and share
  // their commits (group commit, sqlite_write_queue.cc). A few candidates
  // are read, and the whole scan only when none of those suits the worker
  // (each candidate read cost about half of a lease's CPU; issue 28).
  storage::ClaimRequest request;
  request.worker = worker;
  // A worker that did not say it runs studies (an older build) gets trials only.
  request.suits = [study_jobs = worker.study_jobs](const storage::ClaimCandidate& candidate) {
    return candidate.kind != storage::JobKind::kStudy || study_jobs;
  };
  request.scan_limit = options_.claim_scan_limit;
  request.first_scan = std::min(options_.claim_scan_limit, kFirstClaimScan);
  request.now_ms = now;
  request.lease_expires_ms = LeaseExpiryFrom(LeaseNowMs());
  ASSIGN_OR_RETURN(std::optional<LeaseKey> key, store_->ClaimJob(request));
  if (!key.has_value()) return std::optional<Lease>();
  ASSIGN_OR_RETURN(JobRecord job, store_->GetJob(key->job_id));
  Lease lease;
  if (storage::KindInfo(job.kind).checkpoints && key->attempt > 1) {
    ASSIGN_OR_RETURN(lease.resume_from, ResumePoint(job.id, worker.build));
  }
  lease.job = std::move(job);
  lease.key = *key;
  lease.heartbeat_interval_ms = absl::ToInt64Milliseconds(options_.heartbeat_interval);
  lease.lease_timeout_ms = absl::ToInt64Milliseconds(options_.lease_timeout);
  return std::optional<Lease>(std::move(lease));
}

absl::StatusOr<std::optional<Lease>> Scheduler::Acquire(const WorkerIdentity& worker,
                                                        absl::Duration wait) {
  // Real time, whatever clock_ is: this bounds a gRPC long poll. Measured on
  // the monotonic clock (SystemClock::AwaitUntil), not on the wall clock.
  SystemClock real_time;
  const int64_t deadline_ms =
      real_time.MonotonicMs() + absl::ToInt64Milliseconds(std::min(wait, options_.max_acquire_wait));
  while (true) {
    uint64_t generation;
    {
      absl::MutexLock lock(&work_mutex_);
      if (shutdown_) return std::optional<Lease>();
      generation = work_generation_;
    }
    ASSIGN_OR_RETURN(std::optional<Lease> lease, TryAcquire(worker));
    if (lease.has_value()) return lease;
    absl::MutexLock lock(&work_mutex_);
    // Wake when something changed since we looked (no lost wake-ups: the
    // generation was read before the store was).
    const auto changed_since = [&]() ABSL_EXCLUSIVE_LOCKS_REQUIRED(work_mutex_) {
      return shutdown_ || work_generation_ != generation;
    };
    const bool changed = real_time.AwaitUntil(&work_mutex_, absl::Condition(&changed_since), deadline_ms);
    if (!changed || shutdown_) return std::optional<Lease>();
  }
}

void Scheduler::NotifyWork() {
  {
    absl::MutexLock lock(&work_mutex_);
    ++work_generation_;
  }
}

void Scheduler::Shutdown() {
  {
    absl::MutexLock lock(&work_mutex_);
    shutdown_ = true;
  }
}

bool Scheduler::shut_down() const {
  absl::MutexLock lock(&work_mutex_);
  return shutdown_;
}

absl::StatusOr<HeartbeatResult> Scheduler::Heartbeat(
    const std::string& worker_id, const LeaseKey& key, const storage::JobResults& results,
    const std::optional<storage::Checkpoint>& checkpoint) {
  RETURN_IF_ERROR(ValidateResults(results));
  RETURN_IF_ERROR(ValidateCheckpoint(checkpoint));
  // Heartbeats decide nothing, so they do not take decision_mutex_: each
  // store call is fenced inside its own transaction (the attempt must be
  // open and this worker's), which lets the beats of many workers share
  // commits (group commit, sqlite_write_queue.cc). The lease expiry re-checks
  // in its transaction that a lease it ends was not extended meanwhile.
  const int64_t now = clock_->NowMs();
  HeartbeatResult result;
  const int64_t lease_expires = LeaseExpiryFrom(LeaseNowMs());
  // Always called, rows or not: it is the fence and extends the lease.
  ASSIGN_OR_RETURN(result.stored,
                   store_->StoreResults(key, worker_id, results, now, lease_expires));
  if (checkpoint) RETURN_IF_ERROR(store_->StoreCheckpoint(key, worker_id, *checkpoint, now));
  ASSIGN_OR_RETURN(storage::JobStatus job, store_->GetJobStatus(key.job_id));
  auto worker = store_->GetWorker(worker_id);
  bool touch = false;
  {
    absl::MutexLock lock(&decision_mutex_);
    if (worker.ok()) touch = TouchDueLocked(worker_id, now);
    // A beat shows the id's current process is alive (only it holds leases).
    if (auto known = instances_.find(worker_id); known != instances_.end()) {
      known->second.last_heard_monotonic_ms = clock_->MonotonicMs();
    }
  }
  if (touch) {
    if (absl::Status touched = store_->TouchWorker(worker->identity, now); !touched.ok()) {
      absl::MutexLock lock(&decision_mutex_);
      last_touch_ms_.erase(worker_id);  // not written: the next beat tries again
      return touched;
    }
  }
  if (job.state == JobState::kCancelled) {
    result.directive = Directive::kCancel;
  } else if (worker.ok() && worker->draining) {
    result.directive = Directive::kDrain;
  }
  return result;
}

absl::StatusOr<EndOutcome> Scheduler::End(AttemptEnd end, LeaseBudget budget) {
  // Decided inside the end's own transaction, on the job as it is there (not
  // under decision_mutex_): ends run beside leases and heartbeats and share
  // their commits, and a cancel or another end that commits first is seen.
  end.decide = [budget](const storage::JobStatus& job, AttemptEnd* end) -> absl::Status {
    const bool cancelled = job.state == JobState::kCancelled;
    switch (end->attempt_state) {
      case AttemptState::kCompleted:
        // A trial that finishes after its job was cancelled keeps its episodes
        // (the attempt is recorded as completed) but the cancel stands: only
        // the user takes a job out of cancelled (resuming its sweep).
        end->job_state = cancelled ? JobState::kCancelled : JobState::kCompleted;
        break;
      case AttemptState::kFailed:
        end->failures_delta = 1;
        if (cancelled) {
          end->job_state = JobState::kCancelled;
        } else if (job.failures + 1 >= job.max_attempts) {
          end->job_state = JobState::kFailed;
        } else {
          end->job_state = JobState::kQueued;
        }
        break;
      case AttemptState::kLeaseLost:
      case AttemptState::kReleased:
      case AttemptState::kCancelled:
        if (cancelled) {
          end->attempt_state = end->attempt_state == AttemptState::kLeaseLost
                                   ? AttemptState::kLeaseLost
                                   : AttemptState::kCancelled;
          end->job_state = JobState::kCancelled;
          break;
        }
        if (budget == LeaseBudget::kFree) {
          end->job_state = JobState::kQueued;
          break;
        }
        end->lost_leases_delta = 1;
        if (job.lost_leases + 1 >= job.max_lost_leases) {
          end->job_state = JobState::kFailed;
          end->error = absl::StrCat("gave up after ", job.lost_leases + 1,
                                    " lost or released leases (max_lost_leases); last: ",
                                    end->error);
        } else {
          end->job_state = JobState::kQueued;
        }
        break;
      case AttemptState::kRunning:
        return absl::InvalidArgumentError("an attempt cannot end as running");
    }
    return absl::OkStatus();
  };
  end.now_ms = clock_->NowMs();
  ASSIGN_OR_RETURN(EndOutcome outcome, store_->EndAttempt(end));
  if (outcome == EndOutcome::kApplied) NotifyWork();
  return outcome;
}

absl::Status Scheduler::Complete(const std::string& worker_id, const LeaseKey& key,
                                 const storage::JobCompletion& completion) {
  RETURN_IF_ERROR(ValidateResults(completion.results));
  RETURN_IF_ERROR(ValidateCheckpoint(completion.checkpoint));
  for (const storage::ResultTable& table : storage::ResultTables()) {
    const int total = completion.totals.*table.total;
    if (total < 0 || total > storage::kMaxRowsPerTable) {
      return absl::InvalidArgumentError(absl::StrCat(
          "a completion reports ", total, " ", table.noun, "; a total is at least 0 and at most ",
          storage::kMaxRowsPerTable));
    }
  }
  AttemptEnd end;
  end.key = key;
  end.worker_id = worker_id;
  end.attempt_state = AttemptState::kCompleted;
  end.results = completion.results;
  end.totals = completion.totals;
  end.checkpoint = completion.checkpoint;
  // The kind never changes: read outside the end's transaction.
  ASSIGN_OR_RETURN(storage::JobStatus job, store_->GetJobStatus(key.job_id));
  if (storage::KindInfo(job.kind).reports_verdict) {
    if (!std::isfinite(completion.final_eval_cost)) {
      return absl::InvalidArgumentError(
          "final_eval_cost is not finite; a trial with a non-finite cost must be reported with "
          "Fail");
    }
    end.success = completion.success;
    end.final_eval_cost = completion.final_eval_cost;
  } else {
    // A kind without a verdict (a study) that ran to the end succeeded; its
    // numbers are in its rows, whatever the worker sent.
    end.success = true;
    end.final_eval_cost = storage::kNaN;
  }
  return End(std::move(end)).status();
}

absl::StatusOr<bool> Scheduler::Fail(const std::string& worker_id, const LeaseKey& key,
                                     const std::vector<Episode>& episodes,
                                     const std::string& error) {
  RETURN_IF_ERROR(ValidateEpisodes(episodes));
  AttemptEnd end;
  end.key = key;
  end.worker_id = worker_id;
  end.attempt_state = AttemptState::kFailed;
  end.results.episodes = episodes;
  end.error = error.empty() ? "(no error text given)" : error.substr(0, kMaxErrorBytes);
  RETURN_IF_ERROR(End(std::move(end)).status());
  ASSIGN_OR_RETURN(storage::JobStatus job, store_->GetJobStatus(key.job_id));
  return job.state == JobState::kQueued || job.state == JobState::kRunning;
}

absl::Status Scheduler::Release(const std::string& worker_id, const LeaseKey& key,
                                const std::string& reason) {
  return GiveBack(worker_id, key, absl::StrCat("released: ", reason.substr(0, 1000)),
                  LeaseBudget::kCharge);
}

absl::Status Scheduler::ReturnUndelivered(const std::string& worker_id, const LeaseKey& key,
                                          const std::string& reason) {
  return GiveBack(worker_id, key, absl::StrCat("undelivered: ", reason.substr(0, 1000)),
                  LeaseBudget::kFree);
}

absl::Status Scheduler::GiveBack(const std::string& worker_id, const LeaseKey& key,
                                 std::string error, LeaseBudget budget) {
  AttemptEnd end;
  end.key = key;
  end.worker_id = worker_id;
  // Given back after CANCEL, End's decision records it as cancelled; any
  // other time it is released.
  end.attempt_state = AttemptState::kReleased;
  end.error = std::move(error);
  return End(std::move(end), budget).status();
}

absl::StatusOr<int> Scheduler::ExpireLeases(ExpiryReport* report) {
  absl::MutexLock lock(&decision_mutex_);
  ExpiryReport local;
  if (report == nullptr) report = &local;
  *report = ExpiryReport{};
  const int64_t started = clock_->MonotonicMs();
  const int64_t since_last =
      last_expiry_end_monotonic_ms_ < 0 ? 0 : started - last_expiry_end_monotonic_ms_;
  if (since_last > absl::ToInt64Milliseconds(options_.heartbeat_interval)) {
    // Nothing here ran for longer than a beat, so no worker could have
    // reached us either: their silence is ours. Extend, as after a restart.
    ASSIGN_OR_RETURN(report->extended,
                     store_->ExtendOpenLeases(
                         LeaseExpiryFrom(LeaseNowMs()), clock_->NowMs(),
                         absl::StrCat("after a coordinator stall of ", since_last,
                                      " ms (lease loop not run)")));
    report->stalled_ms = since_last;
    last_expiry_end_monotonic_ms_ = clock_->MonotonicMs();
    return 0;
  }
  const int64_t lease_now = LeaseNowMs();
  ASSIGN_OR_RETURN(std::vector<LeaseKey> expired, store_->ListExpiredLeases(lease_now));
  int count = 0;
  for (const LeaseKey& key : expired) {
    ASSIGN_OR_RETURN(JobRecord job, store_->GetJob(key.job_id));
    AttemptEnd end;
    end.key = key;
    end.worker_id = job.worker_id;
    end.attempt_state = AttemptState::kLeaseLost;
    // Heartbeats run beside this loop: one may have extended the lease since.
    end.only_if_lease_expires_before_ms = lease_now;
    end.error = absl::StrCat("no heartbeat for ", absl::FormatDuration(options_.lease_timeout),
                             " from worker ", job.worker_id);
    ASSIGN_OR_RETURN(EndOutcome outcome, End(std::move(end)));
    if (outcome == EndOutcome::kApplied) ++count;
  }
  last_expiry_end_monotonic_ms_ = clock_->MonotonicMs();
  report->expired = count;
  return count;
}

absl::StatusOr<storage::SweepRecord> Scheduler::SubmitSweep(const storage::NewSweep& sweep,
                                                            bool* created) {
  absl::MutexLock lock(&decision_mutex_);
  ASSIGN_OR_RETURN(storage::SweepRecord record,
                   store_->CreateSweep(sweep, clock_->NowMs(), created));
  if (*created) NotifyWork();
  return record;
}

absl::StatusOr<int> Scheduler::GrowSweep(const storage::NewSweep& grown) {
  absl::MutexLock lock(&decision_mutex_);
  ASSIGN_OR_RETURN(int added, store_->GrowSweep(grown, clock_->NowMs()));
  if (added > 0) NotifyWork();
  return added;
}

absl::StatusOr<storage::ImportResult> Scheduler::ImportSweep(
    const std::optional<storage::NewSweep>& create, const std::string& sweep_name,
    const storage::ImportedJobProducer& jobs, const std::string& source) {
  const storage::ImportedJobProducer checked =
      [&jobs](const std::function<absl::Status(const storage::ImportedJob&)>& each) {
        return jobs([&each](const storage::ImportedJob& job) -> absl::Status {
          RETURN_IF_ERROR(CheckImportedJob(job));
          return each(job);
        });
      };
  absl::MutexLock lock(&decision_mutex_);
  ASSIGN_OR_RETURN(storage::ImportResult result,
                   store_->ImportJobStream(create, sweep_name, checked, source, clock_->NowMs()));
  NotifyWork();
  return result;
}

absl::StatusOr<storage::SweepRecord> Scheduler::SetSweepState(const std::string& name,
                                                              SweepState state) {
  absl::MutexLock lock(&decision_mutex_);
  ASSIGN_OR_RETURN(storage::SweepRecord sweep, store_->GetSweep(name));
  if (sweep.state == state) return sweep;
  if (sweep.state == SweepState::kCancelled && state == SweepState::kPaused) {
    return absl::FailedPreconditionError(absl::StrCat(
        "sweep '", name, "' is cancelled; a cancelled sweep cannot be paused, only resumed"));
  }
  RETURN_IF_ERROR(store_->SetSweepState(name, state, clock_->NowMs()));
  NotifyWork();
  return store_->GetSweep(name);
}

absl::StatusOr<storage::SweepContents> Scheduler::DeleteSweep(
    const std::string& name, const storage::SweepContents& expected) {
  absl::MutexLock lock(&decision_mutex_);
  return store_->DeleteSweep(name, expected, clock_->NowMs());
}

absl::StatusOr<JobRecord> Scheduler::RetryJob(int64_t job_id) {
  absl::MutexLock lock(&decision_mutex_);
  RETURN_IF_ERROR(store_->RetryJob(job_id, clock_->NowMs()));
  NotifyWork();
  return store_->GetJob(job_id);
}

absl::StatusOr<JobRecord> Scheduler::SupersedeJob(int64_t job_id, int64_t by_job_id) {
  absl::MutexLock lock(&decision_mutex_);
  RETURN_IF_ERROR(store_->SupersedeJob(job_id, by_job_id, clock_->NowMs()).status());
  return store_->GetJob(job_id);
}

absl::StatusOr<storage::WorkerRecord> Scheduler::DrainWorker(const std::string& worker_id) {
  absl::MutexLock lock(&decision_mutex_);
  RETURN_IF_ERROR(store_->SetWorkerDraining(worker_id, true, clock_->NowMs()));
  const auto known = instances_.find(worker_id);
  drained_instance_[worker_id] = known != instances_.end() ? known->second.instance : "";
  return store_->GetWorker(worker_id);
}

}  // namespace totalgrad::scheduler
