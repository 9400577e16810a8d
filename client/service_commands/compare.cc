// `totalgrad results compare SWEEP [--baseline M] [--alpha A]`: which method
// is better in each task variant, with paired tests (see results/comparison.h).
#include <cmath>
#include <iostream>
#include <memory>

#include "absl/strings/str_cat.h"
#include "client/service_commands/connection.h"
#include "client/service_commands/format.h"
#include "client/service_commands/rpc_results_reader.h"
#include "results/comparison.h"

namespace totalgrad::cli {

using results::Comparison;
using results::ComparisonOptions;
using results::ComparisonReport;

namespace {

// "+0.30": differences read better with their sign.
std::string Signed(double value, int decimals) {
  if (std::isnan(value)) return "-";
  const std::string text = FormatFixed(value, decimals);
  return value > 0 ? "+" + text : text;
}

// p-values: 3 significant digits, "<0.001" below that in tables.
std::string PValue(double p) {
  if (std::isnan(p)) return "-";
  if (p < 0.001) return "<0.001";
  return FormatFixed(p, 3);
}

std::string Number(double value, Format format, int decimals) {
  return format == Format::kTable ? FormatFixed(value, decimals) : FormatNumber(value);
}

}  // namespace

Listing ComparisonListing(const ComparisonReport& report, double alpha) {
  Listing listing;
  listing.columns = {"variant", "method", "vs", "pairs", "both_succeeded", "method_only",
                     "vs_only", "neither", "success_difference", "success_difference95_low",
                     "success_difference95_high", "mcnemar_p",
                     "mcnemar_p_holm", "mcnemar_power", "cost_pairs", "cost_shift_hl",
                     "rank_biserial", "wilcoxon_w_plus", "wilcoxon_exact", "wilcoxon_p",
                     "wilcoxon_p_holm", "wilcoxon_power", "method_trials",
                     "method_successes", "vs_trials", "vs_successes", "rate_difference",
                     "odds_ratio", "fisher_p", "fisher_p_holm", "fisher_power", "alpha",
                     "success_verdict", "cost_verdict"};
  for (const std::string& column : listing.columns) {
    if (column != "variant" && column != "method" && column != "vs" &&
        column != "success_verdict" && column != "cost_verdict") {
      listing.numeric_columns.push_back(column);
    }
  }
  for (const Comparison& c : report.comparisons) {
    const results::PairedSuccess& s = c.success;
    listing.rows.push_back(
        {c.variant, c.method, c.other, std::to_string(s.pairs), std::to_string(s.both),
         std::to_string(s.method_only), std::to_string(s.other_only), std::to_string(s.neither),
         FormatNumber(s.difference), FormatNumber(s.difference95_low),
         FormatNumber(s.difference95_high), FormatNumber(s.mcnemar_p),
         FormatNumber(s.mcnemar_p_holm), FormatNumber(s.mcnemar_power),
         std::to_string(c.cost_pairs), FormatNumber(c.wilcoxon.hodges_lehmann),
         FormatNumber(c.wilcoxon.rank_biserial), FormatNumber(c.wilcoxon.w_plus),
         c.wilcoxon.exact ? "1" : "0", FormatNumber(c.wilcoxon.p),
         FormatNumber(c.wilcoxon_p_holm), FormatNumber(c.wilcoxon_power),
         std::to_string(c.method_trials), std::to_string(c.method_successes),
         std::to_string(c.other_trials), std::to_string(c.other_successes),
         FormatNumber(c.rate_difference), FormatNumber(c.odds_ratio),
         FormatNumber(c.fisher_p), FormatNumber(c.fisher_p_holm),
         FormatNumber(c.fisher_power), FormatNumber(alpha),
         results::SuccessVerdict(c, alpha), results::CostVerdict(c, alpha)});
  }
  return listing;
}

int PrintComparison(Connection* connection, const std::string& sweep_name,
                    const ComparisonOptions& options, Format format) {
  RpcResultsReader reader(connection);
  const absl::StatusOr<std::vector<results::CompletedTrial>> trials =
      reader.CompletedTrials(sweep_name);
  if (!trials.ok()) return ReportError(trials.status(), "results compare " + sweep_name);
  absl::StatusOr<ComparisonReport> report = results::CompareMethods(*trials, options);
  if (!report.ok()) return ReportError(report.status(), "results compare " + sweep_name);

  if (format != Format::kTable) {
    Print(ComparisonListing(*report, options.alpha), format, std::cout);
    return 0;
  }

  std::cout << "sweep " << sweep_name << ": " << reader.last_sweep().jobs_completed() << " of "
            << reader.last_sweep().jobs_total() << " jobs completed; "
            << (options.baseline.empty() ? "every pair of methods"
                                         : "every method against " + options.baseline)
            << ", within each task variant, paired by seed.\n"
            << "Two-sided p-values, Holm-corrected over the comparisons of each variant (one "
               "family per test); verdicts at alpha = "
            << FormatNumber(options.alpha)
            << " after Holm. Power: of each unadjusted test at that n, if the true effect were "
               "the observed one.\n";
  if (report->comparisons.empty()) {
    std::cout << "\nnothing to compare: "
              << (report->methods.size() < 2
                      ? "fewer than two methods have completed trials"
                      : "no task variant has completed trials of two methods")
              << "\n";
    return 0;
  }

  Listing success;
  success.columns = {"variant", "method", "vs", "pairs", "only method", "only vs", "diff",
                     "McNemar p", "Holm", "power", "rates", "odds ratio", "Fisher p", "Holm",
                     "power", "verdict"};
  Listing cost;
  cost.columns = {"variant", "method", "vs", "pairs", "shift (HL)", "rank-biserial", "W+",
                  "Wilcoxon p", "Holm", "power", "verdict"};
  for (const Comparison& c : report->comparisons) {
    const std::string variant = c.variant.empty() ? "-" : c.variant;
    const results::PairedSuccess& s = c.success;
    success.rows.push_back(
        {variant, c.method, c.other, std::to_string(s.pairs), std::to_string(s.method_only),
         std::to_string(s.other_only), Signed(s.difference, 2), PValue(s.mcnemar_p),
         PValue(s.mcnemar_p_holm), Number(s.mcnemar_power, Format::kTable, 2),
         absl::StrCat(c.method_successes, "/", c.method_trials, " vs ", c.other_successes, "/",
                      c.other_trials),
         std::isinf(c.odds_ratio) ? "inf" : Number(c.odds_ratio, Format::kTable, 2),
         PValue(c.fisher_p), PValue(c.fisher_p_holm), Number(c.fisher_power, Format::kTable, 2),
         results::SuccessVerdict(c, options.alpha)});
    cost.rows.push_back(
        {variant, c.method, c.other, std::to_string(c.cost_pairs),
         Signed(c.wilcoxon.hodges_lehmann, 3), Signed(c.wilcoxon.rank_biserial, 2),
         FormatNumber(c.wilcoxon.w_plus),
         PValue(c.wilcoxon.p) + (c.wilcoxon.n > 0 && !c.wilcoxon.exact ? " (normal)" : ""),
         PValue(c.wilcoxon_p_holm), Number(c.wilcoxon_power, Format::kTable, 2),
         results::CostVerdict(c, options.alpha)});
  }
  std::cout << "\nsuccess: McNemar's exact test on the seeds both completed (diff = paired "
               "difference in success rate), Fisher's exact test on all completed trials\n";
  Print(success, Format::kTable, std::cout);
  std::cout << "\nfinal evaluation cost: Wilcoxon signed-rank test on per-seed differences "
               "(method - vs; exact up to "
            << results::kWilcoxonExactMaxN
            << " non-zero differences), shift = Hodges-Lehmann median difference (negative: "
               "method lower), power by Noether's approximation\n";
  Print(cost, Format::kTable, std::cout);
  if (report->duplicate_trials > 0) {
    std::cout << "\nnote: " << report->duplicate_trials
              << " trials repeat a (method, seed, variant); only the first of each was used\n";
  }
  return 0;
}

void AddCompareCommand(CLI::App* results, int* exit_code) {
  CLI::App* command = results->add_subcommand(
      "compare",
      "compare methods per task variant: McNemar's exact test on per-seed success, Wilcoxon "
      "signed-rank on per-seed final costs, Fisher's exact test unpaired; Holm-corrected, with "
      "effect sizes and power");
  auto flags = std::make_shared<ServiceFlags>();
  auto sweep = std::make_shared<std::string>();
  auto options = std::make_shared<ComparisonOptions>();
  AddConnectionFlags(command, flags.get(), /*with_format=*/true);
  command->add_option("SWEEP", *sweep, "sweep name")->required();
  command->add_option("--baseline", options->baseline,
                      "compare every other method with this one (default: every pair)");
  command->add_option("--alpha", options->alpha,
                      "significance level of the verdicts and the power (default 0.05)");
  command->callback([flags, sweep, options, exit_code] {
    absl::StatusOr<Connection> connection = Connection::Open(*flags);
    if (!connection.ok()) {
      *exit_code = ReportError(connection.status(), "results compare");
      return;
    }
    *exit_code = PrintComparison(&*connection, *sweep, *options, connection->format());
  });
}

}  // namespace totalgrad::cli
