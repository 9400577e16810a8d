// WorkerService handlers: authorise (worker role), convert, call the
// scheduler, convert back. No SQL and no scheduling policy here.
//
// Threading: handlers run on gRPC's threads; the scheduler is thread-safe.
#ifndef TOTALGRAD_SERVER_SERVICE_WORKER_SERVICE_H_
#define TOTALGRAD_SERVER_SERVICE_WORKER_SERVICE_H_

#include "server/scheduler/scheduler.h"
#include "server/service/auth.h"
#include "totalgrad/v1/worker_service.grpc.pb.h"

namespace totalgrad::service {

class WorkerServiceImpl final : public v1::WorkerService::Service {
 public:
  // Neither is owned; both must outlive the service.
  WorkerServiceImpl(scheduler::Scheduler* scheduler, const TokenAuthenticator* auth)
      : scheduler_(scheduler), auth_(auth) {}

  grpc::Status AcquireLease(grpc::ServerContext* context, const v1::AcquireLeaseRequest* request,
                            v1::AcquireLeaseResponse* response) override;
  grpc::Status Heartbeat(grpc::ServerContext* context, const v1::HeartbeatRequest* request,
                         v1::HeartbeatResponse* response) override;
  grpc::Status Complete(grpc::ServerContext* context, const v1::CompleteRequest* request,
                        v1::CompleteResponse* response) override;
  grpc::Status Fail(grpc::ServerContext* context, const v1::FailRequest* request,
                    v1::FailResponse* response) override;
  grpc::Status Release(grpc::ServerContext* context, const v1::ReleaseRequest* request,
                       v1::ReleaseResponse* response) override;

 private:
  scheduler::Scheduler* const scheduler_;
  const TokenAuthenticator* const auth_;
};

}  // namespace totalgrad::service

#endif  // TOTALGRAD_SERVER_SERVICE_WORKER_SERVICE_H_
