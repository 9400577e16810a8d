#include "client/service_commands/connection.h"

#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <set>
#include <sstream>
#include <thread>

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "runtime/status_origin.h"
#include "runtime/token_file.h"
#include "absl/time/time.h"
#include "client/service_commands/curves_plot.h"
#include "client/service_commands/success_plot.h"
#include "client/service_commands/local_store.h"
#include "client/service_commands/rpc_results_reader.h"
#include "results/stats.h"

namespace totalgrad::cli {

using results::CurvePoint;
using results::EpisodeValue;
using results::TableCell;

namespace {

std::string Env(const char* name, const std::string& fallback) {
  const char* value = std::getenv(name);
  return value != nullptr && *value != '\0' ? std::string(value) : fallback;
}

const char* CodeName(grpc::StatusCode code) {
  switch (code) {
    case grpc::StatusCode::OK: return "OK";
    case grpc::StatusCode::CANCELLED: return "CANCELLED";
    case grpc::StatusCode::UNKNOWN: return "UNKNOWN";
    case grpc::StatusCode::INVALID_ARGUMENT: return "INVALID_ARGUMENT";
    case grpc::StatusCode::DEADLINE_EXCEEDED: return "DEADLINE_EXCEEDED";
    case grpc::StatusCode::NOT_FOUND: return "NOT_FOUND";
    case grpc::StatusCode::ALREADY_EXISTS: return "ALREADY_EXISTS";
    case grpc::StatusCode::PERMISSION_DENIED: return "PERMISSION_DENIED";
    case grpc::StatusCode::RESOURCE_EXHAUSTED: return "RESOURCE_EXHAUSTED";
    case grpc::StatusCode::FAILED_PRECONDITION: return "FAILED_PRECONDITION";
    case grpc::StatusCode::ABORTED: return "ABORTED";
    case grpc::StatusCode::OUT_OF_RANGE: return "OUT_OF_RANGE";
    case grpc::StatusCode::UNIMPLEMENTED: return "UNIMPLEMENTED";
    case grpc::StatusCode::INTERNAL: return "INTERNAL";
    case grpc::StatusCode::UNAVAILABLE: return "UNAVAILABLE";
    case grpc::StatusCode::DATA_LOSS: return "DATA_LOSS";
    case grpc::StatusCode::UNAUTHENTICATED: return "UNAUTHENTICATED";
    default: return "UNKNOWN";
  }
}

}  // namespace

ServiceFlags ServiceFlagsFromEnvironment() {
  ServiceFlags flags;
  flags.connection.target = Env("TOTALGRAD_COORDINATOR", "127.0.0.1:7070");
  flags.token_file = Env("TOTALGRAD_TOKEN_FILE", "");
  flags.connection.ca_cert_file = Env("TOTALGRAD_CA_CERT", "");
  flags.connection.insecure = Env("TOTALGRAD_INSECURE", "") == "1";
  flags.db = Env("TOTALGRAD_DB", "");
  return flags;
}

void AddConnectionFlags(CLI::App* command, ServiceFlags* flags, bool with_format) {
  const ServiceFlags environment = ServiceFlagsFromEnvironment();
  flags->connection = environment.connection;
  flags->token_file = environment.token_file;
  flags->db = environment.db;
  command->add_option("--coordinator", flags->connection.target,
                      "coordinator host:port [env TOTALGRAD_COORDINATOR]")
      ->capture_default_str();
  command->add_option("--token-file", flags->token_file,
                      "file holding the user token [env TOTALGRAD_TOKEN_FILE]");
  command->add_option("--ca-cert", flags->connection.ca_cert_file, "CA certificate to trust [env TOTALGRAD_CA_CERT]");
  command->add_option("--tls-server-name", flags->connection.tls_server_name,
                      "expected name in the server certificate");
  command->add_option("--client-cert", flags->connection.client_cert_file,
                      "client certificate (PEM), for coordinators that require one");
  command->add_option("--client-key", flags->connection.client_key_file, "client key (PEM)");
  command->add_flag("--insecure", flags->connection.insecure,
                    "plaintext; only to a loopback coordinator [env TOTALGRAD_INSECURE=1]");
  command->add_option("--timeout", flags->timeout_seconds, "seconds per call")
      ->capture_default_str();
  command->add_option("--connect-timeout", flags->connect_timeout_seconds,
                      "seconds to wait for the coordinator to answer before giving up")
      ->capture_default_str();
  command->add_option("--db", flags->db,
                      "read this coordinator database file directly instead of asking a "
                      "coordinator (read-only; safe while a coordinator writes it) [env TOTALGRAD_DB]");
  if (with_format) {
    command->add_option("-f,--format", flags->format, "output: table, json or csv")
        ->check(CLI::IsMember({"table", "json", "csv"}))
        ->capture_default_str();
  }
}

absl::StatusOr<Connection> Connection::Open(const ServiceFlags& flags) {
  Connection connection;
  if (!ParseFormat(flags.format, &connection.format_)) {
    return absl::InvalidArgumentError(absl::StrCat("--format: '", flags.format,
                                                   "' is not table, json or csv"));
  }
  connection.policy_.call_timeout = absl::Seconds(flags.timeout_seconds);
  connection.policy_.give_up_after = absl::Seconds(flags.timeout_seconds);
  connection.policy_.wait_for_ready = false;
  connection.policy_.retry_coordinator_answers = false;  // a refusal is reported at once
  if (!flags.db.empty()) {
    absl::StatusOr<std::shared_ptr<LocalCoordinator>> local = LocalCoordinator::Open(flags.db, flags.db_writable);
    if (!local.ok()) return local.status();
    connection.local_ = *std::move(local);
    connection.stub_ = v1::ControlService::NewStub(connection.local_->channel());
    return connection;
  }
  if (!flags.token_file.empty()) {
    absl::StatusOr<TokenFile> token = ReadTokenFile(flags.token_file);
    if (!token.ok()) return token.status();
    if (!token->warning.empty()) std::cerr << "warning: " << token->warning << "\n";
    connection.token_ = token->token;
  }
  absl::StatusOr<std::shared_ptr<grpc::Channel>> channel = rpc::MakeChannel(flags.connection);
  if (!channel.ok()) return channel.status();
  // Fail fast, with what to do, when nothing usable answers: retrying for the
  // whole call timeout only hides the cause.
  const auto deadline = std::chrono::system_clock::now() +
                        std::chrono::milliseconds(static_cast<int64_t>(
                            1000 * std::max(0.1, flags.connect_timeout_seconds)));
  if (!(*channel)->WaitForConnected(deadline)) {
    const std::string security =
        flags.connection.insecure ? "plaintext, --insecure" : "TLS";
    return absl::UnavailableError(absl::StrCat(
        "no coordinator answered at ", flags.connection.target, " within ",
        flags.connect_timeout_seconds, " s (", security,
        "). Start one (`totalgrad-coordinator --db FILE ...`, or `totalgrad run SWEEP.toml` on "
        "this machine), or point to it with --coordinator / TOTALGRAD_COORDINATOR, or read a "
        "database file without a coordinator with --db FILE. If a coordinator does run there, "
        "check that both sides use ",
        flags.connection.insecure ? "plaintext (the coordinator was started with --insecure)"
                       : "TLS (--ca-cert here, --tls-cert/--tls-key there; or --insecure on both "
                         "for loopback)"));
  }
  connection.stub_ = v1::ControlService::NewStub(*channel);
  return connection;
}

CLI::App* AddCommand(
    CLI::App* parent, const std::string& name, const std::string& help, int* exit_code,
    std::function<int(Connection*)> body, bool with_format,
    std::function<std::optional<int>(const absl::Status& unreachable)> offline,
    bool db_writable) {
  CLI::App* command = parent->add_subcommand(name, help);
  auto flags = std::make_shared<ServiceFlags>();
  AddConnectionFlags(command, flags.get(), with_format);
  // Writing takes an explicit --db: TOTALGRAD_DB names a file to read.
  if (db_writable) flags->db.clear();
  flags->db_writable = db_writable;
  command->callback([flags, exit_code, body = std::move(body), offline = std::move(offline), name] {
    absl::StatusOr<Connection> connection = Connection::Open(*flags);
    const absl::StatusCode code = connection.status().code();
    if (!connection.ok() && offline != nullptr &&
        (code == absl::StatusCode::kUnavailable || code == absl::StatusCode::kDeadlineExceeded)) {
      if (std::optional<int> done = offline(connection.status()); done.has_value()) {
        *exit_code = *done;
        return;
      }
    }
    if (!connection.ok()) {
      *exit_code = ReportError(connection.status(), name);
      return;
    }
    *exit_code = body(&*connection);
  });
  return command;
}

int ReportError(const grpc::Status& status, const std::string& what) {
  std::cerr << "error: " << what << ": " << CodeName(status.error_code()) << ": "
            << status.error_message() << "\n";
  const bool refused = rpc::AnsweredByCoordinator(status);
  switch (status.error_code()) {
    case grpc::StatusCode::UNAVAILABLE:
    case grpc::StatusCode::DEADLINE_EXCEEDED:
      if (refused) break;
      return kExitUnreachable;
    case grpc::StatusCode::INVALID_ARGUMENT:
    case grpc::StatusCode::NOT_FOUND:
    case grpc::StatusCode::ALREADY_EXISTS:
    case grpc::StatusCode::UNAUTHENTICATED:
    case grpc::StatusCode::PERMISSION_DENIED:
      return kExitBadInput;
    case grpc::StatusCode::INTERNAL:
    case grpc::StatusCode::RESOURCE_EXHAUSTED:
    case grpc::StatusCode::DATA_LOSS:
      if (refused) break;
      return kExitFailed;
    default:
      return kExitFailed;
  }
  std::cerr << "(the coordinator answered: it cannot do this now; see its log and "
               "`totalgrad admin health`)\n";
  return kExitCoordinatorRefused;
}

absl::Status ToAbslStatus(const grpc::Status& status) {
  return absl::Status(static_cast<absl::StatusCode>(status.error_code()), status.error_message());
}

int ReportError(const absl::Status& status, const std::string& what) {
  return ReportError(grpc::Status(static_cast<grpc::StatusCode>(status.code()),
                                  std::string(status.message())),
                     what);
}

std::string StateName(v1::JobState state) {
  switch (state) {
    case v1::JOB_STATE_QUEUED: return "queued";
    case v1::JOB_STATE_RUNNING: return "running";
    case v1::JOB_STATE_COMPLETED: return "completed";
    case v1::JOB_STATE_FAILED: return "failed";
    case v1::JOB_STATE_CANCELLED: return "cancelled";
    default: return "?";
  }
}

std::string StateName(v1::SweepState state) {
  switch (state) {
    case v1::SWEEP_STATE_RUNNING: return "running";
    case v1::SWEEP_STATE_PAUSED: return "paused";
    case v1::SWEEP_STATE_CANCELLED: return "cancelled";
    default: return "?";
  }
}

std::string FormatTime(int64_t unix_ms) {
  if (unix_ms <= 0) return "";
  return absl::FormatTime("%Y-%m-%d %H:%M:%S", absl::FromUnixMillis(unix_ms), absl::LocalTimeZone());
}

int WaitForSweep(Connection* connection, const std::string& sweep_name,
                 const std::atomic<bool>* stop) {
  const bool tty = isatty(STDERR_FILENO);
  std::string last_line;
  auto last_print = std::chrono::steady_clock::now() - std::chrono::hours(1);
  v1::SweepRequest request;
  request.set_name(sweep_name);
  v1::SweepInfo sweep;
  while (true) {
    if (stop != nullptr && stop->load()) {
      if (tty) std::cerr << "\n";
      return 130;
    }
    sweep.Clear();
    const grpc::Status status = connection->Call(&v1::ControlService::Stub::GetSweep, request, &sweep);
    if (!status.ok()) {
      if (tty) std::cerr << "\n";
      return ReportError(status, "sweep status " + sweep_name);
    }
    const int done = sweep.jobs_completed() + sweep.jobs_failed() + sweep.jobs_cancelled();
    const int total = std::max(1, sweep.jobs_total());
    constexpr int kWidth = 30;
    const int filled = kWidth * done / total;
    const std::string line = absl::StrCat(
        "[", std::string(filled, '#'), std::string(kWidth - filled, '.'), "] jobs ", done, "/",
        sweep.jobs_total(), " (", sweep.jobs_running(), " running, ", sweep.jobs_failed(),
        " failed)",
        // A sweep of study jobs only has no episodes to count.
        sweep.episodes_expected() > 0
            ? absl::StrCat(" episodes ", sweep.episodes_stored(), "/", sweep.episodes_expected())
            : std::string(),
        sweep.state() == v1::SWEEP_STATE_PAUSED ? " [paused]" : "");
    const auto now = std::chrono::steady_clock::now();
    if (tty) {
      std::cerr << "\r" << line << std::flush;
    } else if (line != last_line && (now - last_print > std::chrono::seconds(10) || sweep.finished())) {
      std::cerr << line << "\n";
      last_print = now;
    }
    last_line = line;
    if (sweep.finished()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
  if (tty) std::cerr << "\n";
  if (sweep.jobs_completed() == sweep.jobs_total()) return 0;
  std::cerr << "sweep " << sweep_name << " finished with " << sweep.jobs_failed() << " failed and "
            << sweep.jobs_cancelled() << " cancelled jobs";
  v1::ListJobsRequest jobs_request;
  jobs_request.set_sweep_name(sweep_name);
  jobs_request.add_states(v1::JOB_STATE_FAILED);
  jobs_request.set_page_size(5);
  v1::ListJobsResponse jobs;
  if (connection->Call(&v1::ControlService::Stub::ListJobs, jobs_request, &jobs).ok() &&
      jobs.jobs_size() > 0) {
    std::cerr << "; for example:";
    for (const auto& job : jobs.jobs()) {
      std::cerr << "\n  job " << job.job_id() << " (" << job.method() << " seed " << job.seed()
                << "): " << job.last_error();
    }
    std::cerr << "\n(see `totalgrad job logs ID`, retry with `totalgrad job retry ID`)";
  }
  std::cerr << "\n";
  return 1;
}

namespace {
std::atomic<bool> g_wait_interrupted{false};
void OnWaitInterrupted(int) { g_wait_interrupted = true; }
}  // namespace

int WaitForSweepUntilInterrupted(Connection* connection, const std::string& sweep_name) {
  g_wait_interrupted = false;
  struct sigaction action = {}, previous = {};
  action.sa_handler = OnWaitInterrupted;
  sigaction(SIGINT, &action, &previous);
  const int code = WaitForSweep(connection, sweep_name, &g_wait_interrupted);
  sigaction(SIGINT, &previous, nullptr);
  if (code == 130) {
    std::cerr << "interrupted: only the wait stopped; sweep " << sweep_name
              << " goes on at the coordinator (`totalgrad sweep status " << sweep_name
              << " --wait` follows it again, `totalgrad sweep cancel " << sweep_name
              << "` stops it)\n";
  }
  return code;
}

namespace {

// The success-rate picture of a sweep's table (`results table --plot`).
int PlotResultsTable(Connection* connection, const std::string& sweep_name,
                     const std::vector<TableCell>& cells, const std::string& plot_path) {
  SuccessPlotInput plot;
  plot.title = absl::StrCat("sweep ", sweep_name,
                            ": success rate per method with its 95% Wilson interval (successes/trials)");
  for (const TableCell& c : cells) {
    plot.points.push_back({c.variant, c.method, c.success});
  }
  std::vector<results::CurvePanel> panels;
  std::string problem = FetchCurvePanels(connection, sweep_name, &panels);
  for (const results::CurvePanel& panel : panels) {
    plot.panel_variants.push_back(panel.variant);
    plot.panel_titles.push_back(panel.title);
  }
  if (problem.empty()) problem = WriteSuccessPlot(plot, plot_path);
  return ReportPlot("table", plot_path, problem);
}

}  // namespace

int PrintResultsTable(Connection* connection, const std::string& sweep_name, Format format,
                      const std::string& plot_path) {
  RpcResultsReader reader(connection);
  const absl::StatusOr<std::vector<results::CompletedTrial>> trials =
      reader.CompletedTrials(sweep_name);
  if (!trials.ok()) return ReportError(trials.status(), "results table " + sweep_name);
  const std::vector<TableCell> cells = results::SuccessTable(*trials);
  if (format != Format::kTable) {
    // The cells' record, named as the dashboard's /api/sweep names them.
    PrintRecords(results::TableCellFields(), cells, format, std::cout);
    return plot_path.empty() ? 0 : PlotResultsTable(connection, sweep_name, cells, plot_path);
  }
  // Table 1 layout: one row per method, one column per task variant; each
  // cell is the success rate, its 95% Wilson interval and the trial count.
  std::vector<std::string> methods, variants;
  std::map<std::pair<std::string, std::string>, const TableCell*> by_key;
  for (const TableCell& c : cells) {
    if (std::find(methods.begin(), methods.end(), c.method) == methods.end()) methods.push_back(c.method);
    if (std::find(variants.begin(), variants.end(), c.variant) == variants.end()) variants.push_back(c.variant);
    by_key[{c.method, c.variant}] = &c;
  }
  Listing listing;
  listing.columns.push_back("method");
  for (const std::string& v : variants) listing.columns.push_back(v.empty() ? "success rate" : v);
  for (const std::string& m : methods) {
    std::vector<std::string> row = {m};
    for (const std::string& v : variants) {
      auto it = by_key.find({m, v});
      if (it == by_key.end()) {
        row.push_back("-");
        continue;
      }
      const TableCell& c = *it->second;
      std::string text = absl::StrCat(FormatRate(c.success), " n=", c.success.trials);
      if (c.held.trials > 0) absl::StrAppend(&text, "; held ", c.held.successes, "/", c.held.trials);
      row.push_back(std::move(text));
    }
    listing.rows.push_back(row);
  }
  std::cout << "sweep " << sweep_name << ": success rate [95% Wilson interval] n=trials ("
            << reader.last_sweep().jobs_completed() << " of " << reader.last_sweep().jobs_total()
            << " jobs completed); held k/n: trials whose final policy held in at least half "
               "of its verdict rollouts, of those classified\n";
  Print(listing, Format::kTable, std::cout);
  return plot_path.empty() ? 0 : PlotResultsTable(connection, sweep_name, cells, plot_path);
}

absl::StatusOr<std::vector<EpisodeValue>> ReadEvaluationCosts(Connection* connection,
                                                               const std::string& sweep_name) {
  v1::ExportEpisodesRequest request;
  request.set_sweep_name(sweep_name);
  std::vector<EpisodeValue> values;
  grpc::Status status = rpc::CallWithRetry(
      connection->policy(), connection->token(), [&](grpc::ClientContext* context) {
        values.clear();
        auto reader = connection->control()->ExportEpisodes(context, request);
        v1::ExportEpisodesResponse batch;
        while (reader->Read(&batch)) {
          for (const auto& row : batch.rows()) {
            // Only completed trials: a curve mixes no partial attempts.
            if (!row.final_attempt()) continue;
            values.push_back({row.method(), row.variant(), row.report().episode(),
                              row.report().eval_cost_mean(), row.job_id()});
          }
        }
        return reader->Finish();
      });
  if (!status.ok()) return ToAbslStatus(status);
  return values;
}

Listing CurvesListing(const std::vector<CurvePoint>& curves) {
  Listing listing;
  for (const auto& field : results::CurvePointFields()) {
    listing.columns.push_back(field.name);
    if (field.type() != record::FieldType::kText) listing.numeric_columns.push_back(field.name);
  }
  for (const CurvePoint& p : curves) {
    const results::SampleSummary& v = p.values;
    listing.rows.push_back({p.method, p.variant, std::to_string(p.episode),
                            std::to_string(v.trials), FormatFixed(v.q25, 2),
                            FormatFixed(v.median, 2), FormatFixed(v.q75, 2), FormatFixed(v.mean, 2),
                            FormatFixed(v.standard_error, 2)});
  }
  return listing;
}

int PrintCurves(Connection* connection, const std::string& sweep_name, Format format,
                const std::string& plot_path, bool print_table, int top) {
  const absl::StatusOr<std::vector<EpisodeValue>> values = ReadEvaluationCosts(connection, sweep_name);
  if (!values.ok()) return ReportError(values.status(), "results curves " + sweep_name);
  const std::vector<CurvePoint> curves = results::Curves(*values);
  if (print_table) {
    if (format == Format::kTable) {
      Print(CurvesListing(curves), format, std::cout);
    } else {
      PrintRecords(results::CurvePointFields(), curves, format, std::cout);
    }
  }
  if (!plot_path.empty()) {
    if (curves.empty()) {
      std::cerr << "error: results curves " << sweep_name
                << ": no completed trial has evaluation costs yet; nothing to plot\n";
      return 1;
    }
    CurvesPlotInput plot;
    plot.sweep_name = sweep_name;
    plot.curves = curves;
    if (top > 0) {
      plot.top = top;
      plot.best_curves = results::Curves(results::BestRuns(*values, top));
    }
    std::string problem = FetchCurvePanels(connection, sweep_name, &plot.panels);
    if (problem.empty()) problem = WriteCurvesPlot(plot, plot_path);
    return ReportPlot("curves", plot_path, problem);
  }
  return 0;
}

}  // namespace totalgrad::cli
