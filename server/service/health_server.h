// A plain HTTP/1.1 liveness endpoint for Kubernetes probes, on its own port,
// served by cpp-httplib (Debian's libcpp-httplib-dev) on a small thread pool
// of its own (no TLS, no token: it exposes nothing but "ok" or the reason
// for not being ok).
//
//   GET /healthz  -> 200 "ok\n" when `check` returns OK, else 503 "<reason>\n"
//   other paths or methods -> 404; malformed requests -> 400 (the library's)
//
// Every connection is closed after one answer; a connection that sends no
// complete request head is dropped after 2 s. Connections are served by
// kHealthThreads threads, so a few idle or slow clients do not delay a probe
// (the hand-written server this replaces served one connection at a time,
// and five idle connections held a probe up for 10 s). Never touches the
// gRPC server; Stop() stops the library's listener and joins its thread.
#ifndef TOTALGRAD_SERVER_SERVICE_HEALTH_SERVER_H_
#define TOTALGRAD_SERVER_SERVICE_HEALTH_SERVER_H_

#include <functional>
#include <memory>
#include <string>
#include <thread>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace httplib {
class Server;
}  // namespace httplib

namespace totalgrad::service {

// Threads answering health connections at once.
inline constexpr int kHealthThreads = 8;

class HealthServer {
 public:
  // Binds "host:port" ("[v6]:port" too; port 0: any free port) and starts
  // serving. `check` runs on the server's threads for each GET /healthz and
  // must be thread-safe. InvalidArgument for a malformed address, Unavailable
  // if it cannot be bound.
  static absl::StatusOr<std::unique_ptr<HealthServer>> Start(const std::string& listen,
                                                             std::function<absl::Status()> check);
  ~HealthServer();  // Stop()
  HealthServer(const HealthServer&) = delete;
  HealthServer& operator=(const HealthServer&) = delete;

  int port() const { return port_; }
  // Stops accepting and joins the thread. Idempotent; from the controlling
  // thread only.
  void Stop();

 private:
  HealthServer();

  std::unique_ptr<httplib::Server> server_;
  int port_ = 0;
  std::thread thread_;
};

}  // namespace totalgrad::service

#endif  // TOTALGRAD_SERVER_SERVICE_HEALTH_SERVER_H_
