// The coordinator's HTTP port: a liveness endpoint for Kubernetes probes
// and, when the coordinator adds them, the dashboard's routes
// (server/dashboard/dashboard.h), served by cpp-httplib (Debian's
// libcpp-httplib-dev, built with OpenSSL) on threads of its own.
//
//   GET /healthz  -> 200 "ok\n" when `check` returns OK, else 503 "<reason>\n";
//                    never asks for a token (it exposes nothing but "ok" or
//                    the reason for not being ok)
//   routes added by HttpPortOptions::add_routes
//   other paths or methods -> 404; malformed requests -> 400 (the library's)
//
// Plain HTTP, or HTTPS with the given certificate and key (then probes use
// scheme HTTPS). Every connection is closed after one answer. Slow or idle
// clients cannot starve a probe (server/service/http_guard.h): the whole
// request must arrive within HttpLimits::request_deadline (3 s) of the
// connection being served, whatever the pace of its bytes; each connection
// has a thread of its own, up to max_connections (64); beyond that, or
// beyond max_connections_per_address (16) from one address, the oldest
// connection still waiting for its request is closed to serve the new one,
// so a probe (one packet, answered in milliseconds) always gets through, from
// any address. /healthz therefore needs no listener of its own. Never
// touches the gRPC server; Stop() stops the library's listener and joins its
// thread.
#ifndef TOTALGRAD_SERVER_SERVICE_HEALTH_SERVER_H_
#define TOTALGRAD_SERVER_SERVICE_HEALTH_SERVER_H_

#include <chrono>
#include <cstdint>
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

struct HttpLimits {
  // The whole request must have arrived this long after its connection is
  // first served; the connection is closed otherwise.
  std::chrono::milliseconds request_deadline{3000};
  // Each write of the answer.
  std::chrono::milliseconds write_timeout{2000};
  // Connections served at once (each has a thread while it is open).
  int max_connections = 64;
  // Connections of one client address at once.
  int max_connections_per_address = 16;
};

struct HttpPortOptions {
  // PEM files of the certificate chain and key: serve HTTPS (both or neither).
  std::string tls_cert_file;
  std::string tls_key_file;
  // Called once before serving to add routes besides /healthz; null: none.
  std::function<void(httplib::Server*)> add_routes;
  // Deadlines and bounds of the port's connections (server/service/http_guard.h).
  HttpLimits limits;
};

class HealthServer {
 public:
  // Binds "host:port" ("[v6]:port" too; port 0: any free port) and starts
  // serving. `check` runs on the server's threads for each GET /healthz and
  // must be thread-safe. InvalidArgument for a malformed address or only one
  // of the TLS files, FailedPrecondition if the certificate or key cannot be
  // loaded, Unavailable if the address cannot be bound.
  static absl::StatusOr<std::unique_ptr<HealthServer>> Start(const std::string& listen,
                                                             std::function<absl::Status()> check,
                                                             HttpPortOptions options = {});
  ~HealthServer();  // Stop()
  HealthServer(const HealthServer&) = delete;
  HealthServer& operator=(const HealthServer&) = delete;

  int port() const { return port_; }
  bool tls() const { return tls_; }
  // Stops accepting and joins the thread. Idempotent; from the controlling
  // thread only.
  void Stop();

 private:
  HealthServer() = default;

  std::unique_ptr<httplib::Server> server_;
  int port_ = 0;
  bool tls_ = false;
  std::thread thread_;
};

}  // namespace totalgrad::service

#endif  // TOTALGRAD_SERVER_SERVICE_HEALTH_SERVER_H_
