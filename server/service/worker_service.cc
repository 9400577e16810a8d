#include "server/service/worker_service.h"

#include <algorithm>
#include <chrono>

#include <spdlog/spdlog.h>

#include "absl/strings/str_cat.h"

#include "server/service/convert.h"

namespace totalgrad::service {

#define TG_AUTHORIZE(context)                                           \
  do {                                                                  \
    const absl::Status auth_status = auth_->Check(*(context), Role::kWorker); \
    if (!auth_status.ok()) return ToGrpcStatus(auth_status);            \
  } while (0)

grpc::Status WorkerServiceImpl::AcquireLease(grpc::ServerContext* context,
                                             const v1::AcquireLeaseRequest* request,
                                             v1::AcquireLeaseResponse* response) {
  TG_AUTHORIZE(context);
  if (request->wait_ms() < 0) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "wait_ms must be >= 0");
  }
  absl::Duration wait = absl::Milliseconds(request->wait_ms());
  // Answer (empty) before the caller's deadline, so an idle poll is not an error.
  const auto deadline = context->deadline();
  if (deadline != std::chrono::system_clock::time_point::max()) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
        deadline - std::chrono::system_clock::now());
    wait = std::min(wait, absl::Milliseconds(std::max<int64_t>(0, left.count() - 500)));
  }
  absl::StatusOr<std::optional<scheduler::Lease>> lease =
      scheduler_->Acquire(FromProto(request->worker()), wait);
  if (!lease.ok()) return ToGrpcStatus(lease.status());
  if (lease->has_value() && context->IsCancelled()) {
    // The caller gave up on the poll (e.g. a draining worker cancelled it)
    // while the grant was being committed: it will never see this lease, so
    // hand the job back now instead of leaving it running until the lease
    // expires. Neither a failure nor a lost lease: no worker ever held it.
    const absl::Status released = scheduler_->ReturnUndelivered(
        request->worker().worker_id(), (**lease).key,
        "the AcquireLease call was cancelled before the lease reached the worker");
    if (!released.ok()) {
      spdlog::warn("job {} attempt {}: releasing the lease of a cancelled AcquireLease failed: {}",
                   (**lease).key.job_id, (**lease).key.attempt, released.ToString());
    }
    return grpc::Status(grpc::StatusCode::CANCELLED, "call cancelled; the lease was released");
  }
  response->set_granted(lease->has_value());
  if (lease->has_value()) ToProto(**lease, response->mutable_lease());
  return grpc::Status::OK;
}

grpc::Status WorkerServiceImpl::Heartbeat(grpc::ServerContext* context,
                                          const v1::HeartbeatRequest* request,
                                          v1::HeartbeatResponse* response) {
  TG_AUTHORIZE(context);
  absl::StatusOr<scheduler::HeartbeatResult> result = scheduler_->Heartbeat(
      request->worker_id(), FromProto(request->lease()), ResultsFromProto(*request),
      CheckpointFromProto(request->has_checkpoint(), request->checkpoint()));
  if (!result.ok()) return ToGrpcStatus(result.status());
  response->set_directive(ToProto(result->directive));
  response->set_episodes_stored(result->stored.episodes);
  response->set_study_rows_stored(result->stored.study_cells + result->stored.study_references);
  return grpc::Status::OK;
}

grpc::Status WorkerServiceImpl::Complete(grpc::ServerContext* context,
                                         const v1::CompleteRequest* request,
                                         v1::CompleteResponse* response) {
  TG_AUTHORIZE(context);
  // One path for every kind: the job's kind decides what the completion
  // must carry (server/storage/job_kinds.h).
  return ToGrpcStatus(scheduler_->Complete(request->worker_id(), FromProto(request->lease()),
                                           CompletionFromProto(*request)));
}

grpc::Status WorkerServiceImpl::Fail(grpc::ServerContext* context, const v1::FailRequest* request,
                                     v1::FailResponse* response) {
  TG_AUTHORIZE(context);
  absl::StatusOr<bool> requeued = scheduler_->Fail(
      request->worker_id(), FromProto(request->lease()), FromProto(request->episodes()),
      request->error());
  if (!requeued.ok()) return ToGrpcStatus(requeued.status());
  response->set_requeued(*requeued);
  return grpc::Status::OK;
}

grpc::Status WorkerServiceImpl::Release(grpc::ServerContext* context,
                                        const v1::ReleaseRequest* request,
                                        v1::ReleaseResponse* response) {
  TG_AUTHORIZE(context);
  if (request->never_started()) {
    return ToGrpcStatus(scheduler_->ReturnUndelivered(
        request->worker_id(), FromProto(request->lease()),
        absl::StrCat("given back unstarted: ", request->reason())));
  }
  return ToGrpcStatus(
      scheduler_->Release(request->worker_id(), FromProto(request->lease()), request->reason()));
}

#undef TG_AUTHORIZE

}  // namespace totalgrad::service
