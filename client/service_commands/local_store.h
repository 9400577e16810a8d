// `--db FILE`: the ControlService of a coordinator database read directly,
// without a coordinator. The real service handlers run in this process over a
// read-only SqliteStore (storage::SqliteStore::OpenReadOnly) and are reached
// through gRPC's in-process channel, so every results command gives exactly
// what it gives against a live coordinator. Safe while a coordinator writes
// the file: no lock is taken and nothing is written (writes are refused with
// FAILED_PRECONDITION naming the file).
#ifndef TOTALGRAD_CLIENT_SERVICE_COMMANDS_LOCAL_STORE_H_
#define TOTALGRAD_CLIENT_SERVICE_COMMANDS_LOCAL_STORE_H_

#include <grpcpp/channel.h>

#include <memory>
#include <string>

#include "absl/status/statusor.h"

namespace totalgrad::cli {

class LocalCoordinator {
 public:
  // FailedPrecondition / DataLoss as SqliteStore::OpenReadOnly; with
  // `writable`, the database is opened (or created) for writing and locked
  // as a coordinator locks it (storage::OpenStoreForWriting): for `results
  // import --db` only.
  static absl::StatusOr<std::shared_ptr<LocalCoordinator>> Open(const std::string& database,
                                                                bool writable = false);
  ~LocalCoordinator();
  LocalCoordinator(const LocalCoordinator&) = delete;
  LocalCoordinator& operator=(const LocalCoordinator&) = delete;

  // A channel to the in-process service; valid while this object lives.
  std::shared_ptr<grpc::Channel> channel() const { return channel_; }

 private:
  struct Parts;
  explicit LocalCoordinator(std::unique_ptr<Parts> parts);
  std::unique_ptr<Parts> parts_;
  std::shared_ptr<grpc::Channel> channel_;
};

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_SERVICE_COMMANDS_LOCAL_STORE_H_
