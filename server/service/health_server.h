// A plain HTTP/1.1 liveness endpoint for Kubernetes probes, on its own port
// and its own thread, with plain POSIX sockets (no TLS, no token: it exposes
// nothing but "ok" or the reason for not being ok).
//
//   GET /healthz  -> 200 "ok\n" when `check` returns OK, else 503 "<reason>\n"
//   other paths or methods -> 404; malformed or oversized requests -> 400
//
// One connection at a time, request head at most 4 KiB, 2 s to read it and
// write the answer, then the connection is closed. Never touches the gRPC
// server; Stop() wakes the thread and joins it.
#ifndef TOTALGRAD_SERVER_SERVICE_HEALTH_SERVER_H_
#define TOTALGRAD_SERVER_SERVICE_HEALTH_SERVER_H_

#include <functional>
#include <memory>
#include <string>
#include <thread>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace totalgrad::service {

class HealthServer {
 public:
  // Binds "host:port" ("[v6]:port" too; port 0: any free port) and starts the
  // thread. `check` runs on that thread for each GET /healthz and must be
  // thread-safe. InvalidArgument for a malformed address, Unavailable if it
  // cannot be bound.
  static absl::StatusOr<std::unique_ptr<HealthServer>> Start(const std::string& listen,
                                                             std::function<absl::Status()> check);
  ~HealthServer();  // Stop()
  HealthServer(const HealthServer&) = delete;
  HealthServer& operator=(const HealthServer&) = delete;

  int port() const { return port_; }
  // Stops accepting, abandons a connection in progress, joins the thread.
  // Idempotent; from the controlling thread only.
  void Stop();

 private:
  HealthServer() = default;
  void Loop();
  void Serve(int client);

  std::function<absl::Status()> check_;
  int listen_fd_ = -1;
  int wake_read_ = -1;
  int wake_write_ = -1;
  int port_ = 0;
  std::thread thread_;
};

}  // namespace totalgrad::service

#endif  // TOTALGRAD_SERVER_SERVICE_HEALTH_SERVER_H_
