#include "server/service/coordinator.h"

#ifdef __GLIBC__
#include <malloc.h>
#endif

#include <grpcpp/security/server_credentials.h>
#include <grpcpp/server_builder.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <fstream>
#include <sstream>

#include "absl/strings/str_cat.h"
#include "runtime/address.h"
#include "runtime/build_info.h"
#include "server/service/archive_spool.h"

namespace totalgrad::service {
namespace {

// Threads of the gRPC server kept waiting for calls between bursts.
constexpr int kIdleServerThreads = 64;

// What a client may send on one stream before the coordinator reads it.
// gRPC grows this window by its bandwidth-delay estimate, which a CPU-starved
// coordinator inflates (its pings are answered late): an import of 60 MB
// beside four busy loops on two cores held 11-22 MB of not-yet-read chunks
// (docs/results/scale/import-receive-window.txt). A fixed window bounds that
// per stream; 4 MiB keeps an import's upload at 40 MB/s over a 100 ms round
// trip. Every other request is far smaller than either window.
constexpr int kStreamReceiveWindowBytes = 4 << 20;

// A big request (submitting or listing 100,000 jobs) leaves its freed memory
// in glibc's heap, which keeps it: 480 MB resident after one submission of
// 100,000 jobs. Giving it back every few seconds bounds the coordinator's
// resident memory by what it holds, not by the biggest request it ever
// served (issue 28 item 3).
constexpr int64_t kReturnFreedMemoryEveryMs = 5000;

void ReturnFreedMemoryToTheSystem() {
#ifdef __GLIBC__
  malloc_trim(0);
#endif
}

absl::StatusOr<std::string> ReadFile(const std::string& path, const char* what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::NotFoundError(absl::StrCat("cannot read ", what, " file ", path));
  std::ostringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

// TLS from the options' files (and client certificates when a client CA is
// given), or plaintext with --insecure.
absl::StatusOr<std::shared_ptr<grpc::ServerCredentials>> ServerCredentials(
    const CoordinatorOptions& options) {
  if (options.insecure) return grpc::InsecureServerCredentials();
  absl::StatusOr<std::string> cert = ReadFile(options.tls_cert_file, "TLS certificate");
  if (!cert.ok()) return cert.status();
  absl::StatusOr<std::string> key = ReadFile(options.tls_key_file, "TLS key");
  if (!key.ok()) return key.status();
  grpc::SslServerCredentialsOptions ssl;
  ssl.pem_key_cert_pairs.push_back({*key, *cert});
  if (!options.tls_client_ca_file.empty()) {
    absl::StatusOr<std::string> ca = ReadFile(options.tls_client_ca_file, "client CA");
    if (!ca.ok()) return ca.status();
    ssl.pem_root_certs = *ca;
    ssl.client_certificate_request = GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY;
  }
  return grpc::SslServerCredentials(ssl);
}

}  // namespace

void LimitMallocArenas(int max_arenas) {
#ifdef __GLIBC__
  if (max_arenas > 0) mallopt(M_ARENA_MAX, max_arenas);
#else
  (void)max_arenas;
#endif
}

absl::Status CoordinatorOptions::Validate() const {
  if (database.empty()) return absl::InvalidArgumentError("--db: a database file is required");
  if (listen.empty()) return absl::InvalidArgumentError("--listen: an address is required");
  if (insecure) {
    if (!IsLoopbackAddress(listen)) {
      return absl::InvalidArgumentError(absl::StrCat(
          "--insecure is only allowed on a loopback address (127.0.0.1, ::1, localhost); '",
          listen, "' is not one. Use --tls-cert/--tls-key and token files instead"));
    }
  } else {
    if (tls_cert_file.empty() || tls_key_file.empty()) {
      return absl::InvalidArgumentError(
          "--tls-cert and --tls-key are required (or --insecure on a loopback address)");
    }
    if (worker_token.empty() || user_token.empty()) {
      return absl::InvalidArgumentError(
          "--worker-token-file and --user-token-file are required (or --insecure on a loopback "
          "address)");
    }
  }
  if (max_message_bytes < 64 * 1024) {
    return absl::InvalidArgumentError("--max-message-bytes must be at least 65536");
  }
  return scheduler.Validate();
}

absl::StatusOr<std::unique_ptr<Coordinator>> Coordinator::Start(const CoordinatorOptions& options,
                                                                 scheduler::Clock* clock) {
  absl::Status valid = options.Validate();
  if (!valid.ok()) return valid;
  std::unique_ptr<Coordinator> c(new Coordinator());
  c->options_ = options;
  if (clock == nullptr) {
    c->own_clock_ = std::make_unique<scheduler::SystemClock>();
    clock = c->own_clock_.get();
  }
  c->clock_ = clock;

  absl::StatusOr<TokenAuthenticator> auth =
      TokenAuthenticator::Create(options.worker_token, options.user_token);
  if (!auth.ok()) return auth.status();
  c->auth_ = std::make_unique<TokenAuthenticator>(*std::move(auth));

  storage::SqliteStoreOptions store_options;
  store_options.init = options.init;
  store_options.max_page_count = options.store_max_page_count;
  absl::StatusOr<std::unique_ptr<storage::SqliteStore>> store =
      storage::SqliteStore::Open(options.database, store_options);
  if (!store.ok()) return store.status();
  c->store_ = *std::move(store);
  if (const int removed = ArchiveSpool::RemoveLeftovers(options.database); removed > 0) {
    spdlog::info("removed {} archive copies left by an import that did not end", removed);
  }
  absl::StatusOr<std::string> settings = c->store_->DescribeSettings();
  spdlog::info("database {} ({})", options.database, settings.ok() ? *settings : "?");

  c->scheduler_ = std::make_unique<scheduler::Scheduler>(c->store_.get(), clock, options.scheduler);
  // Recover before serving: leases that were open when the previous process
  // died get one more lease timeout, so their workers can reattach.
  absl::StatusOr<int> extended = c->scheduler_->Recover();
  if (!extended.ok()) return extended.status();
  if (*extended > 0) spdlog::info("recovery: extended {} open leases", *extended);

  c->worker_service_ = std::make_unique<WorkerServiceImpl>(c->scheduler_.get(), c->auth_.get());
  c->control_service_ = std::make_unique<ControlServiceImpl>(
      c->scheduler_.get(), c->store_.get(), clock, c->auth_.get(),
      ControlServiceOptions{BuildId(), options.database, options.backup_dir});
  // Before the server starts (the check reads only members set by then and
  // the atomic serving_ flag).
  c->control_service_->SetHealthCheck([raw = c.get()] { return raw->CheckHealth(); });

  absl::StatusOr<std::shared_ptr<grpc::ServerCredentials>> credentials =
      ServerCredentials(options);
  if (!credentials.ok()) return credentials.status();

  grpc::ServerBuilder builder;
  builder.AddListeningPort(options.listen, *credentials, &c->port_);
  builder.SetMaxReceiveMessageSize(options.max_message_bytes);
  builder.SetMaxSendMessageSize(options.max_message_bytes);
  // Workers beat every 15 s, so the connection is never idle for long; allow
  // client keepalive pings down to 20 s without a GOAWAY.
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS, 20000);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
  builder.AddChannelArgument(GRPC_ARG_HTTP2_BDP_PROBE, 0);
  builder.AddChannelArgument(GRPC_ARG_HTTP2_STREAM_LOOKAHEAD_BYTES, kStreamReceiveWindowBytes);
  // The synchronous server's threads: one that finishes a call exits when
  // MAX_POLLERS others are already waiting for calls (gRPC's default: 2), so
  // with hundreds of workers calling at once each burst created and
  // destroyed threads (pthread_create, stacks mapped and unmapped: a
  // visible share of the coordinator's CPU with 1,000 workers; issue 28).
  // Idle threads cost a stack each; kIdleServerThreads of them stay.
  builder.SetSyncServerOption(grpc::ServerBuilder::SyncServerOption::MAX_POLLERS,
                              kIdleServerThreads);
  builder.RegisterService(c->worker_service_.get());
  builder.RegisterService(c->control_service_.get());
  c->server_ = builder.BuildAndStart();
  if (c->server_ == nullptr || c->port_ == 0) {
    return absl::UnavailableError(absl::StrCat("cannot listen on ", options.listen,
                                               " (address in use, or not an address?)"));
  }
  if (!options.health_listen.empty()) {
    if (absl::Status http = c->StartHttpPort(); !http.ok()) return http;
  }
  c->control_service_->SetServing(true);
  c->serving_ = true;
  c->expiry_thread_ = std::thread([raw = c.get()] { raw->ExpiryLoop(); });
  spdlog::info("coordinator {} serving on port {} ({}, tokens {})", BuildId(), c->port_,
               options.insecure ? "plaintext" : "TLS",
               c->auth_->enabled() ? "required" : "not configured");
  return c;
}

// The HTTP port (--health-listen): /healthz, and the dashboard where it may
// be served (TLS, or plaintext on loopback).
absl::Status Coordinator::StartHttpPort() {
  HttpPortOptions http;
  if (!options_.insecure) {
    http.tls_cert_file = options_.tls_cert_file;
    http.tls_key_file = options_.tls_key_file;
  }
  // Plaintext leaves the machine only from a non-loopback address: the
  // dashboard (sweep names, errors, hosts) is then not served at all.
  const bool dashboard = options_.serve_dashboard &&
                         (!options_.insecure || IsLoopbackAddress(options_.health_listen));
  if (dashboard) {
    dashboard::DashboardOptions view;
    view.build = BuildId();
    view.database = options_.database;
    view.lease_timeout_ms = absl::ToInt64Milliseconds(options_.scheduler.lease_timeout);
    dashboard_ = std::make_unique<dashboard::Dashboard>(
        store_.get(), view,
        [auth = auth_.get()](const std::string* authorization) {
          return auth->CheckBearer(authorization, Role::kUser);
        },
        [clock = clock_] { return clock->NowMs(); });
    http.add_routes = [raw = dashboard_.get()](httplib::Server* server) {
      raw->Register(server);
    };
  } else if (options_.serve_dashboard) {
    spdlog::warn("dashboard not served: the HTTP port {} is plaintext (--insecure) on an "
                 "address that is not loopback; it serves /healthz alone. Use TLS, or a "
                 "loopback address and an SSH tunnel",
                 options_.health_listen);
  }
  absl::StatusOr<std::unique_ptr<HealthServer>> health = HealthServer::Start(
      options_.health_listen, [this] { return CheckHealth(); }, std::move(http));
  if (!health.ok()) return health.status();
  health_server_ = *std::move(health);
  const char* scheme = health_server_->tls() ? "https" : "http";
  spdlog::info("health endpoint: {}://{}/healthz (port {})", scheme, options_.health_listen,
               health_server_->port());
  if (dashboard) {
    spdlog::info("dashboard: {}://{}/ ({})", scheme, options_.health_listen,
                 auth_->enabled() ? "asks for the user token" : "no token configured");
  }
  return absl::OkStatus();
}

void Coordinator::ExpiryLoop() {
  // Check often relative to the timeout, so a lost lease is noticed within a
  // few percent of lease_timeout, and several times per heartbeat interval,
  // so that a gap of more than one interval really means a stall (the
  // scheduler then extends every lease instead of expiring it).
  const int64_t period_ms = std::clamp<int64_t>(
      std::min(absl::ToInt64Milliseconds(options_.scheduler.lease_timeout) / 20,
               absl::ToInt64Milliseconds(options_.scheduler.heartbeat_interval) / 4),
      10, 1000);
  // Real time, whatever clock_ is (tests move a FakeClock between rounds).
  SystemClock real_time;
  const absl::Condition stop_requested(&stopping_);
  int64_t last_trim_ms = real_time.MonotonicMs();
  mutex_.Lock();  // held except while checking (Lock/Unlock: released mid-loop)
  while (!stopping_) {
    real_time.AwaitUntil(&mutex_, stop_requested, real_time.MonotonicMs() + period_ms);
    if (stopping_) break;
    mutex_.Unlock();
    if (real_time.MonotonicMs() - last_trim_ms >= kReturnFreedMemoryEveryMs) {
      ReturnFreedMemoryToTheSystem();
      last_trim_ms = real_time.MonotonicMs();
    }
    scheduler::ExpiryReport report;
    absl::StatusOr<int> expired = scheduler_->ExpireLeases(&report);
    if (!expired.ok()) {
      spdlog::warn("lease expiry check failed: {}", expired.status().ToString());
    } else if (report.stalled_ms > 0) {
      spdlog::warn("the coordinator stalled for {} ms (lease loop not run; SIGSTOP, swapping or "
                   "a suspended machine?): extended {} open leases by the lease timeout instead "
                   "of expiring them",
                   report.stalled_ms, report.extended);
    } else if (*expired > 0) {
      spdlog::info("{} leases lost; their jobs were re-queued", *expired);
    }
    mutex_.Lock();
  }
  mutex_.Unlock();
}

void Coordinator::Shutdown() {
  {
    absl::MutexLock lock(&mutex_);
    if (stopping_) return;
    stopping_ = true;
  }
  serving_ = false;
  if (control_service_) control_service_->SetServing(false);
  if (scheduler_) scheduler_->Shutdown();
  // In-flight calls get 2 s; then they are cancelled, which is safe because
  // every write is idempotent and clients retry against the next coordinator.
  if (server_) server_->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
  if (expiry_thread_.joinable()) expiry_thread_.join();
  if (server_) server_->Wait();
  // Before the store goes: the health check reads it.
  if (health_server_) health_server_->Stop();
  store_.reset();  // checkpoints the WAL
  spdlog::info("coordinator stopped");
  // Last: once Wait() returns, the owner may destroy this object.
  absl::MutexLock lock(&mutex_);
  stopped_ = true;
}

absl::Status Coordinator::CheckHealth() {
  if (!serving_) return absl::UnavailableError("not serving (starting or shutting down)");
  if (scheduler_->shut_down()) return absl::UnavailableError("scheduler shut down");
  absl::Status store = store_->Ping();
  if (store.ok()) store = store_->CheckWritable();
  if (!store.ok()) return absl::UnavailableError(absl::StrCat("database: ", store.message()));
  return absl::OkStatus();
}

void Coordinator::Wait() {
  absl::MutexLock lock(&mutex_);
  mutex_.Await(absl::Condition(&stopped_));
}

Coordinator::~Coordinator() { Shutdown(); }

}  // namespace totalgrad::service
