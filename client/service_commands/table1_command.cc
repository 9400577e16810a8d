// `totalgrad results table1 SWEEP [SWEEP...]`: the paper's Table 1 from the
// completed trials of the named sweeps, in the paper's grid (rows: cost and
// noise level; columns: the eight methods), each cell beside the paper's
// number (results/table1.h computes it; this file fetches and prints).
#include <cmath>
#include <iostream>
#include <map>
#include <memory>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "client/service_commands/connection.h"
#include "client/service_commands/streamed_reads.h"
#include "client/service_commands/format.h"
#include "results/table1.h"

namespace totalgrad::cli {
namespace {

using results::Table1Cell;
using results::Table1Trial;

// Appends the completed trials of `sweep` to *trials: the counting attempts
// (ListTrialResults) with the options of their jobs (ListJobs of the
// completed jobs, page by page), joined on the job id. The results are
// fetched first, so every job they name is already completed when the jobs
// are listed.
grpc::Status FetchTrials(Connection* connection, const std::string& sweep,
                         std::vector<Table1Trial>* trials) {
  v1::ListTrialResultsResponse completed;
  grpc::Status status = FetchTrialResults(connection, sweep, &completed);
  if (!status.ok()) return status;
  std::map<int64_t, record::TextPairs> options_of;
  v1::ListJobsRequest jobs_request;
  jobs_request.set_sweep_name(sweep);
  jobs_request.add_states(v1::JOB_STATE_COMPLETED);
  jobs_request.set_page_size(1000);
  while (true) {
    v1::ListJobsResponse jobs;
    status = connection->Call(&v1::ControlService::Stub::ListJobs, jobs_request, &jobs);
    if (!status.ok()) return status;
    for (const v1::JobInfo& job : jobs.jobs()) {
      record::TextPairs& options = options_of[job.job_id()];
      for (const auto& option : job.options()) options.emplace_back(option.key(), option.value());
    }
    if (jobs.next_after_job_id() == 0) break;
    jobs_request.set_after_job_id(jobs.next_after_job_id());
  }
  for (const v1::TrialResult& result : completed.results()) {
    auto options = options_of.find(result.job_id());
    if (options == options_of.end()) {
      return grpc::Status(grpc::StatusCode::INTERNAL,
                          absl::StrCat("job ", result.job_id(), " of sweep ", sweep,
                                       " has a result but is not listed as completed"));
    }
    Table1Trial trial;
    trial.sweep = sweep;
    trial.job_id = result.job_id();
    trial.method = result.method();
    trial.seed = result.seed();
    trial.variant = result.variant();
    trial.success = result.success();
    trial.held_fraction = result.held_fraction();
    trial.options = std::move(options->second);
    trials->push_back(std::move(trial));
  }
  return grpc::Status::OK;
}

std::string Rate(double rate, double low, double high) {
  return absl::StrCat(FormatFixed(rate, 2), " [", FormatFixed(low, 2), ", ", FormatFixed(high, 2),
                      "]");
}

// The grid as text: three lines per task (our success rate, the rollout
// verdict's rate, the paper's number), one column per method, then the
// cells whose trials left the paper's protocol (marked '*') and the trials
// that have no cell.
void PrintGrid(const results::Table1& table, const std::vector<std::string>& sweeps,
               std::ostream& out) {
  const std::vector<std::string>& methods = results::Table1Methods();
  const std::vector<results::Table1Row>& rows = results::Table1Rows();
  int in_grid = 0;
  for (const Table1Cell& cell : table.cells) in_grid += cell.trials;
  out << "Table 1 (Parmas et al. 2018) from sweep" << (sweeps.size() == 1 ? " " : "s ")
      << absl::StrJoin(sweeps, ", ") << ": " << in_grid << " completed trials in the grid\n"
      << "success: success rate [95% Wilson interval] n=trials, '*' = not all on the paper's "
         "protocol (below)\n"
      << "held: trials whose final policy held in at least half of its verdict rollouts "
         "[95% Wilson interval] held/classified\n"
      << "paper: the paper's success rate, 'in' or 'OUT' of our interval\n\n";
  Listing listing;
  listing.columns.push_back("task");
  for (const std::string& method : methods) listing.columns.push_back(method);
  std::vector<std::string> marked;
  for (size_t r = 0; r < rows.size(); ++r) {
    std::vector<std::string> success = {rows[r].Label()}, held = {"  held"}, paper = {"  paper"};
    for (size_t m = 0; m < methods.size(); ++m) {
      const Table1Cell& cell = table.cells[r * methods.size() + m];
      if (cell.trials == 0) {
        success.push_back("-");
      } else {
        success.push_back(absl::StrCat(
            Rate(cell.success_rate, cell.wilson95_low, cell.wilson95_high), " n=", cell.trials,
            cell.off_protocol_trials > 0 ? "*" : ""));
      }
      held.push_back(cell.classified == 0
                         ? "-"
                         : absl::StrCat(Rate(cell.held_rate, cell.held_wilson95_low,
                                             cell.held_wilson95_high),
                                        " ", cell.held, "/", cell.classified));
      const std::string inside = results::PaperInInterval(cell);
      paper.push_back(std::isnan(cell.paper_success_rate)
                          ? "none"
                          : absl::StrCat(FormatFixed(cell.paper_success_rate, 2),
                                         inside == "yes" ? " in" : inside == "no" ? " OUT" : ""));
      if (cell.off_protocol_trials > 0) {
        marked.push_back(absl::StrCat("  ", rows[r].Label(), ", ", cell.method, ": ",
                                      cell.off_protocol_trials, " of ", cell.trials,
                                      " trials: ", cell.protocol_differences));
      }
    }
    listing.rows.push_back(std::move(success));
    listing.rows.push_back(std::move(held));
    listing.rows.push_back(std::move(paper));
  }
  Print(listing, Format::kTable, out);
  if (!marked.empty()) {
    std::vector<std::string> protocol;
    for (const auto& [key, value] : results::PaperProtocol()) {
      protocol.push_back(absl::StrCat(key, " ", value));
    }
    out << "\n* not the paper's protocol (" << absl::StrJoin(protocol, ", ") << "):\n"
        << absl::StrJoin(marked, "\n") << "\n";
  }
  if (!table.outside.empty()) {
    out << "\nnot in the grid: " << absl::StrJoin(table.outside, "; ") << "\n";
  }
}

int PrintTable1(Connection* connection, const std::vector<std::string>& sweeps, Format format) {
  std::vector<Table1Trial> trials;
  for (const std::string& sweep : sweeps) {
    const grpc::Status status = FetchTrials(connection, sweep, &trials);
    if (!status.ok()) return ReportError(status, "results table1 " + sweep);
  }
  const absl::StatusOr<results::Table1> table = results::ComputeTable1(trials);
  if (!table.ok()) return ReportError(table.status(), "results table1");
  if (format == Format::kTable) {
    PrintGrid(*table, sweeps, std::cout);
    return 0;
  }
  PrintRecords(results::Table1CellFields(), table->cells, format, std::cout);
  if (!table->outside.empty()) {
    std::cerr << "note: not in the grid: " << absl::StrJoin(table->outside, "; ") << "\n";
  }
  return 0;
}

}  // namespace

void AddTable1Command(CLI::App* results, int* exit_code) {
  auto sweeps = std::make_shared<std::vector<std::string>>();
  CLI::App* command = AddCommand(
      results, "table1",
      "the paper's Table 1 from the completed trials of the named sweeps: success rate with "
      "95% Wilson interval and n, the rollout verdict's rate, the paper's number and whether "
      "it lies in our interval, per task (cost, noise_k) and method; pooled across sweeps",
      exit_code, [sweeps](Connection* c) { return PrintTable1(c, *sweeps, c->format()); });
  command->add_option("SWEEP", *sweeps, "sweep names (one or more)")->required();
}

}  // namespace totalgrad::cli
