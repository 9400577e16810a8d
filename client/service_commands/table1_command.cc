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
#include "client/service_commands/format.h"
#include "client/service_commands/rpc_results_reader.h"
#include "client/service_commands/success_plot.h"
#include "results/table1.h"
#include "results/table1_claims.h"

namespace totalgrad::cli {
namespace {

using results::Table1Cell;

// The paper's line of a cell: its rate, "in" or "OUT" of our interval, and,
// where the rate and a bound of the interval print alike at two decimals,
// that bound at three ("0.69 OUT (high 0.687)" beside "[0.17, 0.69]" would
// otherwise read as a contradiction).
std::string PaperCellText(const Table1Cell& cell) {
  if (std::isnan(cell.paper_success_rate)) return "none";
  const std::string paper = FormatFixed(cell.paper_success_rate, 2);
  const std::string inside = results::PaperInInterval(cell);
  if (inside.empty()) return paper;
  std::string text = absl::StrCat(paper, inside == "yes" ? " in" : " OUT");
  if (FormatFixed(cell.success.low, 2) == paper) {
    absl::StrAppend(&text, " (low ", FormatFixed(cell.success.low, 3), ")");
  } else if (FormatFixed(cell.success.high, 2) == paper) {
    absl::StrAppend(&text, " (high ", FormatFixed(cell.success.high, 3), ")");
  }
  return text;
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
  for (const Table1Cell& cell : table.cells) in_grid += cell.success.trials;
  out << "Table 1 (Parmas et al. 2018) from sweep" << (sweeps.size() == 1 ? " " : "s ")
      << absl::StrJoin(sweeps, ", ") << ": " << in_grid << " completed trials in the grid\n"
      << "success: success rate [95% Wilson interval] n=trials, '*' = not all on the paper's "
         "protocol (below)\n"
      << "held: trials whose final policy held in at least half of its verdict rollouts "
         "[95% Wilson interval] held/classified\n"
      << "paper: the paper's success rate, 'in' or 'OUT' of our interval (the bound at three "
         "decimals where the two print alike)\n\n";
  Listing listing;
  listing.columns.push_back("task");
  for (const std::string& method : methods) listing.columns.push_back(method);
  std::vector<std::string> marked;
  for (size_t r = 0; r < rows.size(); ++r) {
    std::vector<std::string> success = {rows[r].Label()}, held = {"  held"}, paper = {"  paper"};
    for (size_t m = 0; m < methods.size(); ++m) {
      const Table1Cell& cell = table.cells[r * methods.size() + m];
      if (cell.success.trials == 0) {
        success.push_back("-");
      } else {
        success.push_back(absl::StrCat(FormatRate(cell.success), " n=", cell.success.trials,
                                       cell.off_protocol_trials > 0 ? "*" : ""));
      }
      held.push_back(cell.held.trials == 0
                         ? "-"
                         : absl::StrCat(FormatRate(cell.held), " ", cell.held.successes, "/",
                                        cell.held.trials));
      paper.push_back(PaperCellText(cell));
      if (cell.off_protocol_trials > 0) {
        marked.push_back(absl::StrCat("  ", rows[r].Label(), ", ", cell.method, ": ",
                                      cell.off_protocol_trials, " of ", cell.success.trials,
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

// The thresholds as a text table: one line per cell, "successes/trials"
// at each threshold, then the trials whose verdict differs from the
// stored one at the lowest and the highest threshold.
void PrintSensitivity(const std::vector<results::ThresholdRate>& rates,
                      const std::vector<double>& thresholds, std::ostream& out) {
  out << "Threshold sensitivity: successes/trials with final evaluation cost below each "
         "threshold (the trials' own threshold is 15)\n\n";
  Listing listing;
  listing.columns = {"task", "method"};
  for (double threshold : thresholds) listing.columns.push_back(absl::StrCat("< ", threshold));
  std::vector<std::string> changes;
  for (size_t start = 0; start + thresholds.size() <= rates.size(); start += thresholds.size()) {
    const results::ThresholdRate& first = rates[start];
    std::vector<std::string> row = {
        results::Table1Row{first.cost, first.noise_k}.Label(), first.method};
    for (size_t t = 0; t < thresholds.size(); ++t) {
      const results::ThresholdRate& rate = rates[start + t];
      row.push_back(absl::StrCat(rate.success.successes, "/", rate.success.trials));
      if (rate.changed > 0) {
        changes.push_back(absl::StrCat("  ", row[0], ", ", first.method, " at ", rate.threshold,
                                       ": ", rate.changed_trials));
      }
    }
    listing.rows.push_back(std::move(row));
  }
  Print(listing, Format::kTable, out);
  if (!changes.empty()) out << "\nverdicts that change:\n" << absl::StrJoin(changes, "\n") << "\n";
}

std::string DifferenceInterval(const results::PairedSuccess& paired) {
  return FormatInterval(paired.difference, paired.difference95_low, paired.difference95_high, 2);
}

std::string PValue(double p, double holm) {
  if (std::isnan(holm)) return "-";
  return absl::StrCat(FormatFixed(p, 3), " (", FormatFixed(holm, 3), ")");
}

void PrintClaims(const std::vector<results::ClaimComparison>& claims, std::ostream& out) {
  out << "The paper's claims as paired comparisons by seed (method minus other): 95% "
         "intervals first, then p (Holm-adjusted within the row, each test its own family)\n"
         "success: threshold verdicts, Newcombe's paired interval; McNemar's exact test\n"
         "held: rollout verdicts (held in >= half), same; cost: Hodges-Lehmann shift of the "
         "final costs with the signed-rank interval; Wilcoxon's test\n\n";
  Listing listing;
  listing.columns = {"task",  "comparison", "pairs",       "success diff", "McNemar p (Holm)",
                     "held diff", "held p (Holm)", "cost shift", "Wilcoxon p (Holm)"};
  std::vector<std::string> claims_text;
  for (const results::ClaimComparison& claim : claims) {
    const std::string comparison = absl::StrCat(claim.method, " - ", claim.other);
    listing.rows.push_back(
        {results::Table1Row{claim.cost, claim.noise_k}.Label(), comparison,
         absl::StrCat(claim.success.pairs), DifferenceInterval(claim.success),
         PValue(claim.success.mcnemar_p, claim.success.mcnemar_p_holm),
         claim.verdict.pairs == 0
             ? "-"
             : absl::StrCat(DifferenceInterval(claim.verdict), " n=", claim.verdict.pairs),
         PValue(claim.verdict.mcnemar_p, claim.verdict.mcnemar_p_holm),
         FormatInterval(claim.cost_shift, claim.cost_shift95_low, claim.cost_shift95_high, 2),
         PValue(claim.wilcoxon_p, claim.wilcoxon_p_holm)});
    claims_text.push_back(absl::StrCat("  ", comparison, ": ", claim.claim));
  }
  Print(listing, Format::kTable, out);
  out << "\nclaims:\n" << absl::StrJoin(claims_text, "\n") << "\n";
}

void PrintPower(const std::vector<results::PowerEntry>& entries, std::ostream& out) {
  if (entries.empty()) return;
  out << "What " << entries.front().pairs
      << " paired seeds can settle: the exact power of McNemar's test for a true success-rate "
         "difference, at alpha 0.05 and at Holm's first step in a row of 2 and of 4 "
         "comparisons\n"
      << "a significant difference needs at least " << entries.front().min_one_sided_discordant
      << " discordant pairs all one way\n\n";
  Listing listing;
  listing.columns = {"P(method only)", "P(other only)", "difference", "power", "power/2",
                     "power/4"};
  for (const results::PowerEntry& entry : entries) {
    listing.rows.push_back({FormatFixed(entry.method_only_rate, 1),
                            FormatFixed(entry.other_only_rate, 1),
                            FormatFixed(entry.difference, 1), FormatFixed(entry.power, 3),
                            FormatFixed(entry.power_holm2, 3), FormatFixed(entry.power_holm4, 3)});
  }
  Print(listing, Format::kTable, out);
}

// What `results table1` shows: the grid, or what its verdicts rest on.
struct Table1View {
  std::string view = "grid";
  std::vector<double> thresholds = results::DefaultSensitivityThresholds();
  std::string plot;  // the grid's picture (success_plot.h), "" for none
};

// The grid as a picture: one panel per task with a completed trial, every
// method of the paper in its place, the paper's rate as a marker.
int PlotTable1(const results::Table1& table, const std::vector<std::string>& sweeps,
               const std::string& path) {
  const std::vector<std::string>& methods = results::Table1Methods();
  const std::vector<results::Table1Row>& rows = results::Table1Rows();
  SuccessPlotInput plot;
  plot.title = absl::StrCat("Table 1 (Parmas et al. 2018) from ", absl::StrJoin(sweeps, ", "),
                            ": success rate, 95% Wilson interval, successes/trials; diamond: the paper");
  for (size_t r = 0; r < rows.size(); ++r) {
    int trials = 0;
    for (size_t m = 0; m < methods.size(); ++m) trials += table.cells[r * methods.size() + m].success.trials;
    if (trials == 0) continue;
    for (size_t m = 0; m < methods.size(); ++m) {
      const Table1Cell& c = table.cells[r * methods.size() + m];
      plot.points.push_back({rows[r].Label(), c.method, c.success, c.paper_success_rate});
    }
    plot.panel_variants.push_back(rows[r].Label());
    plot.panel_titles.push_back(absl::StrCat("cart-pole swing-up, ", rows[r].Label()));
  }
  return ReportPlot("table1", path, WriteSuccessPlot(plot, path));
}

int PrintTable1(Connection* connection, const std::vector<std::string>& sweeps,
                const Table1View& view, Format format) {
  if (sweeps.empty()) {
    std::cerr << "error: results table1: name at least one sweep\n";
    return 2;
  }
  if (!view.plot.empty() && view.view != "grid") {
    std::cerr << "error: results table1: --plot draws the grid view, not --view " << view.view
              << "\n";
    return 2;
  }
  RpcResultsReader reader(connection);
  const absl::StatusOr<std::vector<results::CompletedTrial>> trials =
      results::ReadCompletedTrials(reader, sweeps);
  if (!trials.ok()) return ReportError(trials.status(), "results table1");
  const absl::StatusOr<results::Table1> table = results::ComputeTable1(*trials);
  if (!table.ok()) return ReportError(table.status(), "results table1");
  if (view.view == "sensitivity") {
    const std::vector<results::ThresholdRate> rates =
        results::ThresholdSensitivity(*table, view.thresholds);
    if (format == Format::kTable) {
      PrintSensitivity(rates, view.thresholds, std::cout);
    } else {
      PrintRecords(results::ThresholdRateFields(), rates, format, std::cout);
    }
    return 0;
  }
  if (view.view == "comparisons") {
    const std::vector<results::ClaimComparison> claims = results::CompareClaims(*table);
    if (format == Format::kTable) {
      PrintClaims(claims, std::cout);
    } else {
      PrintRecords(results::ClaimComparisonFields(), claims, format, std::cout);
    }
    return 0;
  }
  if (format == Format::kTable) {
    PrintGrid(*table, sweeps, std::cout);
  } else {
    PrintRecords(results::Table1CellFields(), table->cells, format, std::cout);
    if (!table->outside.empty()) {
      std::cerr << "note: not in the grid: " << absl::StrJoin(table->outside, "; ") << "\n";
    }
  }
  return view.plot.empty() ? 0 : PlotTable1(*table, sweeps, view.plot);
}

}  // namespace

void AddTable1Command(CLI::App* results, int* exit_code) {
  auto sweeps = std::make_shared<std::vector<std::string>>();
  auto view = std::make_shared<Table1View>();
  CLI::App* command = AddCommand(
      results, "table1",
      "the paper's Table 1 from the completed trials of the named sweeps: success rate with "
      "95% Wilson interval and n, the rollout verdict's rate, the paper's number and whether "
      "it lies in our interval, per task (cost, noise_k) and method; pooled across sweeps. "
      "--view sensitivity: each cell's rate at other thresholds and the verdicts that change; "
      "--view comparisons: the paper's claims as paired comparisons by seed with intervals "
      "and Holm-adjusted p-values (`results power`: what n paired seeds can settle)",
      exit_code,
      [sweeps, view](Connection* c) { return PrintTable1(c, *sweeps, *view, c->format()); });
  command->add_option("SWEEP", *sweeps, "sweep names (one or more)")->required();
  command->add_option("--view", view->view, "grid (default), sensitivity or comparisons")
      ->check(CLI::IsMember({"grid", "sensitivity", "comparisons"}));
  command->add_option("--thresholds", view->thresholds,
                      "thresholds on the final evaluation cost for --view sensitivity "
                      "(default 13,14,15,16,17)")
      ->delimiter(',')
      ->check(CLI::Range(0.0, 1e6));
  command->add_option("--plot", view->plot,
                      "also draw the grid's success rates, their Wilson intervals and the paper's "
                      "rates into FILE.svg, FILE.pdf or FILE.png (gnuplot; the grid view)");
}

void AddPowerCommand(CLI::App* results, int* exit_code) {
  struct Flags {
    int pairs = 10;
    std::string format = "table";
  };
  auto flags = std::make_shared<Flags>();
  CLI::App* command = results->add_subcommand(
      "power",
      "what a paired comparison of n seeds can settle: the exact power of McNemar's test for "
      "true success-rate differences 0.1 .. 1.0, at alpha 0.05 and at Holm's first step in "
      "families of 2 and 4 (computed here, no coordinator needed)");
  command->add_option("--pairs", flags->pairs, "paired seeds (default 10)")
      ->check(CLI::Range(1, 1000));
  command->add_option("-f,--format", flags->format, "table (default), json or csv")
      ->check(CLI::IsMember({"table", "json", "csv"}));
  command->callback([flags, exit_code] {
    Format format = Format::kTable;
    ParseFormat(flags->format, &format);
    const std::vector<results::PowerEntry> power = results::PairedPowerTable(flags->pairs);
    if (format == Format::kTable) {
      PrintPower(power, std::cout);
    } else {
      PrintRecords(results::PowerEntryFields(), power, format, std::cout);
    }
    *exit_code = 0;
  });
}

}  // namespace totalgrad::cli
