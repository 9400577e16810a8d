// totalgrad-worker: runs trials for a coordinator.
//
//   totalgrad-worker --coordinator coord.example:7070 --ca-cert ca.pem
//       --token-file worker.token --slots 8
//   totalgrad-worker --coordinator 127.0.0.1:7070 --insecure
//
// SIGTERM/SIGINT drain (no new leases; running trials finish within
// --drain-timeout or are released; what cannot be delivered then is kept in
// --state-dir for the next worker with the same id on this host); a second
// signal exits at once, keeping what is unfinished in --state-dir.
//
// Exit codes: 0 done; 2 bad flags or files; 77 the coordinator refused the
// token; 78 the worker id is in use by another live worker process.
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cstdlib>
#include <fstream>
#include <thread>

#include "core/common/blas.h"
#include "runtime/build_info.h"
#include "runtime/signals.h"
#include "runtime/token_file.h"
#include "runtime/rpc_client.h"
#include "worker/learner_runner.h"
#include "worker/study_runner.h"
#include "worker/worker.h"

namespace {

std::string HostName() {
  char buffer[256] = {};
  if (gethostname(buffer, sizeof(buffer) - 1) != 0) return "unknown-host";
  return buffer;
}

// Where the worker keeps its lock and spool unless --state-dir says:
// systemd's StateDirectory, then XDG_STATE_HOME, then ~/.local/state, then
// /var/tmp (per user).
std::string DefaultStateDir() {
  if (const char* dir = std::getenv("STATE_DIRECTORY"); dir != nullptr && *dir != '\0') {
    std::string first(dir);
    return first.substr(0, first.find(':'));  // systemd lists several with ':'
  }
  if (const char* dir = std::getenv("XDG_STATE_HOME"); dir != nullptr && *dir != '\0') {
    return std::string(dir) + "/totalgrad-worker";
  }
  if (const char* home = std::getenv("HOME"); home != nullptr && *home != '\0') {
    return std::string(home) + "/.local/state/totalgrad-worker";
  }
  return "/var/tmp/totalgrad-worker-" + std::to_string(getuid());
}

int ExitCode(const totalgrad::worker::WorkerSummary& summary) {
  switch (summary.exit) {
    case totalgrad::worker::WorkerExit::kDone: return 0;
    case totalgrad::worker::WorkerExit::kAuthRefused: return totalgrad::worker::kExitAuthRefused;
    case totalgrad::worker::WorkerExit::kWorkerIdInUse: return totalgrad::worker::kExitWorkerIdInUse;
    case totalgrad::worker::WorkerExit::kCoordinatorUnreachable:
      return totalgrad::worker::kExitCoordinatorUnreachable;
  }
  return 1;
}

// Every flag's value (the defaults shown in --help) before it becomes the
// worker's options.
struct Flags {
  totalgrad::rpc::ConnectionOptions connection;
  totalgrad::worker::WorkerOptions options;
  std::string token_file;
  int threads_per_slot = 1;
  double drain_seconds = 60, max_idle_seconds = -1, acquire_wait_seconds = 20;
  double report_grace_seconds = 5;
  double worker_id_wait_seconds = 120;
  double max_unreachable_seconds = 600;
  double walltime_seconds = -1, trial_seconds = 0;
};

Flags DefaultFlags() {
  Flags flags;
  flags.options.slots = std::max(1u, std::thread::hardware_concurrency());
  flags.options.host = HostName();
  flags.options.worker_id = flags.options.host + "-" + std::to_string(getpid());
  // The BLAS kernels change a trial's last bits: they are part of its provenance.
  flags.options.build = totalgrad::BuildId() + " blas " + totalgrad::BlasCoreName();
  flags.options.state_dir = DefaultStateDir();
  return flags;
}

// A duration flag in seconds, its default shown in --help, its range
// checked by `range` (a negative value is an error unless the flag says
// what it means).
void AddSeconds(CLI::App& app, const std::string& name, double& seconds,
                const CLI::Validator& range, const std::string& help) {
  app.add_option(name, seconds, help)->check(range)->capture_default_str();
}

// Declares every flag on `app`, bound to `flags`.
void AddFlags(CLI::App& app, Flags& flags) {
  app.add_option("--coordinator", flags.connection.target, "coordinator host:port")->required();
  app.add_option("--slots", flags.options.slots, "trials run at once (default: one per core)")
      ->check(CLI::Range(1, 4096))
      ->capture_default_str();
  app.add_option("--threads-per-slot", flags.threads_per_slot,
                 "threads each trial runs on (default 1); results are the same bits for any "
                 "value, so a job gives the same numbers on any worker")
      ->check(CLI::Range(1, 256))
      ->capture_default_str();
  app.add_option("--token-file", flags.token_file, "file holding the worker token");
  app.add_option("--ca-cert", flags.connection.ca_cert_file, "CA certificate to trust (PEM)");
  app.add_option("--client-cert", flags.connection.client_cert_file, "client certificate (PEM)");
  app.add_option("--client-key", flags.connection.client_key_file, "client key (PEM)");
  app.add_option("--tls-server-name", flags.connection.tls_server_name,
                 "expected name in the server certificate (default: the host)");
  app.add_flag("--insecure", flags.connection.insecure,
               "plaintext; only to a loopback coordinator");
  app.add_option("--worker-id", flags.options.worker_id, "unique id of this worker")
      ->capture_default_str();
  AddSeconds(app, "--drain-timeout", flags.drain_seconds, CLI::NonNegativeNumber,
             "seconds running trials get to finish after SIGTERM (then --report-grace for the "
             "final reports)");
  AddSeconds(app, "--report-grace", flags.report_grace_seconds, CLI::NonNegativeNumber,
             "seconds final reports get after --drain-timeout before they are kept in "
             "--state-dir instead");
  app.add_option("--state-dir", flags.options.state_dir,
                 "directory for this worker id's lock and its spool of undelivered results "
                 "(replayed by the next worker with the same id on this host)")
      ->capture_default_str();
  AddSeconds(app, "--worker-id-wait", flags.worker_id_wait_seconds, CLI::NonNegativeNumber,
             "seconds to wait while the coordinator says another live worker uses this "
             "--worker-id before exiting with code 78");
  AddSeconds(app, "--max-idle", flags.max_idle_seconds, CLI::Number,
             "exit after this many seconds without work, time without a coordinator included "
             "(negative: never)");
  AddSeconds(app, "--max-unreachable", flags.max_unreachable_seconds, CLI::PositiveNumber,
             "exit with code 69 after this many seconds in which the coordinator never answered "
             "and no trial ran (codes: 0 done, 69 no coordinator, 77 token refused, 78 worker "
             "id in use)");
  AddSeconds(app, "--acquire-wait", flags.acquire_wait_seconds, CLI::NonNegativeNumber,
             "long-poll length, seconds");
  // Batch allocations (deploy/slurm): drain --trial-time before the end of
  // --walltime, so no trial is taken that cannot finish in time.
  AddSeconds(app, "--walltime", flags.walltime_seconds, CLI::Number,
             "seconds this worker may run (e.g. what is left of a batch allocation); it drains "
             "--trial-time before the end, taking no trial it cannot finish (negative: no end)");
  AddSeconds(app, "--trial-time", flags.trial_seconds, CLI::NonNegativeNumber,
             "longest expected trial, seconds (with --walltime)");
  app.add_option("--speed-factor", flags.options.speed_factor,
                 "this machine's seconds per second of the trial cost model's reference machine "
                 "(with --walltime: a leased trial whose estimate times this exceeds the time "
                 "left is given back unstarted)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
}

// Reads the token file and turns the flags' seconds into the worker's
// options; false (after a log line) if the token file is unusable.
bool ApplyFlags(Flags& flags) {
  if (!flags.token_file.empty()) {
    auto token = totalgrad::ReadTokenFile(flags.token_file);
    if (!token.ok()) {
      spdlog::error("{}", token.status().ToString());
      return false;
    }
    if (!token->warning.empty()) spdlog::warn("{}", token->warning);
    flags.options.token = token->token;
    flags.connection.token = token->token;
  }
  flags.options.drain_timeout = absl::Seconds(flags.drain_seconds);
  flags.options.report_grace = absl::Seconds(flags.report_grace_seconds);
  flags.options.worker_id_wait = absl::Seconds(flags.worker_id_wait_seconds);
  flags.options.acquire_wait = absl::Seconds(flags.acquire_wait_seconds);
  if (flags.max_idle_seconds >= 0) {
    flags.options.max_idle = absl::Seconds(flags.max_idle_seconds);
  }
  flags.options.max_unreachable = absl::Seconds(flags.max_unreachable_seconds);
  if (flags.walltime_seconds >= 0) flags.options.walltime = absl::Seconds(flags.walltime_seconds);
  return true;
}

// The threads that end the worker from outside: the signal thread (the first
// SIGTERM/SIGINT drains, a second exits at once), the watchdog it starts, and
// the --walltime drain. All are detached and hold `worker` until the process
// exits (main ends with std::_Exit).
void StartShutdownThreads(totalgrad::worker::Worker& worker, const Flags& flags) {
  // A trial notices a cancellation between gradient steps, and a model fit
  // can take a while; after the drain timeout and the report grace a
  // watchdog exits anyway, keeping what is unfinished, so the shutdown a
  // supervisor (systemd, Kubernetes, Slurm) waits for is bounded.
  const auto hard_stop_after =
      flags.options.drain_timeout + flags.options.report_grace + absl::Seconds(5);
  std::thread signal_thread([&worker, hard_stop_after] {
    int signal_number = totalgrad::WaitForShutdownSignal();
    spdlog::info("signal {}: draining (send again to exit at once)", signal_number);
    worker.Drain();
    std::thread([&worker, hard_stop_after] {
      std::this_thread::sleep_for(
          std::chrono::milliseconds(absl::ToInt64Milliseconds(hard_stop_after)));
      spdlog::warn("still running {} after the signal: exiting now",
                   absl::FormatDuration(hard_stop_after));
      worker.Stop();
      const int kept = worker.SpoolUnfinished();
      spdlog::info("worker exits: {} unfinished attempts kept for the next worker", kept);
      std::_Exit(0);
    }).detach();
    signal_number = totalgrad::WaitForShutdownSignal();
    spdlog::info("signal {}: exiting at once", signal_number);
    worker.Stop();
    const int kept = worker.SpoolUnfinished();
    spdlog::info("worker exits: {} unfinished attempts kept for the next worker", kept);
    std::_Exit(0);
  });
  signal_thread.detach();
  if (flags.walltime_seconds >= 0) {
    const double drain_after = std::max(0.0, flags.walltime_seconds - flags.trial_seconds);
    std::thread([&worker, drain_after] {
      std::this_thread::sleep_for(std::chrono::duration<double>(drain_after));
      spdlog::info("walltime: less than --trial-time left; taking no new trial");
      worker.Drain();
    }).detach();
  }
}

}  // namespace

int main(int argc, char** argv) {
  totalgrad::SelectBlasKernels(argv);  // may re-execute this program (core/common/blas.h)
  CLI::App app{"totalgrad-worker: runs policy-learning trials leased from a coordinator"};
  Flags flags = DefaultFlags();
  AddFlags(app, flags);
  app.set_version_flag("--version", totalgrad::BuildId());
  CLI11_PARSE(app, argc, argv);
  spdlog::flush_on(spdlog::level::info);
  if (!ApplyFlags(flags)) return 2;
  const totalgrad::rpc::ConnectionOptions& connection = flags.connection;
  const totalgrad::worker::WorkerOptions& options = flags.options;

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
  auto* trials = new totalgrad::worker::LearnerTrialRunner(flags.threads_per_slot);
  auto* studies = new totalgrad::worker::CoreStudyRunner();
  auto* worker_ptr = new totalgrad::worker::Worker(
      options, *channel,
      {{totalgrad::v1::JOB_KIND_TRIAL, trials}, {totalgrad::v1::JOB_KIND_STUDY, studies}});
  totalgrad::worker::Worker& worker = *worker_ptr;
  StartShutdownThreads(worker, flags);
  // The first lease request waits for a connection up to --acquire-wait plus
  // the call timeout (35 s by default) before it fails: say at once when
  // nothing answers at the address, a typo or a coordinator not yet started.
  std::thread([channel = *channel, target = connection.target,
               max_unreachable = options.max_unreachable] {
    if (!channel->WaitForConnected(std::chrono::system_clock::now() + std::chrono::seconds(5))) {
      spdlog::warn("nothing answers at {} after 5 s: is the coordinator running there, and is the "
                   "address (--coordinator) right? The worker keeps trying for --max-unreachable "
                   "({})",
                   target, absl::FormatDuration(max_unreachable));
    }
  }).detach();
  spdlog::info("worker {} ({} slots x {} threads per trial) -> {} [{}]", options.worker_id,
               options.slots, flags.threads_per_slot, connection.target, options.build);
  const totalgrad::worker::WorkerSummary summary = worker.Run();
  spdlog::info("worker done: {} completed, {} failed, {} released, {} dropped, {} kept in the "
               "spool, {} replayed from it",
               summary.completed, summary.failed, summary.released, summary.dropped,
               summary.spooled, summary.replayed);
  if (summary.exit != totalgrad::worker::WorkerExit::kDone) {
    spdlog::error("worker exits with code {}: {}", ExitCode(summary), summary.exit_message);
  }
  // Detached threads (signals, walltime) may still hold the worker: end now.
  std::_Exit(ExitCode(summary));
}
