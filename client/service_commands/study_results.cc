// `totalgrad results study SWEEP`: the rows of a sweep's study jobs (one per
// study cell; --references: one per reference gradient) as a table, CSV or
// JSON. CSV and JSON are the records' own layouts (io/record_format.h over
// study::CellFields() / ReferenceFields(): the columns of the study's
// table.csv and references.csv, the objects of its results.json), with the
// row's key (study, job_id, attempt, index) in front.
#include <filesystem>
#include <iostream>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "client/core_commands/study_plots.h"
#include "client/service_commands/connection.h"
#include "client/service_commands/streamed_reads.h"
#include "client/service_commands/format.h"
#include "core/study/study.h"
#include "io/record_format.h"
#include "runtime/record_proto.h"
#include "server/sweep/sweep_spec.h"

namespace totalgrad::cli {
namespace {

// A number for the text table (the layout of `totalgrad study`'s table).
std::string TableNumber(double value, int decimals = -1) {
  if (value != value) return "-";
  return decimals < 0 ? absl::StrFormat("%.3g", value) : FormatFixed(value, decimals);
}

std::vector<std::string> KeyColumns() { return {"study", "job_id", "attempt", "index"}; }

template <typename Row>
std::vector<std::string> KeyCells(const Row& row) {
  return {row.study(), std::to_string(row.job_id()), std::to_string(row.attempt()),
          std::to_string(row.index())};
}

template <typename Row>
nlohmann::ordered_json KeyJson(const Row& row) {
  nlohmann::ordered_json object = nlohmann::ordered_json::object();
  object["study"] = row.study();
  object["job_id"] = row.job_id();
  object["attempt"] = row.attempt();
  object["index"] = row.index();
  return object;
}

// The rows as their records' CSV or JSON, key first.
template <typename Record, typename Rows>
void PrintRecords(const record::FieldTable<Record>& table, const Rows& rows, Format format,
                  std::ostream& out) {
  if (format == Format::kCsv) {
    std::vector<std::string> columns = KeyColumns();
    for (const std::string& c : io::RecordCsvColumns(table)) columns.push_back(c);
    out << io::CsvLine(columns) << "\n";
    for (const auto& row : rows) {
      Record record;
      record_proto::RecordFromProto(table, row, &record);
      std::vector<std::string> cells = KeyCells(row);
      for (std::string& c : io::RecordCsvCells(table, record)) cells.push_back(std::move(c));
      out << io::CsvLine(cells) << "\n";
    }
    return;
  }
  nlohmann::ordered_json array = nlohmann::ordered_json::array();
  for (const auto& row : rows) {
    Record record;
    record_proto::RecordFromProto(table, row, &record);
    nlohmann::ordered_json object = KeyJson(row);
    io::AppendRecordJson(table, record, &object);
    array.push_back(std::move(object));
  }
  out << array.dump(2) << "\n";
}

Listing CellTable(const v1::ListStudyRowsResponse& response, bool all_attempts) {
  Listing listing;
  listing.columns = {"study", "estimator", "P", "H", "reps", "t_min_ms", "rel_rmse", "rel_bias",
                     "bias_noise", "cos", "ess", "k_lr", "nonfin", "err", "note"};
  if (all_attempts) listing.columns.insert(listing.columns.begin() + 1, "attempt");
  for (const auto& row : response.cells()) {
    study::CellResult c;
    record_proto::RecordFromProto(study::CellFields(), row, &c);
    std::vector<std::string> cells = {
        row.study(), c.estimator, c.particles > 0 ? std::to_string(c.particles) : "-",
        std::to_string(c.horizon), std::to_string(c.replicates),
        TableNumber(c.time_min_s * 1e3), TableNumber(c.rel_rmse), TableNumber(c.rel_bias),
        TableNumber(c.rel_bias_noise), TableNumber(c.cos_mean, 3), TableNumber(c.ess_mean, 3),
        TableNumber(c.k_lr_mean, 3), std::to_string(c.nonfinite), std::to_string(c.errors),
        study::CellNote(c)};
    if (all_attempts) cells.insert(cells.begin() + 1, std::to_string(row.attempt()));
    listing.rows.push_back(std::move(cells));
  }
  return listing;
}

Listing ReferenceTable(const v1::ListStudyRowsResponse& response) {
  Listing listing;
  listing.columns = {"study", "job_id", "attempt", "horizon", "norm", "relative_error", "floor",
                     "objective", "used", "replicates", "agreement_max_z", "agreement_mean_z2",
                     "agree", "seconds", "note"};
  for (const auto& row : response.references()) {
    study::ReferenceGradient r;
    record_proto::RecordFromProto(study::ReferenceFields(), row, &r);
    listing.rows.push_back(
        {row.study(), std::to_string(row.job_id()), std::to_string(row.attempt()),
         std::to_string(r.horizon), TableNumber(r.norm), TableNumber(r.relative_error),
         TableNumber(r.floor), TableNumber(r.objective), absl::StrJoin(r.used, ";"),
         absl::StrJoin(r.replicates, ";"), TableNumber(r.agreement_max_z),
         TableNumber(r.agreement_mean_z2), r.agree ? "1" : "0", TableNumber(r.seconds), r.note});
  }
  return listing;
}

// `results study --plot DIR`: each study's work-precision and horizon-sweep
// pictures, as `totalgrad study --output-dir` draws them (study_plots.h),
// into DIR/<study>/ from the stored rows and the sweep's study specs.
int PlotStudies(Connection* connection, const std::string& sweep_name,
                const v1::ListStudyRowsResponse& response, const std::string& dir) {
  v1::SweepRequest request;
  request.set_name(sweep_name);
  v1::SweepInfo sweep;
  const grpc::Status status = connection->Call(&v1::ControlService::Stub::GetSweep, request, &sweep);
  if (!status.ok()) return ReportError(status, "results study --plot " + sweep_name);
  const absl::StatusOr<sweep::SweepSpec> spec = sweep::SpecFromCanonicalJson(sweep.canonical_spec());
  if (!spec.ok()) return ReportError(spec.status(), "results study --plot " + sweep_name);
  int drawn = 0;
  for (const sweep::StudyEntry& entry : spec->studies) {
    study::StudyResult result;
    for (const auto& row : response.cells()) {
      if (row.study() != entry.name) continue;
      record_proto::RecordFromProto(study::CellFields(), row, &result.cells.emplace_back());
    }
    for (const auto& row : response.references()) {
      if (row.study() != entry.name) continue;
      record_proto::RecordFromProto(study::ReferenceFields(), row, &result.references.emplace_back());
    }
    if (result.cells.empty()) {
      std::cerr << "note: study " << entry.name << " has no stored cells yet; not drawn\n";
      continue;
    }
    const nlohmann::json doc = nlohmann::json::parse(entry.spec_json, nullptr, false);
    const absl::StatusOr<io::StudySpec> study_spec =
        doc.is_discarded() ? absl::InvalidArgumentError("the stored study spec is not JSON")
                           : io::ParseStudySpec(doc, /*base_dir=*/"");
    if (!study_spec.ok()) {
      return ReportError(study_spec.status(), "results study --plot: study " + entry.name);
    }
    result.scene = entry.name;
    const std::string out = (std::filesystem::path(dir) / entry.name).string();
    const absl::StatusOr<std::vector<std::string>> written =
        WriteStudyPlots(result, *study_spec, out, /*run_gnuplot=*/true);
    if (!written.ok()) return ReportError(written.status(), "results study --plot " + out);
    std::cerr << "plots of study " << entry.name << " written to " << out << "/\n";
    ++drawn;
  }
  if (drawn == 0) {
    std::cerr << "error: results study --plot: sweep " << sweep_name
              << " has no study with stored cells; nothing to plot\n";
    return 1;
  }
  return 0;
}

}  // namespace

int PrintStudyResults(Connection* connection, const std::string& sweep_name, Format format,
                      bool references, bool all_attempts, std::ostream& out,
                      const std::string& plot_dir) {
  v1::ListStudyRowsResponse response;
  const grpc::Status status = FetchStudyRows(connection, sweep_name, all_attempts, &response);
  if (!status.ok()) return ReportError(status, "results study " + sweep_name);
  if (!plot_dir.empty()) {
    if (all_attempts) {
      std::cerr << "error: results study: --plot draws the final attempts; drop --all-attempts\n";
      return 2;
    }
    if (const int code = PlotStudies(connection, sweep_name, response, plot_dir); code != 0) return code;
  }
  if (format != Format::kTable) {
    if (references) {
      PrintRecords(study::ReferenceFields(), response.references(), format, out);
    } else {
      PrintRecords(study::CellFields(), response.cells(), format, out);
    }
    return 0;
  }
  if (response.cells_size() == 0 && response.references_size() == 0) {
    out << "sweep " << sweep_name << ": no study rows stored yet\n";
    return 0;
  }
  out << "reference gradients (pooled; floor = 1.96 |SE| / |g*|):\n";
  Print(ReferenceTable(response), format, out);
  if (!references) {
    out << "\nstudy cells (t_min_ms: fastest single-threaded gradient):\n";
    Print(CellTable(response, all_attempts), format, out);
  }
  return 0;
}

}  // namespace totalgrad::cli
