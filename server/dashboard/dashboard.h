// The coordinator's read-only web dashboard, served on its HTTP port beside
// GET /healthz (server/service/health_server.h):
//
//   GET /                      the page (assets/index.html); it asks for the
//   GET /dashboard.js|.css     user token when the API answers 401
//   GET /api/overview          sweeps with progress and ETA, workers
//   GET /api/sweep?name=S      progress and the Table 1 cells
//   GET /api/curves?name=S[&running=0|1]
//   GET /api/compare?name=S[&baseline=M]
//   GET /api/table1?name=S[&name=T...]  the paper's Table 1 from these sweeps
//   GET /api/jobs?name=S[&after=ID][&limit=N]
//   GET /api/job?id=ID         options, attempts, events, episodes
//
// The API answers JSON; errors are {"error": "..."} with 400 (bad
// parameter), 401 (no or unknown token), 403 (a worker token), 404
// (unknown sweep or job) or 503/500 (the store's errors). Only GET: it never
// writes. Whether the port is TLS and which addresses it may bind is the
// coordinator's decision (coordinator.h); this class only serves.
//
// Threading: handlers run on the HTTP server's threads; the store and the
// authorisation function must be thread-safe.
#ifndef TOTALGRAD_SERVER_DASHBOARD_DASHBOARD_H_
#define TOTALGRAD_SERVER_DASHBOARD_DASHBOARD_H_

#include <functional>
#include <optional>
#include <string>
#include <string_view>

#include "absl/status/status.h"
#include "server/dashboard/dashboard_data.h"

namespace httplib {
class Server;
}  // namespace httplib

namespace totalgrad::dashboard {

// The page's files, compiled into the binary (generated from assets/ by
// cmake/EmbedFiles.cmake): by base name, nullopt if there is none.
std::optional<std::string_view> EmbeddedFile(std::string_view name);

class Dashboard {
 public:
  // `authorize` gets the request's Authorization header (nullptr if none)
  // and returns OK, Unauthenticated or PermissionDenied. `now_ms` is the
  // coordinator's wall clock. `store` is not owned and must outlive this.
  Dashboard(storage::StoreReader* store, DashboardOptions options,
            std::function<absl::Status(const std::string* authorization)> authorize,
            std::function<int64_t()> now_ms)
      : data_(store, std::move(options)), authorize_(std::move(authorize)),
        now_ms_(std::move(now_ms)) {}
  Dashboard(const Dashboard&) = delete;
  Dashboard& operator=(const Dashboard&) = delete;

  // Adds the routes above to `server`. This object must outlive the server's
  // last request (stop the server first).
  void Register(httplib::Server* server);

 private:
  DashboardData data_;
  const std::function<absl::Status(const std::string*)> authorize_;
  const std::function<int64_t()> now_ms_;
};

}  // namespace totalgrad::dashboard

#endif  // TOTALGRAD_SERVER_DASHBOARD_DASHBOARD_H_
