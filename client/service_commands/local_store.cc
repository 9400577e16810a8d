#include "client/service_commands/local_store.h"

#include <grpcpp/server.h>
#include <grpcpp/server_builder.h>

#include <utility>

#include "runtime/build_info.h"
#include "server/scheduler/clock.h"
#include "server/scheduler/scheduler.h"
#include "server/service/archive_spool.h"
#include "server/service/auth.h"
#include "server/service/control_service.h"
#include "server/storage/store.h"

namespace totalgrad::cli {

struct LocalCoordinator::Parts {
  std::unique_ptr<storage::Store> store;
  scheduler::SystemClock clock;
  std::unique_ptr<scheduler::Scheduler> scheduler;
  std::unique_ptr<service::TokenAuthenticator> auth;
  std::unique_ptr<service::ControlServiceImpl> control;
  std::unique_ptr<grpc::Server> server;
};

LocalCoordinator::LocalCoordinator(std::unique_ptr<Parts> parts) : parts_(std::move(parts)) {
  channel_ = parts_->server->InProcessChannel(grpc::ChannelArguments());
}

LocalCoordinator::~LocalCoordinator() {
  channel_.reset();
  if (parts_ && parts_->server) parts_->server->Shutdown();
}

absl::StatusOr<std::shared_ptr<LocalCoordinator>> LocalCoordinator::Open(
    const std::string& database, bool writable) {
  auto parts = std::make_unique<Parts>();
  absl::StatusOr<std::unique_ptr<storage::Store>> store =
      writable ? storage::OpenStoreForWriting(database) : storage::OpenStoreReadOnly(database);
  if (!store.ok()) return store.status();
  parts->store = *std::move(store);
  if (writable) service::ArchiveSpool::RemoveLeftovers(database);
  parts->scheduler = std::make_unique<scheduler::Scheduler>(parts->store.get(), &parts->clock,
                                                            scheduler::SchedulerOptions());
  // No tokens: the channel exists only inside this process.
  absl::StatusOr<service::TokenAuthenticator> auth = service::TokenAuthenticator::Create("", "");
  if (!auth.ok()) return auth.status();
  parts->auth = std::make_unique<service::TokenAuthenticator>(*std::move(auth));
  parts->control = std::make_unique<service::ControlServiceImpl>(
      parts->scheduler.get(), parts->store.get(), &parts->clock, parts->auth.get(),
      service::ControlServiceOptions{BuildId(), database, /*backup_dir=*/""});
  parts->control->SetServing(true);
  grpc::ServerBuilder builder;
  builder.RegisterService(parts->control.get());
  parts->server = builder.BuildAndStart();
  if (parts->server == nullptr) {
    return absl::InternalError("could not start the in-process service for --db");
  }
  return std::shared_ptr<LocalCoordinator>(new LocalCoordinator(std::move(parts)));
}

}  // namespace totalgrad::cli
