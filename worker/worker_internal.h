// Private to the worker runtime (worker.cc, worker_final_reports.cc): the
// state of one lease a slot runs, shared by the slot's thread, the heartbeat
// thread and the final report, and the status tests both files make.
#ifndef TOTALGRAD_WORKER_WORKER_INTERNAL_H_
#define TOTALGRAD_WORKER_WORKER_INTERNAL_H_

#include <grpcpp/support/status.h>

#include <atomic>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "totalgrad/v1/worker_service.grpc.pb.h"
#include "worker/worker.h"

namespace totalgrad::worker {
namespace worker_internal {


inline bool IsAuthError(grpc::StatusCode code) {
  return code == grpc::StatusCode::UNAUTHENTICATED || code == grpc::StatusCode::PERMISSION_DENIED;
}

// The lease is gone on the coordinator (lost, ended, or re-queued): whatever
// belongs to it can never be stored.
inline bool IsLeaseGone(grpc::StatusCode code) {
  return code == grpc::StatusCode::ABORTED || code == grpc::StatusCode::NOT_FOUND;
}

inline std::string Describe(const v1::LeaseKey& key) {
  return absl::StrCat("job ", key.job_id(), " attempt ", key.attempt());
}

}  // namespace worker_internal

struct Worker::ActiveLease {
  v1::Lease lease;
  // The fields below are guarded by Worker::mutex_ (not written as
  // ABSL_GUARDED_BY: the annotation can only name a mutex reachable from this
  // struct, and the lock belongs to the Worker that holds the lease).
  std::vector<v1::EpisodeReport> unacked;
  // The trial's latest checkpoint until the coordinator acknowledges it.
  std::optional<v1::TrialCheckpoint> checkpoint;
  bool checkpoint_too_big = false;  // warned once
  bool has_new = false;
  bool beat_in_flight = false;
  int64_t next_beat_ms = 0;
  int64_t backoff_ms = 200;
  std::string cancel_reason;
  std::string failure;
  // Granted while the poll was being cancelled; the trial never ran.
  bool never_started = false;
  // Read by the trial's thread without the lock.
  std::atomic<bool> cancel{false};
  std::atomic<bool> lost{false};
};

}  // namespace totalgrad::worker

#endif  // TOTALGRAD_WORKER_WORKER_INTERNAL_H_
