// totalgrad-coordinator: owns the SQLite store and serves workers and users.
//
//   totalgrad-coordinator --db results.db --listen 0.0.0.0:7070
//       --tls-cert server.pem --tls-key server.key
//       --worker-token-file worker.token --user-token-file user.token
//   totalgrad-coordinator --db results.db --listen 127.0.0.1:7070 --insecure
//   totalgrad-coordinator --db results.db --backup copy.db     # consistent copy, then exit
//   ... --http-listen 0.0.0.0:8080   # GET /healthz for probes, the dashboard at /
//
// SIGINT/SIGTERM stop it gracefully (in-flight calls finish, WAL checkpointed).
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <fstream>
#include <thread>

#include "absl/synchronization/mutex.h"
#include "runtime/build_info.h"
#include "runtime/signals.h"
#include "runtime/token_file.h"
#include "server/service/auth.h"
#include "server/service/coordinator.h"
#include "server/storage/sqlite_store.h"

namespace {

int Fail(const std::string& message) {
  spdlog::error("{}", message);
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  using totalgrad::service::CoordinatorOptions;
  totalgrad::service::LimitMallocArenas(totalgrad::service::kCoordinatorMallocArenas);
  // abseil's lock-order (deadlock) check runs on every Mutex acquisition,
  // gRPC's own included, where abseil was built without NDEBUG (Debian's):
  // about 6 % of the coordinator's CPU with 1,000 workers (perf, issue 28).
  // The tests keep it; the binary does not pay for it.
  absl::SetMutexDeadlockDetectionMode(absl::OnDeadlockCycle::kIgnore);
  CLI::App app{"totalgrad-coordinator: hands trials to workers and stores their results"};
  CoordinatorOptions options;
  std::string worker_token_file, user_token_file, port_file, backup_path;
  double heartbeat_seconds = 15, lease_timeout_seconds = 90;
  app.add_option("--db", options.database,
                 "SQLite file (local disk only; created on a first start, see --init)")
      ->required();
  app.add_flag("--init", options.init,
               "allow initialising a new database in a 0-byte file, an SQLite file without "
               "tables, or in place of a database that its lock file says was deleted");
  app.add_option("--listen", options.listen, "host:port to serve on (port 0: any free port)")
      ->capture_default_str();
  app.add_option("--worker-token-file", worker_token_file, "file holding the worker token");
  app.add_option("--user-token-file", user_token_file, "file holding the user token");
  app.add_option("--tls-cert", options.tls_cert_file, "server certificate (PEM)");
  app.add_option("--tls-key", options.tls_key_file, "server private key (PEM)");
  app.add_option("--tls-client-ca", options.tls_client_ca_file,
                 "CA for client certificates (makes them mandatory)");
  app.add_flag("--insecure", options.insecure,
               "plaintext, tokens optional; only on a loopback address");
  app.add_option("--heartbeat-interval", heartbeat_seconds, "seconds between worker heartbeats")
      ->capture_default_str();
  app.add_option("--lease-timeout", lease_timeout_seconds,
                 "seconds without a heartbeat before a lease is lost")
      ->capture_default_str();
  app.add_option("--backup-dir", options.backup_dir, "directory for Backup RPC copies");
  app.add_option("--backup", backup_path,
                 "write a consistent copy of --db to this path and exit");
  app.add_option("--max-message-bytes", options.max_message_bytes, "largest gRPC message")
      ->capture_default_str();
  app.add_option("--http-listen,--health-listen", options.health_listen,
                 "host:port of the HTTP port: GET /healthz for probes (no token) and the "
                 "read-only dashboard at / (HTTPS + user token when TLS is configured; "
                 "plaintext: dashboard on loopback only)");
  bool no_dashboard = false;
  app.add_flag("--no-dashboard", no_dashboard, "serve only /healthz on the HTTP port");
  app.add_option("--port-file", port_file, "write the bound port to this file once serving");
  app.set_version_flag("--version", totalgrad::BuildId());
  CLI11_PARSE(app, argc, argv);
  options.serve_dashboard = !no_dashboard;
  spdlog::flush_on(spdlog::level::info);

  if (!backup_path.empty()) {
    // Read-only and without the lock: works while a coordinator owns the file.
    auto bytes = totalgrad::storage::SqliteStore::BackupFile(options.database, backup_path);
    if (!bytes.ok()) return Fail(bytes.status().ToString());
    spdlog::info("backup of {} written to {} ({} bytes)", options.database, backup_path, *bytes);
    return 0;
  }
  for (auto [file, token] : {std::pair{&worker_token_file, &options.worker_token},
                             std::pair{&user_token_file, &options.user_token}}) {
    if (file->empty()) continue;
    auto read = totalgrad::ReadTokenFile(*file);
    if (!read.ok()) return Fail(read.status().ToString());
    if (!read->warning.empty()) spdlog::warn("{}", read->warning);
    *token = read->token;
  }
  options.scheduler.heartbeat_interval = absl::Seconds(heartbeat_seconds);
  options.scheduler.lease_timeout = absl::Seconds(lease_timeout_seconds);

  // The signal handler only wakes a thread; shutdown runs outside signal context.
  if (!totalgrad::InstallShutdownSignals()) return Fail("cannot install signal handlers");

  auto coordinator = totalgrad::service::Coordinator::Start(options);
  if (!coordinator.ok()) return Fail(coordinator.status().ToString());
  if (!port_file.empty()) {
    // Written to a temporary name and renamed, so a reader never sees half a number.
    const std::string temporary = port_file + ".tmp";
    std::ofstream(temporary) << (*coordinator)->port() << "\n";
    std::rename(temporary.c_str(), port_file.c_str());
  }
  std::thread signal_thread([&] {
    const int signal_number = totalgrad::WaitForShutdownSignal();
    spdlog::info("signal {}: shutting down", signal_number);
    (*coordinator)->Shutdown();
  });
  // Only the signal thread shuts the coordinator down, so joining it is the
  // wait; the coordinator is destroyed after the thread is done with it.
  signal_thread.join();
  (*coordinator)->Wait();
  return 0;
}
