// The worker runtime: pulls leases from the coordinator, runs one trial (or
// study job) per slot, streams each finished episode, heartbeats on its own
// thread, and reports the end of every attempt.
//
// Study jobs (JOB_KIND_STUDY) run through the StudyRunner, if one is given
// (the worker then tells the coordinator it takes study jobs). Their rows
// are sent when the study ends, in heartbeats of bounded size (repeats are
// harmless: rows are keyed by index), then Complete names the totals. A
// study that fails is reported with Fail and its error; cancellation and
// drain stop it between cells and release the job, as for trials.
//
// Guarantees:
//   * Episodes are sent as soon as they finish and kept until the coordinator
//     acknowledges them; after a disconnect they are replayed (the store
//     ignores repeats), so a coordinator restart loses nothing.
//   * A lease the coordinator refuses (ABORTED: lost, re-queued) is dropped:
//     the trial is stopped and nothing more is sent for it.
//   * A trial that returns an error, throws, or reports a non-finite cost is
//     reported with Fail and the reason.
//   * Drain(): no new leases; running trials may finish for drain_timeout,
//     then are stopped and released. Stop(): stop and release at once.
//
// Threading: Run() blocks on the calling thread and owns one thread per slot
// plus the heartbeat thread. Drain() and Stop() may be called from any thread.
#ifndef TOTALGRAD_WORKER_WORKER_H_
#define TOTALGRAD_WORKER_WORKER_H_

#include <grpcpp/channel.h>

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "absl/time/time.h"
#include "server/common/rpc_client.h"
#include "totalgrad/v1/worker_service.grpc.pb.h"
#include "worker/study_runner.h"
#include "worker/trial_runner.h"

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
  // A final report (Complete/Fail/Release) is retried this long, e.g. while
  // the coordinator restarts; then the result is given up.
  absl::Duration orphan_timeout = absl::Minutes(30);
  // Exit when no lease was granted for this long (InfiniteDuration: never).
  absl::Duration max_idle = absl::InfiniteDuration();
};

struct WorkerSummary {
  int completed = 0;  // Complete acknowledged
  int failed = 0;     // Fail acknowledged
  int released = 0;   // Release acknowledged
  int dropped = 0;    // refused by the coordinator (stale lease) or given up
};

class Worker {
 public:
  // `runner` and `study_runner` are not owned and must outlive the worker.
  // Without a study runner the worker takes trial jobs only.
  Worker(WorkerOptions options, std::shared_ptr<grpc::Channel> channel, TrialRunner* runner,
         StudyRunner* study_runner = nullptr);
  ~Worker();
  Worker(const Worker&) = delete;
  Worker& operator=(const Worker&) = delete;

  // Works until drained, stopped, or idle for max_idle.
  WorkerSummary Run();
  void Drain();
  void Stop();

 private:
  struct ActiveLease;
  class Progress;

  void SlotLoop(int slot);
  // Runs the trial of `lease` and reports how it ended.
  void RunLease(const v1::Lease& lease);
  void HeartbeatLoop();
  // Sends one heartbeat for `active`; updates its unacknowledged episodes.
  void Beat(const std::shared_ptr<ActiveLease>& active);
  // Sends the final report of an attempt, retrying while it makes sense.
  // `study` holds a finished study job's rows (null for trials).
  void Finish(const std::shared_ptr<ActiveLease>& active, const absl::StatusOr<TrialOutcome>& result,
              const StudyOutcome* study = nullptr);
  // Sends a finished study's rows in heartbeats of bounded size.
  grpc::Status SendStudyRows(const v1::LeaseKey& key, const StudyOutcome& study,
                             const rpc::RetryPolicy& policy);
  void CancelAll(const std::string& reason);

  const WorkerOptions options_;
  std::unique_ptr<v1::WorkerService::Stub> stub_;
  TrialRunner* const runner_;
  StudyRunner* const study_runner_;

  std::atomic<bool> draining_{false};
  std::atomic<bool> stopping_{false};   // hard stop: release at once
  std::atomic<bool> finished_{false};   // all slots done; heartbeat thread exits

  std::mutex mutex_;
  std::condition_variable changed_;  // new episodes, leases ending, drain, stop
  std::map<int64_t, std::shared_ptr<ActiveLease>> active_;  // by job id; guarded by mutex_
  std::vector<grpc::ClientContext*> acquiring_;             // in-flight polls; guarded by mutex_
  int64_t drain_started_ms_ = 0;                            // guarded by mutex_
  WorkerSummary summary_;                                   // guarded by mutex_
};

}  // namespace totalgrad::worker

#endif  // TOTALGRAD_WORKER_WORKER_H_
