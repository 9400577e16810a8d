// What every service command shares: connection flags (with environment
// defaults), the stubs, calls with deadlines and retries, error reporting.
#ifndef TOTALGRAD_CLIENT_SERVICE_COMMANDS_CONNECTION_H_
#define TOTALGRAD_CLIENT_SERVICE_COMMANDS_CONNECTION_H_

#include <CLI/CLI.hpp>
#include <grpcpp/support/status.h>

#include <memory>
#include <optional>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "client/service_commands/format.h"
#include "results/comparison.h"
#include "results/diagnostics.h"
#include "results/stats.h"
#include "runtime/rpc_client.h"
#include "totalgrad/v1/control_service.grpc.pb.h"

namespace totalgrad::cli {

// Flags of every service command. Defaults come from the environment:
// TOTALGRAD_COORDINATOR (else 127.0.0.1:7070), TOTALGRAD_TOKEN_FILE,
// TOTALGRAD_CA_CERT, TOTALGRAD_INSECURE=1, TOTALGRAD_DB.
struct ServiceFlags {
  // A coordinator database to read directly instead of a coordinator
  // (local_store.h): reads work, writes are refused.
  std::string db;
  // Open `db` for writing (created when missing, locked as a coordinator
  // locks it): `results import --db` only; every other command reads.
  bool db_writable = false;
  // The coordinator's address and security (--coordinator, --insecure,
  // --ca-cert, --tls-server-name, --client-cert, --client-key); its token is
  // read from `token_file` when the connection opens.
  rpc::ConnectionOptions connection;
  std::string token_file;
  std::string format = "table";
  double timeout_seconds = 60;
  // How long to wait for a connection to the coordinator before giving up
  // with a hint (no coordinator there, or TLS against plaintext).
  double connect_timeout_seconds = 5;
};

// The defaults above read from the environment (the CLI's flags and the
// Python module's connections start from them).
ServiceFlags ServiceFlagsFromEnvironment();

// Adds the connection flags (and -f/--format when `with_format`) to `command`.
void AddConnectionFlags(CLI::App* command, ServiceFlags* flags, bool with_format = true);

class LocalCoordinator;  // local_store.h

class Connection {
 public:
  // InvalidArgument: bad flags (plaintext to a remote host, bad format);
  // NotFound: unreadable token or certificate file; Unavailable (within
  // --connect-timeout) naming what to do when nothing answers at the address
  // or the answer is not gRPC with the expected security; with --db, the
  // errors of SqliteStore::OpenReadOnly.
  static absl::StatusOr<Connection> Open(const ServiceFlags& flags);

  v1::ControlService::Stub* control() { return stub_.get(); }
  const std::string& token() const { return token_; }
  Format format() const { return format_; }
  const rpc::RetryPolicy& policy() const { return policy_; }

  // One unary call with deadline and retries.
  template <typename Request, typename Response>
  grpc::Status Call(grpc::Status (v1::ControlService::Stub::*method)(grpc::ClientContext*,
                                                                      const Request&, Response*),
                    const Request& request, Response* response) {
    return rpc::CallWithRetry(policy_, token_, [&](grpc::ClientContext* context) {
      return (stub_.get()->*method)(context, request, response);
    });
  }

 private:
  std::shared_ptr<LocalCoordinator> local_;  // --db: the in-process service
  std::shared_ptr<v1::ControlService::Stub> stub_;
  std::string token_;
  Format format_ = Format::kTable;
  rpc::RetryPolicy policy_;
};

// Adds subcommand `name` to `parent` with the connection flags (and
// -f/--format when `with_format`); its callback opens the connection and
// stores body's exit code in *exit_code. A connection error is reported,
// except that when no coordinator answers (UNAVAILABLE, DEADLINE_EXCEEDED)
// `offline` (may be null) is asked first: an exit code means it did the work
// without one; nullopt, report the error.
CLI::App* AddCommand(
    CLI::App* parent, const std::string& name, const std::string& help, int* exit_code,
    std::function<int(Connection*)> body, bool with_format = true,
    std::function<std::optional<int>(const absl::Status& unreachable)> offline = nullptr,
    bool db_writable = false);

// `results export` and `results import` (archive_commands.cc).
void AddArchiveCommands(CLI::App* results, int* exit_code);
// Sends the archive file to the connection's ImportSweep (`results import`).
// INVALID_ARGUMENT naming the file when it cannot be read; else the call's status.
grpc::Status ImportArchive(Connection* connection, const std::string& archive,
                           v1::ImportSweepResponse* response);
// "created sweep NAME: 12 jobs taken over (...)": what `results import` prints.
std::string ImportSummary(const v1::ImportSweepResponse& response);
// `sweep delete`: archives the sweep to a file, then deletes it
// (archive_commands.cc).
void AddSweepDeleteCommand(CLI::App* sweep, int* exit_code);
// `sweep size` and `sweep prune` (disk_commands.cc).
void AddSweepDiskCommands(CLI::App* sweep, int* exit_code);

// The service commands' exit codes (also in `totalgrad --help`, README and
// docs/service.md).
inline constexpr int kExitFailed = 1;    // the operation failed (or a waited sweep did)
inline constexpr int kExitBadInput = 2;  // malformed file, unknown name, bad token
inline constexpr int kExitUnreachable = 3;  // no answer from the coordinator
// The coordinator answered but cannot do it: its store is full, failing,
// deleted or locked by another process (server-side UNAVAILABLE, INTERNAL,
// RESOURCE_EXHAUSTED, DATA_LOSS; rpc::AnsweredByCoordinator).
inline constexpr int kExitCoordinatorRefused = 4;

// Prints "error: <what>: <message>" and returns the exit code for `status`:
// kExitUnreachable for UNAVAILABLE/DEADLINE_EXCEEDED that the gRPC library
// made (no answer), kExitCoordinatorRefused for UNAVAILABLE, DEADLINE_EXCEEDED,
// INTERNAL, RESOURCE_EXHAUSTED and DATA_LOSS that the coordinator answered
// with, kExitBadInput for INVALID_ARGUMENT/NOT_FOUND/ALREADY_EXISTS/
// UNAUTHENTICATED/PERMISSION_DENIED, kExitFailed otherwise.
int ReportError(const grpc::Status& status, const std::string& what);
int ReportError(const absl::Status& status, const std::string& what);
// A gRPC status as an absl::Status (the codes are the same numbers).
absl::Status ToAbslStatus(const grpc::Status& status);

// Shared helpers of the commands.
std::string StateName(v1::JobState state);
std::string StateName(v1::SweepState state);
std::string FormatTime(int64_t unix_ms);

// Polls the sweep until it is finished, drawing a progress bar on stderr.
// Returns 0 if every job completed, 1 if any failed or was cancelled, or an
// error exit code. `stop` (may be null) ends the wait early (exit code 130).
int WaitForSweep(Connection* connection, const std::string& sweep_name,
                 const std::atomic<bool>* stop = nullptr);

// WaitForSweep for `sweep submit --wait` and `sweep status --wait`: Ctrl-C
// (SIGINT) ends the wait, not the sweep, and says so on stderr with the
// commands that follow or cancel it; exit code 130. The previous SIGINT
// disposition is restored before returning.
int WaitForSweepUntilInterrupted(Connection* connection, const std::string& sweep_name);

// The results table of a sweep (the paper's Table 1 layout), printed; with
// a `plot_path`, also drawn there (success_plot.h; .svg, .pdf or .png).
int PrintResultsTable(Connection* connection, const std::string& sweep_name, Format format,
                      const std::string& plot_path = "");
// The rows of a sweep's study jobs (study_results.cc): table format prints
// the reference gradients then the cells (only the references with
// `references`); csv/json print the cells, or with `references` the
// reference gradients, with every stored column.
// With a `plot_dir`, also draws each study's work-precision and horizon-sweep
// plots (PNG and PDF, `totalgrad study`'s) into plot_dir/<study>/.
int PrintStudyResults(Connection* connection, const std::string& sweep_name, Format format,
                      bool references, bool all_attempts, std::ostream& out,
                      const std::string& plot_dir = "");
// The paired comparisons of the sweep's methods (compare.cc; `results compare`).
int PrintComparison(Connection* connection, const std::string& sweep_name,
                    const results::ComparisonOptions& options, Format format);
// The estimator statistics of a sweep's trials per method, variant and
// episode (`results diagnostics`, results/diagnostics.h): every statistic,
// or `statistic` alone; InvalidArgument naming the closest statistic for an
// unknown one, else the call's status.
absl::StatusOr<std::vector<results::DiagnosticPoint>> ReadDiagnostics(
    Connection* connection, const std::string& sweep_name, const std::string& statistic);
// Its -f json/csv rows: one per comparison, the verdicts at `alpha` last
// (the Python module's `compare` reads the same rows).
Listing ComparisonListing(const results::ComparisonReport& report, double alpha);
// The evaluation cost of every episode of the sweep's completed trials (each
// job's counting attempt), in export order, with its job id as the run.
absl::StatusOr<std::vector<results::EpisodeValue>> ReadEvaluationCosts(Connection* connection,
                                                                       const std::string& sweep_name);
// `results curves`' table: method, variant, episode, trials, q25, median,
// q75, mean, standard_error, numbers to 2 decimals. (-f csv|json write the
// points through results::CurvePointFields(), as the Python module does.)
Listing CurvesListing(const std::vector<results::CurvePoint>& curves);
// Per-method curves (median, quartiles, mean and its standard error over
// the completed trials); optionally a gnuplot picture at `plot_path` (.svg,
// .pdf or .png; curves_plot.h). With `top` > 0 the picture is the paper's
// Figure 3: per variant, all runs' median and quartiles, their mean and
// standard error, and the median and quartiles of the `top` best runs.
int PrintCurves(Connection* connection, const std::string& sweep_name, Format format,
                const std::string& plot_path, bool print_table, int top = 0);

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_SERVICE_COMMANDS_CONNECTION_H_
