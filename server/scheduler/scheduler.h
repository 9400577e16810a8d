// The scheduler: leases, heartbeats, expiry, re-queueing and attempt budgets,
// over a Store and an injected Clock. It knows nothing of gRPC; the service
// layer converts messages and calls it.
//
// Policy (docs/service.md):
//   * A lease is one attempt of one job; its number is its epoch. A worker
//     keeps it by heartbeating at least every heartbeat_interval; it is lost
//     when no heartbeat arrived for lease_timeout, judged on the coordinator's
//     monotonic clock by ExpireLeases(). A lost lease ends the attempt
//     (lease_lost) and re-queues the job; the old worker's later writes get
//     ABORTED.
//   * Lease times are measured on the monotonic clock (a wall-clock step
//     changes nothing). If ExpireLeases() was not called for longer than a
//     heartbeat interval (the coordinator stalled: SIGSTOP, swapping, a
//     suspended VM), the workers could not have reached it either, so it
//     extends every open lease by one lease timeout, as start-up recovery
//     does, before it expires any.
//   * Application failures (Fail) count against the sweep's max_attempts; lost
//     leases and releases count against max_lost_leases instead. A job over
//     either budget becomes failed.
//   * A cancelled job's running attempt gets DIRECTIVE kCancel; a draining
//     worker gets kDrain and no new leases. Paused sweeps hand out nothing.
//   * A cancel is final unless the user resumes the sweep: a report that
//     arrives after it (even a completion) is stored as data but leaves the
//     job cancelled.
//   * Repeated Complete/Fail/Release of an attempt that already ended that way
//     are OK and change nothing (duplicate delivery).
//
// Threading: every method may be called from any thread. Decisions that read
// then write happen under one mutex, so they cannot interleave; the store
// commits each decision in one transaction before the method returns.
#ifndef TOTALGRAD_SERVER_SCHEDULER_SCHEDULER_H_
#define TOTALGRAD_SERVER_SCHEDULER_SCHEDULER_H_

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"
#include "absl/time/time.h"
#include "server/scheduler/clock.h"
#include "server/scheduler/result_checks.h"
#include "server/storage/store.h"

namespace totalgrad::scheduler {

struct SchedulerOptions {
  // How often workers must beat.
  absl::Duration heartbeat_interval = absl::Seconds(15);
  // A lease with no beat for this long is lost (6 missed beats by default, so
  // a busy network or a long GC pause does not kill live work).
  absl::Duration lease_timeout = absl::Seconds(90);
  // Longest AcquireLease long-poll.
  absl::Duration max_acquire_wait = absl::Seconds(30);
  // A worker's last-seen time is written at most this often per worker.
  absl::Duration worker_touch_interval = absl::Seconds(5);
  // Queued jobs examined per lease request.
  int claim_scan_limit = 256;

  // InvalidArgument naming the bad field (non-positive durations, a lease
  // timeout not above the heartbeat interval).
  absl::Status Validate() const;
};

enum class Directive { kContinue, kCancel, kDrain };

struct Lease {
  storage::JobRecord job;  // job.attempts is the lease's attempt number
  storage::LeaseKey key;
  int64_t heartbeat_interval_ms = 0;
  int64_t lease_timeout_ms = 0;
  // Trial jobs: the latest checkpoint of an earlier attempt, to resume from.
  std::optional<storage::CheckpointRecord> resume_from;
};

// What one ExpireLeases() call did.
struct ExpiryReport {
  int expired = 0;  // leases lost
  // A stall was detected: how long the lease loop had not run, and how many
  // open leases were extended instead of expired.
  int64_t stalled_ms = 0;
  int extended = 0;
};

struct HeartbeatResult {
  Directive directive = Directive::kContinue;
  storage::ResultTotals stored;  // rows stored for the attempt, per table of its kind
};

class Scheduler {
 public:
  // `store` and `clock` are not owned and must outlive the scheduler.
  Scheduler(storage::Store* store, Clock* clock, SchedulerOptions options);
  Scheduler(const Scheduler&) = delete;
  Scheduler& operator=(const Scheduler&) = delete;

  const SchedulerOptions& options() const { return options_; }

  // Start-up recovery: extends every open lease to now + lease_timeout so
  // workers that kept running while the coordinator was down can reattach
  // before anything is re-queued. Returns the number of leases extended.
  absl::StatusOr<int> Recover();

  // ---- worker calls ----

  // Leases the next claimable job to `worker`, or returns nullopt if there is
  // none (or the worker is draining). Study jobs go only to workers whose
  // identity says study_jobs. Does not wait. AlreadyExists if another live
  // process uses the same worker_id: a different `instance` while the current
  // one was heard from within lease_timeout, unless it comes from the same
  // host with `takes_over` (it holds the host-local lock, so the earlier
  // process has exited); an instance once replaced stays refused.
  absl::StatusOr<std::optional<Lease>> TryAcquire(const storage::WorkerIdentity& worker);
  // Like TryAcquire, but waits up to min(wait, max_acquire_wait) of real time
  // for work to appear. Returns nullopt at the deadline or after Shutdown().
  absl::StatusOr<std::optional<Lease>> Acquire(const storage::WorkerIdentity& worker,
                                               absl::Duration wait);
  // Stores `results` (rows of the tables of the job's kind, job_kinds.h),
  // then `checkpoint` if given, and extends the lease; an empty beat only
  // extends it. Aborted for a stale lease; InvalidArgument for rows of a
  // table the job's kind does not own, or a checkpoint over
  // kMaxCheckpointBytes, of a kind without checkpoints or of an episode
  // outside the trial.
  absl::StatusOr<HeartbeatResult> Heartbeat(
      const std::string& worker_id, const storage::LeaseKey& key,
      const storage::JobResults& results,
      const std::optional<storage::Checkpoint>& checkpoint = std::nullopt);
  // Ends the attempt as completed, for every kind: `completion`'s rows and
  // checkpoint are stored first, then the kind's completion check runs
  // (Store::EndAttempt; job_kinds.h). InvalidArgument before anything is
  // stored for a total outside 0..storage::kMaxRowsPerTable, and, for a kind
  // whose verdict is the worker's (trials), a non-finite final_eval_cost (a
  // trial with a non-finite cost must Fail). A kind without a verdict
  // (studies) completes as a success with no cost, whatever the worker sent.
  absl::Status Complete(const std::string& worker_id, const storage::LeaseKey& key,
                        const storage::JobCompletion& completion);
  // Ends the attempt as failed. Returns true if the job was re-queued.
  absl::StatusOr<bool> Fail(const std::string& worker_id, const storage::LeaseKey& key,
                            const std::vector<storage::Episode>& episodes,
                            const std::string& error);
  // Ends the attempt as released (or cancelled, if the job was cancelled).
  absl::Status Release(const std::string& worker_id, const storage::LeaseKey& key,
                       const std::string& reason);
  // Ends an attempt whose lease never reached the worker (the AcquireLease
  // call was cancelled while the grant was committed): recorded as released
  // with `reason`, and the job re-queued without charging its lost-lease
  // budget, since no worker ever held it.
  absl::Status ReturnUndelivered(const std::string& worker_id, const storage::LeaseKey& key,
                                 const std::string& reason);

  // Ends every lease that expired on the coordinator's monotonic clock and
  // returns how many. Meant to be called in a loop well within
  // heartbeat_interval; if the previous call ended more than a heartbeat
  // interval ago (a stall), it instead extends every open lease to now +
  // lease_timeout and expires nothing this time. `report`, if not null,
  // receives the details.
  absl::StatusOr<int> ExpireLeases(ExpiryReport* report = nullptr);

  // ---- user calls ----

  absl::StatusOr<storage::SweepRecord> SubmitSweep(const storage::NewSweep& sweep, bool* created);
  // Store::GrowSweep, then wakes waiting workers.
  absl::StatusOr<int> GrowSweep(const storage::NewSweep& grown);
  // Store::ImportJobStream with CheckImportedJob (the values Complete would
  // check) on each job before the store takes it (the rows), then wakes
  // waiting workers (a created sweep has queued jobs).
  absl::StatusOr<storage::ImportResult> ImportSweep(const std::optional<storage::NewSweep>& create,
                                                    const std::string& sweep_name,
                                                    const storage::ImportedJobProducer& jobs,
                                                    const std::string& source);
  absl::StatusOr<storage::ImportResult> ImportSweep(const std::optional<storage::NewSweep>& create,
                                                    const std::string& sweep_name,
                                                    const std::vector<storage::ImportedJob>& jobs,
                                                    const std::string& source) {
    return ImportSweep(create, sweep_name, storage::ProduceEach(jobs), source);
  }
  // Pause/resume/cancel with the transition rules of the proto: no-op when
  // already there; cancelling cancels queued and running jobs; resuming a
  // cancelled sweep (the only way out of a cancel) re-queues its cancelled
  // jobs (those whose attempt is still open run on); pausing a cancelled
  // sweep is FailedPrecondition.
  absl::StatusOr<storage::SweepRecord> SetSweepState(const std::string& name,
                                                     storage::SweepState state);
  // Deletes a sweep (Store::DeleteSweep) under the decision lock, so no lease
  // of it can be granted meanwhile.
  absl::StatusOr<storage::SweepContents> DeleteSweep(const std::string& name,
                                                     const storage::SweepContents& expected);
  absl::StatusOr<storage::JobRecord> RetryJob(int64_t job_id);
  // storage::Store::SupersedeJob; the job as it is then.
  absl::StatusOr<storage::JobRecord> SupersedeJob(int64_t job_id, int64_t by_job_id);
  absl::StatusOr<storage::WorkerRecord> DrainWorker(const std::string& worker_id);

  // Wakes every waiting Acquire; later Acquire calls return nullopt at once.
  void Shutdown();
  bool shut_down() const;

 private:
  // The lease clock: the monotonic clock shifted to read as wall time at
  // construction, so stored lease deadlines stay readable but never move
  // with a wall-clock step. Restarts are covered by Recover().
  int64_t LeaseNowMs();
  int64_t LeaseExpiryFrom(int64_t lease_now_ms) const;
  // The duplicate-worker-id rule of TryAcquire; records the instance.
  absl::Status CheckInstanceLocked(const storage::WorkerIdentity& worker)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(decision_mutex_);
  // Whether the worker's last-seen time is due to be written (it was not
  // written within worker_touch_interval); if so, records `now_ms` as written.
  bool TouchDueLocked(const std::string& worker_id, int64_t now_ms)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(decision_mutex_);
  // The checkpoint a new attempt of job `job_id` resumes from: the furthest
  // (highest episode, then attempt) written by `worker_build`, since a worker
  // resumes only its own build's (results stay one build's); when there is
  // none of that build, the furthest of any (the worker says why it starts
  // over). nullopt: the job has no checkpoint.
  absl::StatusOr<std::optional<storage::CheckpointRecord>> ResumePoint(
      int64_t job_id, const std::string& worker_build);
  // Whether a worker whose row says draining stays drained (the drain was
  // meant for this process); undrains a new process under a drained id.
  absl::StatusOr<bool> StaysDrainedLocked(const storage::WorkerIdentity& worker)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(decision_mutex_);
  // Whether a released or lost lease counts against the job's max_lost_leases.
  enum class LeaseBudget { kCharge, kFree };
  // Ends the attempt with the job's next state decided by the budgets, in
  // the end's own transaction (AttemptEnd::decide).
  absl::StatusOr<storage::EndOutcome> End(storage::AttemptEnd end,
                                          LeaseBudget budget = LeaseBudget::kCharge);
  // Release and ReturnUndelivered: ends the attempt as released (cancelled
  // if the job was cancelled) with `error` recorded.
  absl::Status GiveBack(const std::string& worker_id, const storage::LeaseKey& key,
                        std::string error, LeaseBudget budget);
  // Counts a change that may make a job claimable and wakes waiters.
  void NotifyWork() ABSL_LOCKS_EXCLUDED(work_mutex_);

  storage::Store* const store_;
  Clock* const clock_;
  const SchedulerOptions options_;

  const int64_t lease_origin_wall_ms_;
  const int64_t lease_origin_monotonic_ms_;

  // Serialises the read-decide-write sequences of sweep and worker
  // administration and the lease expiry loop, and guards the in-memory
  // worker maps. Leases, heartbeats and the ends of attempts decide inside
  // their own store transactions (ClaimJob, fenced writes, AttemptEnd::decide)
  // and take it only for those maps, never across a store write, so that
  // many workers' writes share commits (group commit).
  absl::Mutex decision_mutex_;
  std::map<std::string, int64_t> last_touch_ms_ ABSL_GUARDED_BY(decision_mutex_);
  // The live process behind each worker id (in memory: after a restart the
  // first caller is accepted).
  struct WorkerInstance {
    std::string instance;
    std::string host;
    int64_t last_heard_monotonic_ms = 0;
    std::vector<std::string> replaced;  // earlier instances, newest last (at most 16)
  };
  std::map<std::string, WorkerInstance> instances_ ABSL_GUARDED_BY(decision_mutex_);
  // The process a drain was meant for, by worker id: its instance when the
  // drain was asked ("" when none had been heard from: then the next one to
  // ask for work). A drain stops that process; another process with the id
  // (the drained one exited, or this coordinator restarted since: a draining
  // process never asks for work) is undrained when it asks (StaysDrainedLocked).
  std::map<std::string, std::string> drained_instance_ ABSL_GUARDED_BY(decision_mutex_);
  // Monotonic time at which the last ExpireLeases() (or Recover()) ended; -1
  // before the first.
  int64_t last_expiry_end_monotonic_ms_ ABSL_GUARDED_BY(decision_mutex_) = -1;

  // Long-poll wake-ups: Acquire awaits a change of these (absl::Mutex
  // re-evaluates the condition whenever work_mutex_ is released).
  mutable absl::Mutex work_mutex_;
  uint64_t work_generation_ ABSL_GUARDED_BY(work_mutex_) = 0;
  bool shutdown_ ABSL_GUARDED_BY(work_mutex_) = false;
};

}  // namespace totalgrad::scheduler

#endif  // TOTALGRAD_SERVER_SCHEDULER_SCHEDULER_H_
