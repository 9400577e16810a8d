// ControlService handlers (user role): sweeps, jobs, results, export,
// workers, health, backup. Each handler authorises, converts, makes one call
// into the scheduler (writes) or the store (reads) and converts back.
//
// Threading: handlers run on gRPC's threads; scheduler and store are thread-safe.
#ifndef TOTALGRAD_SERVER_SERVICE_CONTROL_SERVICE_H_
#define TOTALGRAD_SERVER_SERVICE_CONTROL_SERVICE_H_

#include <functional>
#include <atomic>
#include <string>

#include "server/scheduler/clock.h"
#include "server/scheduler/scheduler.h"
#include "server/service/auth.h"
#include "server/service/submission.h"
#include "server/storage/store.h"
#include "totalgrad/v1/control_service.grpc.pb.h"

namespace totalgrad::service {

struct ControlServiceOptions {
  std::string build;         // the coordinator's BuildId()
  std::string database;      // path of the SQLite file (shown by Health)
  std::string backup_dir;    // empty: Backup RPC refused
};

class ControlServiceImpl final : public v1::ControlService::Service {
 public:
  // None owned; all must outlive the service.
  ControlServiceImpl(scheduler::Scheduler* scheduler, storage::Store* store,
                     scheduler::Clock* clock, const TokenAuthenticator* auth,
                     ControlServiceOptions options)
      : scheduler_(scheduler), store_(store), clock_(clock), auth_(auth),
        options_(std::move(options)) {}

  // Health reports serving = false until this is called (after recovery).
  void SetServing(bool serving) { serving_ = serving; }
  // What Health reports as serving: `check` (the coordinator's /healthz
  // check: serving, scheduler up, database writable) instead of the serving
  // flag alone. Set before the server starts.
  void SetHealthCheck(std::function<absl::Status()> check) { health_check_ = std::move(check); }

  grpc::Status SubmitSweep(grpc::ServerContext* context, const v1::SubmitSweepRequest* request,
                           v1::SubmitSweepResponse* response) override;
  grpc::Status ListSweeps(grpc::ServerContext* context, const v1::ListSweepsRequest* request,
                          v1::ListSweepsResponse* response) override;
  grpc::Status GetSweep(grpc::ServerContext* context, const v1::SweepRequest* request,
                        v1::SweepInfo* response) override;
  grpc::Status CancelSweep(grpc::ServerContext* context, const v1::SweepRequest* request,
                           v1::SweepInfo* response) override;
  grpc::Status PauseSweep(grpc::ServerContext* context, const v1::SweepRequest* request,
                          v1::SweepInfo* response) override;
  grpc::Status ResumeSweep(grpc::ServerContext* context, const v1::SweepRequest* request,
                           v1::SweepInfo* response) override;
  grpc::Status DeleteSweep(grpc::ServerContext* context, const v1::DeleteSweepRequest* request,
                           v1::DeleteSweepResponse* response) override;
  grpc::Status PruneSweep(grpc::ServerContext* context, const v1::PruneSweepRequest* request,
                          v1::PruneSweepResponse* response) override;
  grpc::Status ListJobs(grpc::ServerContext* context, const v1::ListJobsRequest* request,
                        v1::ListJobsResponse* response) override;
  grpc::Status RetryJob(grpc::ServerContext* context, const v1::JobRequest* request,
                        v1::JobInfo* response) override;
  grpc::Status SupersedeJob(grpc::ServerContext* context, const v1::SupersedeJobRequest* request,
                            v1::JobInfo* response) override;
  grpc::Status GetJobLog(grpc::ServerContext* context, const v1::JobRequest* request,
                         v1::GetJobLogResponse* response) override;
  grpc::Status GetJobArtifacts(grpc::ServerContext* context, const v1::JobRequest* request,
                               v1::GetJobArtifactsResponse* response) override;
  grpc::Status ListTrialResults(grpc::ServerContext* context, const v1::SweepRequest* request,
                                v1::ListTrialResultsResponse* response) override;
  grpc::Status ExportEpisodes(grpc::ServerContext* context,
                              const v1::ExportEpisodesRequest* request,
                              grpc::ServerWriter<v1::ExportEpisodesResponse>* writer) override;
  grpc::Status ListStudyRows(grpc::ServerContext* context, const v1::ListStudyRowsRequest* request,
                             v1::ListStudyRowsResponse* response) override;
  grpc::Status ExportStudyRows(grpc::ServerContext* context,
                               const v1::ListStudyRowsRequest* request,
                               grpc::ServerWriter<v1::ListStudyRowsResponse>* writer) override;
  grpc::Status ExportTrialResults(grpc::ServerContext* context, const v1::SweepRequest* request,
                                  grpc::ServerWriter<v1::ListTrialResultsResponse>* writer) override;
  grpc::Status ListWorkers(grpc::ServerContext* context, const v1::ListWorkersRequest* request,
                           v1::ListWorkersResponse* response) override;
  grpc::Status DrainWorker(grpc::ServerContext* context, const v1::DrainWorkerRequest* request,
                           v1::WorkerInfo* response) override;
  grpc::Status Health(grpc::ServerContext* context, const v1::HealthRequest* request,
                      v1::HealthResponse* response) override;
  grpc::Status Backup(grpc::ServerContext* context, const v1::BackupRequest* request,
                      v1::BackupResponse* response) override;
  grpc::Status ImportSweep(grpc::ServerContext* context,
                           grpc::ServerReader<v1::ImportSweepChunk>* reader,
                           v1::ImportSweepResponse* response) override;

 private:
  grpc::Status SetState(grpc::ServerContext* context, const v1::SweepRequest* request,
                        storage::SweepState state, v1::SweepInfo* response);

  scheduler::Scheduler* const scheduler_;
  storage::Store* const store_;
  scheduler::Clock* const clock_;
  const TokenAuthenticator* const auth_;
  const ControlServiceOptions options_;
  std::atomic<bool> serving_{false};
  std::function<absl::Status()> health_check_;
};

}  // namespace totalgrad::service

#endif  // TOTALGRAD_SERVER_SERVICE_CONTROL_SERVICE_H_
