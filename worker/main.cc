// totalgrad-worker: runs trials for a coordinator.
//
//   totalgrad-worker --coordinator coord.example:7070 --ca-cert ca.pem
//       --token-file worker.token --slots 8
//   totalgrad-worker --coordinator 127.0.0.1:7070 --insecure
//
// SIGTERM/SIGINT drain (no new leases; running trials finish within
// --drain-timeout or are released); a second signal releases at once.
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <fstream>
#include <thread>

#include "core/common/blas.h"
#include "server/common/build_info.h"
#include "server/common/signals.h"
#include "server/common/rpc_client.h"
#include "worker/learner_runner.h"
#include "worker/study_runner.h"
#include "worker/worker.h"

namespace {

std::string HostName() {
  char buffer[256] = {};
  if (gethostname(buffer, sizeof(buffer) - 1) != 0) return "unknown-host";
  return buffer;
}

absl::StatusOr<std::string> ReadToken(const std::string& path) {
  std::ifstream in(path);
  if (!in) return absl::NotFoundError("cannot read token file " + path);
  std::string token((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  while (!token.empty() && std::isspace(static_cast<unsigned char>(token.back()))) token.pop_back();
  while (!token.empty() && std::isspace(static_cast<unsigned char>(token.front()))) token.erase(0, 1);
  if (token.empty()) return absl::InvalidArgumentError("token file " + path + " is empty");
  return token;
}

}  // namespace

int main(int argc, char** argv) {
  totalgrad::SelectBlasKernels(argv);  // may re-execute this program (core/common/blas.h)
  CLI::App app{"totalgrad-worker: runs policy-learning trials leased from a coordinator"};
  totalgrad::rpc::ConnectionOptions connection;
  totalgrad::worker::WorkerOptions options;
  options.slots = std::max(1u, std::thread::hardware_concurrency());
  options.host = HostName();
  options.worker_id = options.host + "-" + std::to_string(getpid());
  // The BLAS kernels change a trial's last bits: they are part of its provenance.
  options.build = totalgrad::BuildId() + " blas " + totalgrad::BlasCoreName();
  std::string token_file;
  double drain_seconds = 60, max_idle_seconds = -1, acquire_wait_seconds = 20;
  app.add_option("--coordinator", connection.target, "coordinator host:port")->required();
  app.add_option("--slots", options.slots, "trials run at once (default: one per core)")
      ->check(CLI::Range(1, 4096))
      ->capture_default_str();
  app.add_option("--token-file", token_file, "file holding the worker token");
  app.add_option("--ca-cert", connection.ca_cert_file, "CA certificate to trust (PEM)");
  app.add_option("--client-cert", connection.client_cert_file, "client certificate (PEM)");
  app.add_option("--client-key", connection.client_key_file, "client key (PEM)");
  app.add_option("--tls-server-name", connection.tls_server_name,
                 "expected name in the server certificate (default: the host)");
  app.add_flag("--insecure", connection.insecure, "plaintext; only to a loopback coordinator");
  app.add_option("--worker-id", options.worker_id, "unique id of this worker")
      ->capture_default_str();
  app.add_option("--drain-timeout", drain_seconds,
                 "seconds running trials get to finish after SIGTERM")
      ->capture_default_str();
  app.add_option("--max-idle", max_idle_seconds,
                 "exit after this many seconds without work (default: never)");
  app.add_option("--acquire-wait", acquire_wait_seconds, "long-poll length, seconds")
      ->capture_default_str();
  // Batch allocations (deploy/slurm): drain --trial-time before the end of
  // --walltime, so no trial is taken that cannot finish in time.
  double walltime_seconds = -1, trial_seconds = 0;
  app.add_option("--walltime", walltime_seconds,
                 "seconds this worker may run (e.g. what is left of a batch allocation); it "
                 "drains --trial-time before the end, taking no trial it cannot finish")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--trial-time", trial_seconds, "longest expected trial, seconds (with --walltime)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.set_version_flag("--version", totalgrad::BuildId());
  CLI11_PARSE(app, argc, argv);
  spdlog::flush_on(spdlog::level::info);

  if (!token_file.empty()) {
    auto token = ReadToken(token_file);
    if (!token.ok()) {
      spdlog::error("{}", token.status().ToString());
      return 2;
    }
    options.token = *token;
    connection.token = *token;
  }
  options.drain_timeout = absl::Seconds(drain_seconds);
  options.acquire_wait = absl::Seconds(acquire_wait_seconds);
  if (max_idle_seconds >= 0) options.max_idle = absl::Seconds(max_idle_seconds);

  auto channel = totalgrad::rpc::MakeChannel(connection);
  if (!channel.ok()) {
    spdlog::error("{}", channel.status().ToString());
    return 2;
  }
  if (!totalgrad::InstallShutdownSignals()) {
    spdlog::error("cannot install signal handlers");
    return 2;
  }

  // Deliberately never destroyed: the detached signal thread may still hold
  // them while the process exits.
  auto* runner = new totalgrad::worker::LearnerTrialRunner();
  auto* study_runner = new totalgrad::worker::CoreStudyRunner();
  auto* worker_ptr = new totalgrad::worker::Worker(options, *channel, runner, study_runner);
  totalgrad::worker::Worker& worker = *worker_ptr;
  std::thread signal_thread([&worker] {
    int signal_number = totalgrad::WaitForShutdownSignal();
    spdlog::info("signal {}: draining (send again to release running trials now)", signal_number);
    worker.Drain();
    signal_number = totalgrad::WaitForShutdownSignal();
    spdlog::info("signal {}: releasing running trials", signal_number);
    worker.Stop();
  });
  signal_thread.detach();
  if (walltime_seconds >= 0) {
    const double drain_after = std::max(0.0, walltime_seconds - trial_seconds);
    std::thread([&worker, drain_after] {
      std::this_thread::sleep_for(std::chrono::duration<double>(drain_after));
      spdlog::info("walltime: less than --trial-time left; taking no new trial");
      worker.Drain();
    }).detach();
  }
  spdlog::info("worker {} ({} slots) -> {} [{}]", options.worker_id, options.slots,
               connection.target, options.build);
  const totalgrad::worker::WorkerSummary summary = worker.Run();
  spdlog::info("worker done: {} completed, {} failed, {} released, {} dropped", summary.completed,
               summary.failed, summary.released, summary.dropped);
  return 0;
}
