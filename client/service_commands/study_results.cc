// `totalgrad results study SWEEP`: the rows of a sweep's study jobs (one per
// study cell, the columns of the study's table.csv; --references: one per
// reference gradient, the columns of references.csv) as a table, CSV or JSON.
#include <iostream>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "client/service_commands/connection.h"
#include "client/service_commands/format.h"

namespace totalgrad::cli {
namespace {

std::string Number(double value, Format format, int decimals = -1) {
  if (format == Format::kTable) {
    if (value != value) return "-";
    return decimals < 0 ? absl::StrFormat("%.3g", value) : FormatFixed(value, decimals);
  }
  return FormatNumber(value);
}

Listing CellListing(const v1::ListStudyRowsResponse& response, Format format, bool all_attempts) {
  Listing listing;
  if (format == Format::kTable) {
    // The layout of `totalgrad study`'s table, with the study in front.
    listing.columns = {"study", "estimator", "P", "H", "reps", "t_min_ms", "rel_rmse", "rel_bias",
                       "bias_noise", "cos", "ess", "k_lr", "nonfin", "err", "note"};
    if (all_attempts) listing.columns.insert(listing.columns.begin() + 1, "attempt");
    for (const auto& c : response.cells()) {
      std::vector<std::string> row = {
          c.study(), c.estimator(), c.particles() > 0 ? std::to_string(c.particles()) : "-",
          std::to_string(c.horizon()), std::to_string(c.replicates()),
          Number(c.time_min_s() * 1e3, format), Number(c.rel_rmse(), format),
          Number(c.rel_bias(), format), Number(c.rel_bias_noise(), format),
          Number(c.cos_mean(), format, 3), Number(c.ess_mean(), format, 3),
          Number(c.k_lr_mean(), format, 3), std::to_string(c.nonfinite()),
          std::to_string(c.errors()), c.note()};
      if (all_attempts) row.insert(row.begin() + 1, std::to_string(c.attempt()));
      listing.rows.push_back(std::move(row));
    }
    return listing;
  }
  // table.csv's columns, with the job's coordinates in front.
  listing.columns = {"study", "job_id", "attempt", "index", "estimator", "method", "particles",
                     "horizon", "replicates", "nonfinite", "errors", "time_min_s",
                     "time_median_s", "rel_rmse", "rel_bias", "rel_bias_noise", "total_variance",
                     "cos_mean", "objective_mean", "ess_mean", "ess_min", "k_lr_mean",
                     "reference_agrees", "reference_floor", "budget_hit", "omitted", "note"};
  listing.numeric_columns = {"job_id", "attempt", "index", "particles", "horizon", "replicates",
                             "nonfinite", "errors", "time_min_s", "time_median_s", "rel_rmse",
                             "rel_bias", "rel_bias_noise", "total_variance", "cos_mean",
                             "objective_mean", "ess_mean", "ess_min", "k_lr_mean",
                             "reference_agrees", "reference_floor", "budget_hit", "omitted"};
  for (const auto& c : response.cells()) {
    listing.rows.push_back(
        {c.study(), std::to_string(c.job_id()), std::to_string(c.attempt()),
         std::to_string(c.index()), c.estimator(), c.method(), std::to_string(c.particles()),
         std::to_string(c.horizon()), std::to_string(c.replicates()),
         std::to_string(c.nonfinite()), std::to_string(c.errors()), Number(c.time_min_s(), format),
         Number(c.time_median_s(), format), Number(c.rel_rmse(), format),
         Number(c.rel_bias(), format), Number(c.rel_bias_noise(), format),
         Number(c.total_variance(), format), Number(c.cos_mean(), format),
         Number(c.objective_mean(), format), Number(c.ess_mean(), format),
         Number(c.ess_min(), format), Number(c.k_lr_mean(), format),
         c.reference_agrees() ? "1" : "0", Number(c.reference_floor(), format),
         c.budget_hit() ? "1" : "0", c.omitted() ? "1" : "0", c.note()});
  }
  return listing;
}

Listing ReferenceListing(const v1::ListStudyRowsResponse& response, Format format) {
  Listing listing;
  // references.csv's columns, with the job's coordinates in front.
  listing.columns = {"study", "job_id", "attempt", "horizon", "norm", "relative_error", "floor",
                     "objective", "used", "replicates", "agreement_max_z", "agreement_mean_z2",
                     "agree", "seconds", "note"};
  listing.numeric_columns = {"job_id", "attempt", "horizon", "norm", "relative_error", "floor",
                             "objective", "agreement_max_z", "agreement_mean_z2", "agree",
                             "seconds"};
  for (const auto& r : response.references()) {
    listing.rows.push_back(
        {r.study(), std::to_string(r.job_id()), std::to_string(r.attempt()),
         std::to_string(r.horizon()), Number(r.norm(), format), Number(r.relative_error(), format),
         Number(r.floor(), format), Number(r.objective(), format), absl::StrJoin(r.used(), ";"),
         absl::StrJoin(r.replicates(), ";"), Number(r.agreement_max_z(), format),
         Number(r.agreement_mean_z2(), format), r.agree() ? "1" : "0",
         Number(r.seconds(), format), r.note()});
  }
  return listing;
}

}  // namespace

int PrintStudyResults(Connection* connection, const std::string& sweep_name, Format format,
                      bool references, bool all_attempts, std::ostream& out) {
  v1::ListStudyRowsRequest request;
  request.set_sweep_name(sweep_name);
  request.set_all_attempts(all_attempts);
  v1::ListStudyRowsResponse response;
  const grpc::Status status =
      connection->Call(&v1::ControlService::Stub::ListStudyRows, request, &response);
  if (!status.ok()) return ReportError(status, "results study " + sweep_name);
  if (format != Format::kTable) {
    Print(references ? ReferenceListing(response, format) : CellListing(response, format, true),
          format, out);
    return 0;
  }
  if (response.cells_size() == 0 && response.references_size() == 0) {
    out << "sweep " << sweep_name << ": no study rows stored yet\n";
    return 0;
  }
  out << "reference gradients (pooled; floor = 1.96 |SE| / |g*|):\n";
  Print(ReferenceListing(response, format), format, out);
  if (!references) {
    out << "\nstudy cells (t_min_ms: fastest single-threaded gradient):\n";
    Print(CellListing(response, format, all_attempts), format, out);
  }
  return 0;
}

}  // namespace totalgrad::cli
