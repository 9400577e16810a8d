// The coordinator process in one object: opens the store, recovers open
// leases, serves WorkerService and ControlService over gRPC, and expires
// leases on a timer. main.cc only parses flags, starts it and waits for a
// signal; tests start it in-process the same way.
//
// Security rules (checked by Validate): without `insecure`, TLS certificate
// and key files and both tokens are required; `insecure` (plaintext, tokens
// optional) is refused unless the listen address is loopback.
//
// Threading: Start/Shutdown/Wait from one controlling thread; the services
// run on gRPC's threads.
#ifndef TOTALGRAD_SERVER_SERVICE_COORDINATOR_H_
#define TOTALGRAD_SERVER_SERVICE_COORDINATOR_H_

#include <grpcpp/server.h>

#include <atomic>
#include <memory>
#include <string>
#include <thread>

#include "absl/base/thread_annotations.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"
#include "server/dashboard/dashboard.h"
#include "server/scheduler/clock.h"
#include "server/scheduler/scheduler.h"
#include "server/service/auth.h"
#include "server/service/control_service.h"
#include "server/service/health_server.h"
#include "server/service/worker_service.h"
#include "server/storage/sqlite_store.h"

namespace totalgrad::service {

struct CoordinatorOptions {
  // host:port to listen on; port 0 picks a free port (see Coordinator::port()).
  std::string listen = "127.0.0.1:7070";
  // The SQLite file. Must be on a local disk. Created on a first start (no
  // file and no lock file beside it); see SqliteStore::Open for the rest.
  std::string database;
  // --init: may initialise a new store in a 0-byte file, an SQLite file
  // without tables, or in place of a database the lock file says was there.
  bool init = false;
  // Passed to the store (tests use max_page_count to emulate a full disk).
  int64_t store_max_page_count = 0;
  // Token contents (not file names). Both or neither.
  std::string worker_token;
  std::string user_token;
  // PEM files. The client CA, if given, makes client certificates mandatory.
  std::string tls_cert_file;
  std::string tls_key_file;
  std::string tls_client_ca_file;
  bool insecure = false;
  scheduler::SchedulerOptions scheduler;
  // Directory for Backup RPC copies; empty refuses the RPC.
  std::string backup_dir;
  // Largest request or response message, bytes.
  int max_message_bytes = 4 << 20;
  // host:port of the HTTP port (--http-listen, also --health-listen): GET
  // /healthz for probes (health_server.h), never behind a token, and the
  // read-only dashboard (server/dashboard/dashboard.h). Empty: no HTTP port.
  // Port 0 picks a free port. With TLS configured the port is HTTPS with the
  // same certificate and key, and the dashboard's API asks for the user
  // token. Plaintext (--insecure) serves the dashboard only on a loopback
  // address (its API then asks for the user token if tokens are set); on
  // any other address the port serves /healthz alone.
  std::string health_listen;
  // False: the HTTP port serves /healthz alone (--no-dashboard).
  bool serve_dashboard = true;

  // InvalidArgument naming the flag at fault.
  absl::Status Validate() const;
};

// glibc gives each thread that meets a busy heap an arena of its own (up to
// 8 per core), and malloc_trim, which the coordinator calls every 5 s, does
// not shrink the top of those per-thread heaps: after listing 20,000 jobs,
// 2 to 7 MB of freed memory stayed resident in whichever arena the call's
// gRPC thread had used (scale_export_test; 0.2-0.3 MB with two arenas,
// docs/results/scale/listing-retention-arenas.txt). A process that runs a
// coordinator calls LimitMallocArenas(kCoordinatorMallocArenas) before it
// starts any thread (totalgrad-coordinator's main, the load bench); 0 keeps
// glibc's default. A no-op without glibc.
inline constexpr int kCoordinatorMallocArenas = 2;
void LimitMallocArenas(int max_arenas);

class Coordinator {
 public:
  // Opens the database, runs recovery, starts serving. `clock` is not owned
  // (null: the system clock). Errors: InvalidArgument (options), the store's
  // open errors, Unavailable if the address cannot be bound.
  static absl::StatusOr<std::unique_ptr<Coordinator>> Start(const CoordinatorOptions& options,
                                                            scheduler::Clock* clock = nullptr);
  ~Coordinator();  // Shutdown()
  Coordinator(const Coordinator&) = delete;
  Coordinator& operator=(const Coordinator&) = delete;

  // The bound port.
  int port() const { return port_; }
  // The bound health port (0 without health_listen).
  int health_port() const { return health_server_ ? health_server_->port() : 0; }
  // Whether the HTTP port serves the dashboard (see health_listen).
  bool dashboard_served() const { return dashboard_ != nullptr; }
  // What GET /healthz reports: OK while serving, the store answers a trivial
  // query and can commit (SqliteStore::CheckWritable: the file was not
  // deleted or replaced, commits do not fail), else Unavailable with the
  // reason. Thread-safe until Shutdown has stopped the health server.
  absl::Status CheckHealth();
  // Stops taking leases, wakes long polls, stops the server (in-flight calls
  // get up to 2 s), stops the lease timer and closes the store. Idempotent.
  void Shutdown() ABSL_LOCKS_EXCLUDED(mutex_);
  // Blocks until Shutdown() has been called and finished.
  void Wait() ABSL_LOCKS_EXCLUDED(mutex_);
  storage::SqliteStore* store() { return store_.get(); }

 private:
  Coordinator() = default;
  void ExpiryLoop() ABSL_LOCKS_EXCLUDED(mutex_);
  // Serves /healthz and the dashboard on options_.health_listen (Start).
  absl::Status StartHttpPort();

  CoordinatorOptions options_;
  std::unique_ptr<scheduler::SystemClock> own_clock_;
  scheduler::Clock* clock_ = nullptr;
  std::unique_ptr<storage::SqliteStore> store_;
  std::unique_ptr<scheduler::Scheduler> scheduler_;
  std::unique_ptr<TokenAuthenticator> auth_;
  std::unique_ptr<WorkerServiceImpl> worker_service_;
  std::unique_ptr<ControlServiceImpl> control_service_;
  std::unique_ptr<grpc::Server> server_;
  int port_ = 0;
  // Declared before health_server_ so it outlives the server's last request.
  std::unique_ptr<dashboard::Dashboard> dashboard_;
  std::unique_ptr<HealthServer> health_server_;
  std::atomic<bool> serving_{false};

  // The expiry loop and Wait() await changes of these (absl::Mutex
  // re-evaluates their conditions whenever mutex_ is released).
  absl::Mutex mutex_;
  bool stopping_ ABSL_GUARDED_BY(mutex_) = false;
  bool stopped_ ABSL_GUARDED_BY(mutex_) = false;
  std::thread expiry_thread_;
};

}  // namespace totalgrad::service

#endif  // TOTALGRAD_SERVER_SERVICE_COORDINATOR_H_
