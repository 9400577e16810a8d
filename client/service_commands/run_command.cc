// `totalgrad run FILE`: the embedded single-machine default. Starts a
// coordinator on a local SQLite file and one worker per core on loopback,
// runs the sweep with the usual progress display, prints the results table
// and the curves plot, then stops them (workers first, then coordinator).
//
// Everything goes through the same binaries and RPCs as a multi-machine
// deployment, so `run` exercises the real service. The database stays, so
// running the same file again is a no-op that prints the stored results.
#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <random>
#include <thread>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "client/service_commands/connection.h"
#include "client/service_commands/service_commands.h"
#include "server/sweep/sweep_proto.h"
#include "server/sweep/sweep_spec.h"

namespace totalgrad::cli {
namespace {

std::atomic<bool> g_interrupted{false};
void OnInterrupt(int) { g_interrupted = true; }

// The executable `name`: next to this program's build tree, beside it, or on PATH.
std::string FindProgram(const std::string& name, const std::string& build_subdir) {
  std::error_code error;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", error);
  if (!error) {
    for (const std::filesystem::path& candidate :
         {self.parent_path().parent_path() / build_subdir / name, self.parent_path() / name}) {
      if (access(candidate.c_str(), X_OK) == 0) return candidate.string();
    }
  }
  const char* path = std::getenv("PATH");
  for (absl::string_view dir : absl::StrSplit(path ? path : "", ':')) {
    const std::string candidate = absl::StrCat(dir, "/", name);
    if (!dir.empty() && access(candidate.c_str(), X_OK) == 0) return candidate;
  }
  return "";
}

std::string RandomToken() {
  std::random_device random;
  static constexpr char kHex[] = "0123456789abcdef";
  std::string token;
  for (int i = 0; i < 40; ++i) token.push_back(kHex[random() % 16]);
  return token;
}

bool WriteSecret(const std::string& path, const std::string& text) {
  const int fd = open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  if (fd < 0) return false;
  const bool ok = write(fd, text.data(), text.size()) == static_cast<ssize_t>(text.size());
  close(fd);
  return ok;
}

// Starts `argv` with stdout/stderr to `log`; the child gets SIGTERM if we die.
pid_t Spawn(const std::vector<std::string>& argv, const std::string& log) {
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid != 0) return pid;
  // Child: only async-signal-safe calls until exec.
  prctl(PR_SET_PDEATHSIG, SIGTERM);
  if (getppid() != parent) _exit(127);
  setpgid(0, 0);  // our Ctrl-C is handled by `run`, which stops children in order
  const int fd = open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
  if (fd >= 0) {
    dup2(fd, STDOUT_FILENO);
    dup2(fd, STDERR_FILENO);
    close(fd);
  }
  execv(args[0], args.data());
  _exit(127);
}

bool Alive(pid_t pid) {
  int status = 0;
  return waitpid(pid, &status, WNOHANG) == 0;
}

// SIGTERM, then SIGKILL after `grace`.
void Terminate(const std::vector<pid_t>& pids, std::chrono::seconds grace) {
  for (pid_t pid : pids) kill(pid, SIGTERM);
  const auto deadline = std::chrono::steady_clock::now() + grace;
  for (pid_t pid : pids) {
    while (Alive(pid) && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    if (Alive(pid)) {
      kill(pid, SIGKILL);
      waitpid(pid, nullptr, 0);
    }
  }
}

int FreeLoopbackPort() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return -1;
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  address.sin_port = 0;
  socklen_t length = sizeof(address);
  int port = -1;
  if (bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)) == 0 &&
      getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length) == 0) {
    port = ntohs(address.sin_port);
  }
  close(fd);
  return port;
}

struct RunFlags {
  std::string file;
  int workers = std::max(1u, std::thread::hardware_concurrency());
  std::string dir = "out/run";
  std::string db;
  std::string plot;
  bool no_plot = false;
  double heartbeat_seconds = 15;
  double lease_timeout_seconds = 90;
  std::string format = "table";
};

// What `run` starts and where its files are (beside the database).
struct LocalService {
  std::string base;  // DIR/<sweep>: the prefix of every file
  std::string db;
  std::string user_token_file;
  std::string port_file;
  std::string coordinator_log;
  std::string address;  // the coordinator's gRPC address on loopback
  int http_port = 0;
  pid_t coordinator = -1;
  std::vector<pid_t> workers;
};

// Starts the coordinator on a loopback port of the system's choosing (read
// back from its port file) and `flags.workers` workers. 0, or 1 having said
// why and stopped whatever it started.
int StartLocalService(const RunFlags& flags, const std::string& sweep_name,
                      LocalService* service) {
  const std::string coordinator_bin = FindProgram("totalgrad-coordinator", "server");
  const std::string worker_bin = FindProgram("totalgrad-worker", "worker");
  if (coordinator_bin.empty() || worker_bin.empty()) {
    std::cerr << "error: run: cannot find totalgrad-coordinator and totalgrad-worker next to "
                 "this program or on PATH (build them: cmake --build build)\n";
    return 1;
  }
  std::error_code error;
  std::filesystem::create_directories(flags.dir, error);
  if (error) {
    std::cerr << "error: run: cannot create " << flags.dir << ": " << error.message() << "\n";
    return 1;
  }
  const std::string base = (std::filesystem::path(flags.dir) / sweep_name).string();
  service->base = base;
  service->db = flags.db.empty() ? base + ".db" : flags.db;
  const std::string worker_token = RandomToken(), user_token = RandomToken();
  const std::string worker_token_file = base + ".worker-token";
  service->user_token_file = base + ".user-token";
  service->port_file = base + ".port";
  // The dashboard's port: one the system has just handed out (bound and
  // released here; another process taking it in between is unlikely on a
  // workstation, and then the coordinator reports it and the run stops).
  service->http_port = FreeLoopbackPort();
  if (service->http_port <= 0) {
    std::cerr << "error: run: no free loopback port for the dashboard\n";
    return 1;
  }
  if (!WriteSecret(worker_token_file, worker_token) ||
      !WriteSecret(service->user_token_file, user_token)) {
    std::cerr << "error: run: cannot write token files in " << flags.dir << "\n";
    return 1;
  }
  std::filesystem::remove(service->port_file, error);

  service->coordinator_log = base + "-coordinator.log";
  service->coordinator = Spawn(
      {coordinator_bin, "--db", service->db, "--listen", "127.0.0.1:0", "--insecure",
       "--worker-token-file", worker_token_file, "--user-token-file", service->user_token_file,
       "--port-file", service->port_file, "--heartbeat-interval",
       absl::StrCat(flags.heartbeat_seconds), "--lease-timeout",
       absl::StrCat(flags.lease_timeout_seconds), "--http-listen",
       absl::StrCat("127.0.0.1:", service->http_port)},
      service->coordinator_log);
  int port = 0;
  for (int i = 0; i < 600 && port == 0; ++i) {  // up to 30 s
    std::ifstream in(service->port_file);
    if (in >> port && port > 0) break;
    port = 0;
    if (!Alive(service->coordinator) || g_interrupted) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  if (port == 0) {
    std::cerr << "error: run: the coordinator did not start; see " << service->coordinator_log
              << "\n";
    Terminate({service->coordinator}, std::chrono::seconds(5));
    return 1;
  }
  service->address = absl::StrCat("127.0.0.1:", port);
  // Stable worker ids and a state directory beside the database: after a
  // Ctrl-C, worker i of the next `run` replays what worker i kept (results
  // not yet delivered when it had to stop).
  for (int i = 0; i < flags.workers; ++i) {
    service->workers.push_back(
        Spawn({worker_bin, "--coordinator", service->address, "--insecure", "--token-file",
               worker_token_file, "--slots", "1", "--worker-id", absl::StrCat("run-", i),
               "--state-dir", base + "-worker-state", "--drain-timeout", "5", "--acquire-wait",
               "5"},
              absl::StrCat(base, "-worker-", i, ".log")));
  }
  std::cerr << "coordinator on " << service->address << " (database " << service->db << ", log "
            << service->coordinator_log << "), " << flags.workers << " workers\n";
  std::cerr << "dashboard: http://127.0.0.1:" << service->http_port
            << "/ while this runs (the page asks for the user token: "
            << service->user_token_file << ")\n";
  return 0;
}

// What `run` prints once the sweep is done: the results table (and a
// study's rows), the paired comparison and the curves with their plot.
// Returns `code`, or the first failure of a printout if `code` is 0.
int PrintRunResults(Connection* connection, const sweep::SweepSpec& spec, Format format,
                    const std::string& plot, const std::string& db, int code) {
  int table = 0;
  if (!spec.grid.empty()) table = PrintResultsTable(connection, spec.name, format);
  if (!spec.studies.empty()) {
    if (!spec.grid.empty() && format == Format::kTable) std::cout << "\n";
    const int study = PrintStudyResults(connection, spec.name, format, /*references=*/false,
                                        /*all_attempts=*/false, std::cout);
    if (table == 0) table = study;
  }
  if (!spec.grid.empty() && format == Format::kTable) {
    // The story of the sweep: which method is better, and how they learned.
    std::cout << "\n";
    const int compared =
        PrintComparison(connection, spec.name, results::ComparisonOptions(), format);
    if (compared != 0 && code == 0) code = compared;
    std::cout << "\n";
  }
  if (!spec.grid.empty()) {
    const int curves = PrintCurves(connection, spec.name, format, plot,
                                   /*print_table=*/format == Format::kTable);
    if (curves != 0 && code == 0) code = curves;
  }
  if (table != 0 && code == 0) code = table;
  std::cerr << "results stored in " << db << "; read them any time without a "
            << "coordinator, e.g. `totalgrad results table " << spec.name << " --db " << db
            << "`, `totalgrad results compare " << spec.name << " --db " << db
            << "`, or in Python: pandas.read_sql('SELECT * FROM \"episodes/" << spec.name
            << "\"', sqlite3.connect('" << db << "')) (docs/results_schema.md)\n";
  return code;
}

// Submits the sweep to the local coordinator, waits for it with the usual
// progress display and prints its results. The exit code of `run`.
int SubmitAndReport(const RunFlags& flags, const sweep::SweepSpec& spec, const std::string& source,
                    Format format, const LocalService& service) {
  ServiceFlags service_flags;
  service_flags.connection.target = service.address;
  service_flags.connection.insecure = true;
  service_flags.token_file = service.user_token_file;
  service_flags.format = flags.format;
  absl::StatusOr<Connection> connection = Connection::Open(service_flags);
  if (!connection.ok()) return ReportError(connection.status(), "run");
  if (absl::StatusOr<sweep::SweepCostEstimate> cost = sweep::EstimateSweepCost(spec); cost.ok()) {
    std::cerr << "estimated cost: " << cost->Text() << "\n";
  }
  v1::SubmitSweepRequest request;
  sweep::SweepSpecToProto(spec, request.mutable_spec());
  request.set_source_name(flags.file);
  request.set_source_text(source);
  v1::SubmitSweepResponse response;
  const grpc::Status status =
      connection->Call(&v1::ControlService::Stub::SubmitSweep, request, &response);
  if (!status.ok()) return ReportError(status, "run: submit " + flags.file);
  if (response.jobs_added() > 0) {
    std::cerr << "grew sweep " << spec.name << " by " << response.jobs_added() << " jobs (now "
              << response.sweep().jobs_total() << ")\n";
  } else {
    std::cerr << (response.created() ? "submitted" : "already in the database") << ": sweep "
              << spec.name << ", " << response.sweep().jobs_total() << " jobs\n";
  }
  const int code = WaitForSweep(&*connection, spec.name, &g_interrupted);
  if (code == 130) {
    std::cerr << "interrupted: stopping the workers (running trials are released) and the "
                 "coordinator; run the same file again to continue the sweep\n";
  }
  if (code != 0 && code != 1) return code;
  const std::string plot =
      flags.no_plot ? "" : (flags.plot.empty() ? service.base + "-curves.svg" : flags.plot);
  return PrintRunResults(&*connection, spec, format, plot, service.db, code);
}

int Run(const RunFlags& flags) {
  std::string source;
  absl::StatusOr<sweep::SweepSpec> spec = sweep::LoadSweepFile(flags.file, &source);
  if (!spec.ok()) {
    std::cerr << "error: " << spec.status().message() << "\n";
    return 2;
  }
  Format format;
  if (!ParseFormat(flags.format, &format)) return 2;
  struct sigaction action = {};
  action.sa_handler = OnInterrupt;
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
  LocalService service;
  if (const int started = StartLocalService(flags, spec->name, &service); started != 0) {
    return started;
  }
  const int code = SubmitAndReport(flags, *spec, source, format, service);
  Terminate(service.workers, std::chrono::seconds(15));
  Terminate({service.coordinator}, std::chrono::seconds(15));
  std::error_code error;
  std::filesystem::remove(service.port_file, error);
  return code;
}

}  // namespace

void AddRunCommand(CLI::App* app, int* exit_code) {
  auto flags = std::make_shared<RunFlags>();
  CLI::App* run = app->add_subcommand(
      "run", "run a sweep file on this machine: coordinator + one worker per core on loopback");
  run->add_option("FILE", flags->file, "sweep file (TOML)")->required();
  run->add_option("--workers", flags->workers, "worker processes (default: one per core)")
      ->check(CLI::Range(1, 1024))
      ->capture_default_str();
  run->add_option("--dir", flags->dir, "where the database, logs and plot go")->capture_default_str();
  run->add_option("--db", flags->db, "SQLite file (default: DIR/<sweep>.db)");
  run->add_option("--plot", flags->plot, "curves picture (default: DIR/<sweep>-curves.svg)");
  run->add_flag("--no-plot", flags->no_plot, "draw no picture");
  run->add_option("--heartbeat-interval", flags->heartbeat_seconds, "seconds")->capture_default_str();
  run->add_option("--lease-timeout", flags->lease_timeout_seconds, "seconds")->capture_default_str();
  run->add_option("-f,--format", flags->format, "results table: table, json or csv")
      ->check(CLI::IsMember({"table", "json", "csv"}))
      ->capture_default_str();
  run->callback([flags, exit_code] { *exit_code = Run(*flags); });
}

}  // namespace totalgrad::cli
