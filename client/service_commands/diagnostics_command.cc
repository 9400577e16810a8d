// `totalgrad results diagnostics SWEEP [--statistic NAME]`: the estimator
// statistics of the sweep's completed trials per method, task variant and
// episode (median and quartiles over trials; results/diagnostics.h), as a
// table, CSV or JSON. The dashboard's /api/diagnostics draws the same points.
#include <algorithm>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "client/service_commands/connection.h"
#include "core/common/closest_word.h"
#include "results/diagnostics.h"
#include "runtime/record_proto.h"

namespace totalgrad::cli {

absl::StatusOr<std::vector<results::DiagnosticPoint>> ReadDiagnostics(
    Connection* connection, const std::string& sweep_name, const std::string& statistic) {
  const std::vector<std::string>& known = results::DiagnosticStatistics();
  if (!statistic.empty() && std::find(known.begin(), known.end(), statistic) == known.end()) {
    const std::string closest = ClosestCandidate(statistic, known);
    return absl::InvalidArgumentError(absl::StrCat(
        "unknown statistic '", statistic, "'",
        closest.empty() ? "" : absl::StrCat(" (did you mean '", closest, "'?)"),
        "; the statistics are ", absl::StrJoin(known, ", ")));
  }
  v1::ExportEpisodesRequest request;
  request.set_sweep_name(sweep_name);
  std::vector<results::EpisodeStatistics> rows;
  const grpc::Status status = rpc::CallWithRetry(
      connection->policy(), connection->token(), [&](grpc::ClientContext* context) {
        rows.clear();
        auto reader = connection->control()->ExportEpisodes(context, request);
        v1::ExportEpisodesResponse batch;
        while (reader->Read(&batch)) {
          for (const auto& row : batch.rows()) {
            if (!row.final_attempt()) continue;  // each job's counting attempt only
            results::EpisodeStatistics& out = rows.emplace_back();
            out.method = row.method();
            out.variant = row.variant();
            record_proto::RecordFromProto<learner::EpisodeSummary>(learner::EpisodeFields(),
                                                                   row.report(), &out.episode);
          }
        }
        return reader->Finish();
      });
  if (!status.ok()) return ToAbslStatus(status);
  return results::DiagnosticCurves(rows, statistic);
}

namespace {

int PrintDiagnostics(Connection* connection, const std::string& sweep_name,
                     const std::string& statistic) {
  const std::string what = "results diagnostics " + sweep_name;
  const absl::StatusOr<std::vector<results::DiagnosticPoint>> read =
      ReadDiagnostics(connection, sweep_name, statistic);
  if (!read.ok()) return ReportError(read.status(), what);
  const std::vector<results::DiagnosticPoint>& points = *read;
  const Format format = connection->format();
  if (format != Format::kTable) {
    PrintRecords(results::DiagnosticPointFields(), points, format, std::cout);
    return 0;
  }
  if (points.empty()) {
    std::cout << "sweep " << sweep_name << ": no completed trial recorded "
              << (statistic.empty() ? "estimator statistics" : statistic)
              << " (PILCO has none; trials of builds before issue 27 recorded none)\n";
    return 0;
  }
  Listing listing;
  listing.columns = {"statistic", "method", "variant", "episode", "trials", "q25", "median", "q75"};
  for (const results::DiagnosticPoint& point : points) {
    const results::CurvePoint& p = point.curve;
    listing.rows.push_back({point.statistic, p.method, p.variant, std::to_string(p.episode),
                            std::to_string(p.values.trials), absl::StrFormat("%.4g", p.values.q25),
                            absl::StrFormat("%.4g", p.values.median),
                            absl::StrFormat("%.4g", p.values.q75)});
  }
  std::cout << "sweep " << sweep_name
            << ": estimator statistics of the completed trials, median and quartiles over "
               "trials per episode (docs/diagnostics.md)\n";
  Print(listing, Format::kTable, std::cout);
  return 0;
}

}  // namespace

void AddDiagnosticsCommand(CLI::App* results, int* exit_code) {
  auto sweep = std::make_shared<std::string>();
  auto statistic = std::make_shared<std::string>();
  CLI::App* command = AddCommand(
      results, "diagnostics",
      "the estimator statistics of a sweep's completed trials (gradient norm and SNR, step "
      "norm, importance weights' ESS, total propagation's LR share) per method, variant and "
      "episode: median and quartiles over trials",
      exit_code,
      [sweep, statistic](Connection* c) { return PrintDiagnostics(c, *sweep, *statistic); });
  command->add_option("SWEEP", *sweep, "sweep name")->required();
  command->add_option("--statistic", *statistic,
                      "only this statistic (e.g. gradient_snr_mean, ess_median, lr_share_mean)");
}

}  // namespace totalgrad::cli
