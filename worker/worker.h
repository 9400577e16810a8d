// The worker runtime: pulls leases from the coordinator, runs one job per
// slot through the runner of its kind (job_runner.h), streams each finished
// episode, heartbeats on its own thread, and reports the end of every
// attempt.
//
// Every kind takes the same path. Rows a runner streams (episodes) are sent
// as they come, with the checkpoint that follows each; rows a runner returns
// at the end (a study's cells and references) are sent when the job ends, in
// heartbeats of bounded size (repeats are harmless: rows are keyed by
// index). Then one Complete carries the per-table totals and the verdict;
// the coordinator's job kind (server/storage/job_kinds.h) decides which of
// them count. A worker runs only the kinds it has a runner for (it tells the
// coordinator whether it takes study jobs). A job that fails is reported
// with Fail and its error; cancellation and drain stop it (a study between
// cells) and release the job.
//
// Guarantees:
//   * Episodes are sent as soon as they finish and kept until the coordinator
//     acknowledges them; after a disconnect they are replayed (the store
//     ignores repeats), so a coordinator restart loses nothing. The trial's
//     checkpoint after each episode goes with it (only the latest is kept).
//   * A lease that carries an earlier attempt's checkpoint written by this
//     same build resumes the trial from it (JobInput::resume_from); one of
//     another build, or one the runner cannot use, is ignored with a log
//     line and the trial starts over, so results stay those of one build.
//   * A lease the coordinator refuses (ABORTED: lost, re-queued) is dropped:
//     the trial is stopped and nothing more is sent for it.
//   * A trial that returns an error, throws, or reports a non-finite cost is
//     reported with Fail and the reason.
//   * Drain(): no new leases; running trials may finish for drain_timeout,
//     then are stopped and released. Final reports get report_grace more;
//     what is still undelivered then (the coordinator is unreachable) is kept
//     in the spool (state_dir, worker/spool.h) instead of blocking, so
//     shutdown takes at most drain_timeout + report_grace plus the time a
//     trial needs to notice its cancellation (main.cc bounds that too).
//     Stop(): stop at once; SpoolUnfinished() then keeps what is left.
//   * The next worker with the same id on the same host replays the spool
//     when it starts: results of leases the coordinator still holds are
//     stored; those of an ended lease are refused (ABORTED) and dropped with
//     a log line (the job re-runs).
//   * With a spool, every lease is marked held in it when its trial starts
//     (a release, "held by an earlier process"), and the mark is removed
//     once the attempt's end reached the coordinator. A process killed
//     outright (kill -9, the machine rebooted) thus leaves its leases in the
//     spool, and its successor with the same id releases them at start
//     instead of leaving them to expire after lease_timeout: the jobs are
//     re-queued at once and resume from their stored checkpoints.
//   * An auth error (UNAUTHENTICATED, PERMISSION_DENIED) or a worker id in
//     use by another live process (ALREADY_EXISTS from AcquireLease, or the
//     host-local lock) stops the worker at once, with results spooled, and
//     Run() says why (WorkerSummary::exit): retrying cannot help.
//
// Time: every interval and deadline above (heartbeats, drain_timeout,
// report_grace, max_idle, backoff between polls) is measured on the injected
// Clock's monotonic clock, so tests can move time instead of sleeping; gRPC
// call deadlines (acquire_wait, call_timeout) and the retries of final
// reports (rpc::CallWithRetry) stay on real time.
//
// Files: worker.cc leases, runs and heartbeats; worker_final_reports.cc ends
// an attempt (final reports, their delivery, the spool and its replay).
//
// Threading: Run() blocks on the calling thread and owns one thread per slot,
// the heartbeat thread and the drain-deadline thread. Drain(), Stop() and SpoolUnfinished() may be
// called from any thread.
#ifndef TOTALGRAD_WORKER_WORKER_H_
#define TOTALGRAD_WORKER_WORKER_H_

#include <grpcpp/channel.h>

#include <atomic>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/synchronization/mutex.h"
#include "absl/time/time.h"
#include "runtime/clock.h"
#include "runtime/rpc_client.h"
#include "totalgrad/v1/worker_service.grpc.pb.h"
#include "totalgrad/v1/worker_spool.pb.h"
#include "worker/spool.h"
#include "worker/job_runner.h"

namespace totalgrad::worker {

struct WorkerOptions {
  std::string worker_id;  // default in main: "<host>-<pid>"
  std::string host;
  std::string build;
  int slots = 1;
  // Bearer token sent with every call.
  std::string token;
  // Long-poll length of one AcquireLease.
  absl::Duration acquire_wait = absl::Seconds(20);
  // Deadline of each heartbeat / report call.
  absl::Duration call_timeout = absl::Seconds(15);
  // After Drain(), running trials get this long to finish before release.
  absl::Duration drain_timeout = absl::Seconds(60);
  // After the drain timeout, final reports get this much longer to be
  // delivered; then they are spooled (or, without a state_dir, dropped).
  absl::Duration report_grace = absl::Seconds(5);
  // Outside a drain, a final report (Complete/Fail/Release) is retried this
  // long, e.g. while the coordinator restarts; then it is spooled.
  absl::Duration orphan_timeout = absl::Minutes(30);
  // Directory for the host-local worker-id lock and the spool (worker/spool.h).
  // Empty: neither (undeliverable results are dropped with a log line).
  std::string state_dir;
  // Unique per process, sent as WorkerIdentity.instance. Empty: a random one.
  std::string instance;
  // While the coordinator says another live process uses this worker id
  // (ALREADY_EXISTS), keep asking this long before giving up with
  // WorkerExit::kWorkerIdInUse: a process that crashed without a state_dir
  // lock to prove it is gone counts as alive until its silence exceeds the
  // coordinator's lease timeout (90 s by default).
  absl::Duration worker_id_wait = absl::Seconds(120);
  // Exit when no lease was granted for this long (InfiniteDuration: never);
  // time without any answer from the coordinator counts too.
  absl::Duration max_idle = absl::InfiniteDuration();
  // Exit (WorkerExit::kCoordinatorUnreachable) when the coordinator has not
  // answered a lease request for this long while no trial runs: a batch job
  // must not spend its allocation waiting for a coordinator that is gone.
  absl::Duration max_unreachable = absl::Minutes(10);
  // How long this worker may run from its construction (a batch
  // allocation's time left; InfiniteDuration: no limit). A granted job whose
  // cost-model estimate (JobRunner::EstimateCpuSeconds x speed_factor) is
  // more than the time left is given back unstarted (its lease budget is not
  // charged) and the worker drains: it would not finish in time.
  absl::Duration walltime = absl::InfiniteDuration();
  // This machine's seconds per cost-model second (1: as fast as the cost
  // model's reference machine, one core per trial; 2: half as fast).
  double speed_factor = 1.0;
};

// Why Run() returned.
enum class WorkerExit {
  kDone,           // drained, stopped or idle for max_idle
  kAuthRefused,    // the coordinator refused the token (UNAUTHENTICATED/PERMISSION_DENIED)
  kWorkerIdInUse,  // another live process uses this worker id (here or on another host)
  kCoordinatorUnreachable,  // no answer for max_unreachable (or max_idle)
};

// Checkpoints larger than this are not sent (the coordinator refuses them:
// scheduler::kMaxCheckpointBytes, checked equal in worker_test).
inline constexpr size_t kMaxCheckpointBytes = 2 << 20;

// Process exit codes of totalgrad-worker (main.cc), distinct so that a
// supervisor does not restart a worker that cannot succeed (sysexits.h).
inline constexpr int kExitAuthRefused = 77;   // EX_NOPERM
inline constexpr int kExitWorkerIdInUse = 78;  // EX_CONFIG
inline constexpr int kExitCoordinatorUnreachable = 69;  // EX_UNAVAILABLE

struct WorkerSummary {
  int resumed = 0;    // trials resumed from an earlier attempt's checkpoint
  int completed = 0;  // Complete acknowledged
  int failed = 0;     // Fail acknowledged
  int released = 0;   // Release acknowledged
  int dropped = 0;    // refused by the coordinator (the lease had ended) or given up
  int spooled = 0;    // kept in the spool for the next worker with this id
  int replayed = 0;   // spooled attempts of an earlier process delivered at start
  WorkerExit exit = WorkerExit::kDone;
  std::string exit_message;  // the error behind a non-kDone exit
};

// The runner of each job kind a worker runs (a kind without one, or with
// null, is not run: e.g. trial jobs only).
using JobRunners = std::map<v1::JobKind, JobRunner*>;

class Worker {
 public:
  // The runners and `clock` are not owned and must outlive the worker.
  // Without a clock it uses the system clock.
  Worker(WorkerOptions options, std::shared_ptr<grpc::Channel> channel, JobRunners runners,
         Clock* clock = nullptr);
  ~Worker();
  Worker(const Worker&) = delete;
  Worker& operator=(const Worker&) = delete;

  // Replays the spool of an earlier process with this id, then works until
  // drained, stopped, idle for max_idle, or a fatal error (summary.exit).
  WorkerSummary Run() ABSL_LOCKS_EXCLUDED(mutex_);
  void Drain() ABSL_LOCKS_EXCLUDED(mutex_);
  // Stops at once: trials are cancelled and calls in flight cut short.
  void Stop() ABSL_LOCKS_EXCLUDED(mutex_);
  // Writes every attempt this worker still holds (running trials, final
  // reports not yet acknowledged) to the spool, each with its unacknowledged
  // episodes and its final report (a release for running trials). Returns how
  // many; 0 without a state_dir. For a process that must exit now (a second
  // SIGTERM): call after Stop(), then exit.
  int SpoolUnfinished() ABSL_LOCKS_EXCLUDED(mutex_);

 private:
  struct ActiveLease;
  class Progress;
  // The outcome of delivering one spooled attempt (a final report).
  struct Delivery {
    grpc::Status status;
    enum class Kind { kComplete, kFail, kRelease } kind = Kind::kRelease;
    std::string failure;  // set when a refused completion became a Fail
  };

  void SlotLoop(int slot) ABSL_LOCKS_EXCLUDED(mutex_);
  // Why `lease` cannot finish within options_.walltime (its estimate and
  // the time left, for the log); nullopt if it can or nothing is known.
  std::optional<std::string> OutlastsWalltime(const v1::Lease& lease);
  // Runs the job of `lease` and reports how it ended.
  void RunLease(const v1::Lease& lease) ABSL_LOCKS_EXCLUDED(mutex_);
  void HeartbeatLoop() ABSL_LOCKS_EXCLUDED(mutex_);
  // After Drain(): cancels running trials at the drain deadline and gives
  // up on undelivered final reports at drain deadline + report_grace.
  void DeadlineLoop() ABSL_LOCKS_EXCLUDED(mutex_);
  // Sends one heartbeat for `active`; updates its unacknowledged episodes.
  void Beat(const std::shared_ptr<ActiveLease>& active) ABSL_LOCKS_EXCLUDED(mutex_);
  // Sends the final report of an attempt (first the rows `result` returned,
  // if any), retrying while it makes sense, and spools it if it cannot be
  // delivered in time.
  void Finish(const std::shared_ptr<ActiveLease>& active, const absl::StatusOr<JobOutcome>& result)
      ABSL_LOCKS_EXCLUDED(mutex_);
  // What Finish takes from an attempt that ended (copied under mutex_).
  struct EndedAttempt {
    std::string failure;  // set: the attempt is reported with Fail
    std::string cancel_reason;
    bool never_started = false;
    std::vector<v1::EpisodeReport> unacked;
    std::optional<v1::TrialCheckpoint> checkpoint;
  };
  // The final report of an attempt that ended with `result`: Fail when
  // `ended.failure` is set, Release when the job stopped without a result,
  // else Complete with the unacknowledged rows and the checkpoint in it.
  v1::SpooledAttempt FinalReport(const v1::LeaseKey& key, const absl::StatusOr<JobOutcome>& result,
                                 const EndedAttempt& ended) const;
  // Counts (and logs) how the delivery of `entry`, the final report of
  // `key`, ended: delivered, dropped, or spooled when it could not be sent.
  void CountFinalReport(const v1::LeaseKey& key, const absl::StatusOr<JobOutcome>& result,
                        const EndedAttempt& ended, const Delivery& delivery,
                        const v1::SpooledAttempt& entry) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mutex_);
  // Sends `attempt`: its pending heartbeat, then its final report. A refused
  // completion (INVALID_ARGUMENT/FAILED_PRECONDITION) becomes a Fail with
  // the reason. Calls go through `registry` and stop when it is cancelled.
  Delivery Deliver(const v1::SpooledAttempt& attempt, const rpc::RetryPolicy& policy,
                   rpc::CallRegistry* registry);
  // Replays the spool of an earlier process at start.
  void ReplaySpool() ABSL_LOCKS_EXCLUDED(mutex_);
  // How final reports are retried now (bounded by the drain deadline).
  rpc::RetryPolicy FinalReportPolicy() const ABSL_LOCKS_EXCLUDED(mutex_);
  // Sends the rows a job returned at its end in heartbeats of bounded size.
  grpc::Status SendReturnedRows(const v1::LeaseKey& key, const JobOutcome& outcome,
                                const rpc::RetryPolicy& policy);
  void CancelAll(const std::string& reason) ABSL_LOCKS_EXCLUDED(mutex_);
  // Ends the worker at once for a reason retrying cannot fix.
  void FailFatally(WorkerExit exit, const std::string& message) ABSL_LOCKS_EXCLUDED(mutex_);
  // Fills the identity fields of `identity`.
  void FillIdentity(v1::WorkerIdentity* identity) const;
  // An attempt as a spool entry: `unacked` (and `checkpoint`, if any) as
  // its pending heartbeat.
  v1::SpooledAttempt SpoolEntry(const v1::LeaseKey& key,
                                const std::vector<v1::EpisodeReport>& unacked,
                                const std::optional<v1::TrialCheckpoint>& checkpoint = {}) const;
  // Keeps `entry` in the spool; false (and a log line) without one.
  bool KeepInSpool(const v1::SpooledAttempt& entry, const std::string& why);
  // Marks `key` held in the spool (a release for the next process with this
  // id, should this one die without reporting it), and forgets the mark once
  // the attempt's end was delivered or refused. No-ops without a spool;
  // a failed write is logged and the lease kept (it then expires as before).
  void MarkHeldInSpool(const v1::LeaseKey& key);
  void ForgetHeldInSpool(const v1::LeaseKey& key);

  const WorkerOptions options_;
  std::unique_ptr<v1::WorkerService::Stub> stub_;
  const JobRunners runners_;
  // End of options_.walltime on clock_ (ms); -1: none.
  int64_t walltime_end_ms_ = -1;
  const std::unique_ptr<SystemClock> own_clock_;  // set when no clock was given
  Clock* const clock_;

  // Null without a state_dir (or if it is unusable). Set once at the start
  // of Run() under mutex_; SpoolUnfinished reads it under mutex_.
  std::unique_ptr<Spool> spool_;

  std::atomic<bool> draining_{false};
  std::atomic<bool> stopping_{false};   // hard stop: release at once
  std::atomic<bool> finished_{false};   // all slots done; heartbeat thread exits
  // Final reports are no longer worth waiting for (drain deadline +
  // report_grace passed, Stop(), a fatal error): undelivered ones are spooled.
  std::atomic<bool> give_up_{false};
  rpc::CallRegistry calls_;         // heartbeats and final reports in flight
  rpc::CallRegistry replay_calls_;  // spool replay at start (cancelled by Drain)

  // Waits (new episodes, leases ending, drain, stop) are Mutex::Await or
  // clock_->AwaitUntil on conditions over the state below: absl::Mutex
  // re-evaluates them whenever the mutex is released, so a change made
  // under mutex_ needs no separate notification.
  mutable absl::Mutex mutex_;
  std::map<int64_t, std::shared_ptr<ActiveLease>> active_ ABSL_GUARDED_BY(mutex_);  // by job id
  std::vector<grpc::ClientContext*> acquiring_ ABSL_GUARDED_BY(mutex_);  // in-flight polls
  int64_t drain_started_ms_ ABSL_GUARDED_BY(mutex_) = 0;  // on clock_->MonotonicMs()
  int64_t id_refused_since_ms_ ABSL_GUARDED_BY(mutex_) = -1;  // first ALREADY_EXISTS in a row
  // Bumped when the heartbeat thread must re-plan (a new lease, a drain).
  uint64_t heartbeat_generation_ ABSL_GUARDED_BY(mutex_) = 0;
  // Final reports being delivered, by job id, as they would be spooled.
  std::map<int64_t, v1::SpooledAttempt> finishing_ ABSL_GUARDED_BY(mutex_);
  WorkerSummary summary_ ABSL_GUARDED_BY(mutex_);
};

}  // namespace totalgrad::worker

#endif  // TOTALGRAD_WORKER_WORKER_H_
