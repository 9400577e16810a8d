// Results for Python over a PyConnection (connection_binding.h) and the
// results library's tables computed from it (results::ReadCompletedTrials,
// SuccessTable, CompareMethods, ComputeTable1). Each table comes back as the
// JSON array `totalgrad results ... -f json` prints, so a Python number is
// the CLI's bit for bit.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "client/service_commands/connection.h"
#include "client/service_commands/format.h"
#include "client/service_commands/rpc_results_reader.h"
#include "client/service_commands/streamed_reads.h"
#include "io/record_format.h"
#include "python/bindings.h"
#include "python/connection_binding.h"
#include "results/comparison.h"
#include "results/completed_trial.h"
#include "results/diagnostics.h"
#include "results/stats.h"
#include "results/table1.h"
#include "results/table1_claims.h"
#include "server/service/convert.h"
#include "server/storage/service_records.h"

namespace py = pybind11;

namespace totalgrad::python {

[[noreturn]] void Raise(const absl::Status& status, const std::string& what) {
  const std::string message = what + ": " + std::string(status.message());
  switch (status.code()) {
    case absl::StatusCode::kNotFound: throw py::key_error(message);
    case absl::StatusCode::kInvalidArgument:
    case absl::StatusCode::kAlreadyExists: throw py::value_error(message);
    case absl::StatusCode::kUnavailable:
    case absl::StatusCode::kDeadlineExceeded:
      PyErr_SetString(PyExc_ConnectionError, message.c_str());
      throw py::error_already_set();
    default: throw std::runtime_error(message);
  }
}

[[noreturn]] void Raise(const grpc::Status& status, const std::string& what) {
  Raise(cli::ToAbslStatus(status), what);
}

PyConnection::PyConnection(std::optional<std::string> db, std::optional<std::string> coordinator,
                           std::optional<std::string> token_file,
                           std::optional<std::string> ca_cert, std::optional<bool> insecure,
                           double timeout_seconds) {
  cli::ServiceFlags flags = cli::ServiceFlagsFromEnvironment();
  if (db) flags.db = *db;
  if (coordinator) {
    flags.connection.target = *coordinator;
    if (!db) flags.db.clear();
  }
  if (token_file) flags.token_file = *token_file;
  if (ca_cert) flags.connection.ca_cert_file = *ca_cert;
  if (insecure) flags.connection.insecure = *insecure;
  flags.timeout_seconds = timeout_seconds;
  flags.format = "json";
  absl::StatusOr<cli::Connection> connection = [&] {
    py::gil_scoped_release release;
    return cli::Connection::Open(flags);
  }();
  if (!connection.ok()) Raise(connection.status(), "connect");
  connection_.emplace(*std::move(connection));
}

namespace {

template <typename R>
std::string RecordsJson(const record::FieldTable<R>& table, const std::vector<R>& records) {
  std::ostringstream out;
  cli::PrintRecords(table, records, cli::Format::kJson, out);
  return out.str();
}

std::vector<results::CompletedTrial> ReadTrials(PyConnection& self,
                                                const std::vector<std::string>& sweeps,
                                                const std::string& what) {
  if (sweeps.empty()) throw py::value_error(what + ": name at least one sweep");
  absl::StatusOr<std::vector<results::CompletedTrial>> trials;
  {
    py::gil_scoped_release release;
    cli::RpcResultsReader reader(&self.connection());
    trials = results::ReadCompletedTrials(reader, sweeps);
  }
  if (!trials.ok()) Raise(trials.status(), what);
  return *std::move(trials);
}

// `totalgrad sweep list -f json`.
std::string Sweeps(PyConnection& self) {
  v1::ListSweepsResponse response;
  grpc::Status status;
  {
    py::gil_scoped_release release;
    status = self.connection().Call(&v1::ControlService::Stub::ListSweeps,
                                    v1::ListSweepsRequest(), &response);
  }
  if (!status.ok()) Raise(status, "sweeps");
  std::vector<storage::SweepRecord> sweeps;
  for (const v1::SweepInfo& info : response.sweeps()) sweeps.push_back(service::FromProto(info));
  return RecordsJson(storage::SweepFields(), sweeps);
}

// `totalgrad job list --sweep SWEEP -f json`.
std::string Jobs(PyConnection& self, const std::string& sweep) {
  std::vector<storage::JobRecord> jobs;
  grpc::Status status;
  {
    py::gil_scoped_release release;
    v1::ListJobsRequest request;
    request.set_sweep_name(sweep);
    status = cli::ForEachJobPage(&self.connection(), request, [&](const v1::ListJobsResponse& page) {
      for (const v1::JobInfo& info : page.jobs()) jobs.push_back(service::FromProto(info));
      return grpc::Status::OK;
    });
  }
  if (!status.ok()) Raise(status, "jobs " + sweep);
  return RecordsJson(storage::JobFields(), jobs);
}

// `results export SWEEP -f jsonl`: one JSON object a line.
std::string Episodes(PyConnection& self, const std::string& sweep, bool all_attempts) {
  std::string lines;
  grpc::Status status;
  {
    py::gil_scoped_release release;
    status = cli::ForEachEpisodeRowWithJob(
        &self.connection(), sweep, all_attempts,
        [&](const v1::EpisodeRow& row, const v1::JobInfo& job) {
          lines += cli::EpisodeRowJson(row, &job).dump();
          lines += '\n';
        });
  }
  if (!status.ok()) Raise(status, "episodes " + sweep);
  return lines;
}

// `results compare SWEEP -f json [--baseline B] [--alpha A]`.
std::string Compare(PyConnection& self, const std::vector<std::string>& sweeps,
                    const std::string& baseline, double alpha) {
  results::ComparisonOptions options;
  options.baseline = baseline;
  options.alpha = alpha;
  const absl::StatusOr<results::ComparisonReport> report =
      results::CompareMethods(ReadTrials(self, sweeps, "compare"), options);
  if (!report.ok()) Raise(report.status(), "compare");
  std::ostringstream out;
  cli::Print(cli::ComparisonListing(*report, alpha), cli::Format::kJson, out);
  return out.str();
}

// `results table1 SWEEP... -f json --view grid|sensitivity|comparisons`.
std::string Table1(PyConnection& self, const std::vector<std::string>& sweeps,
                   const std::string& view, const std::vector<double>& thresholds) {
  const absl::StatusOr<results::Table1> table =
      results::ComputeTable1(ReadTrials(self, sweeps, "table1"));
  if (!table.ok()) Raise(table.status(), "table1");
  if (view == "grid") return RecordsJson(results::Table1CellFields(), table->cells);
  if (view == "sensitivity") {
    return RecordsJson(results::ThresholdRateFields(),
                       results::ThresholdSensitivity(
                           *table, thresholds.empty() ? results::DefaultSensitivityThresholds()
                                                      : thresholds));
  }
  if (view == "comparisons") {
    return RecordsJson(results::ClaimComparisonFields(), results::CompareClaims(*table));
  }
  throw py::value_error("table1: view '" + view +
                        "' is not one of grid, sensitivity, comparisons");
}

// `results diagnostics SWEEP [--statistic S] -f json`.
std::string Diagnostics(PyConnection& self, const std::string& sweep, const std::string& statistic) {
  absl::StatusOr<std::vector<results::DiagnosticPoint>> points;
  {
    py::gil_scoped_release release;
    points = cli::ReadDiagnostics(&self.connection(), sweep, statistic);
  }
  if (!points.ok()) Raise(points.status(), "diagnostics " + sweep);
  return RecordsJson(results::DiagnosticPointFields(), *points);
}

// `results curves SWEEP -f json`; with `top` > 0 the curves of each method's
// and variant's `top` best runs (results::BestRuns, Figure 3's last panel).
std::string Curves(PyConnection& self, const std::string& sweep, int top) {
  if (top < 0) throw py::value_error("curves: top must be >= 1 (or None for every run)");
  absl::StatusOr<std::vector<results::EpisodeValue>> values;
  {
    py::gil_scoped_release release;
    values = cli::ReadEvaluationCosts(&self.connection(), sweep);
  }
  if (!values.ok()) Raise(values.status(), "curves " + sweep);
  const std::vector<results::CurvePoint> curves =
      results::Curves(top > 0 ? results::BestRuns(*values, top) : *values);
  return RecordsJson(results::CurvePointFields(), curves);
}

// `totalgrad results import ARCHIVE --db DB`: the summary line it prints.
std::string ImportArchiveIntoFile(const std::string& archive, const std::string& db) {
  cli::ServiceFlags flags;
  flags.db = db;
  flags.db_writable = true;
  flags.format = "json";
  v1::ImportSweepResponse response;
  absl::Status opened;
  grpc::Status status;
  {
    py::gil_scoped_release release;
    absl::StatusOr<cli::Connection> connection = cli::Connection::Open(flags);
    opened = connection.status();
    if (connection.ok()) status = cli::ImportArchive(&*connection, archive, &response);
  }
  if (!opened.ok()) Raise(opened, "import into " + db);
  if (!status.ok()) Raise(status, "import " + archive);
  return cli::ImportSummary(response);
}

}  // namespace

void AddResultsBindings(py::module_& module) {
  py::class_<PyConnection> connection(module, "_Connection");
  connection
      .def(py::init<std::optional<std::string>, std::optional<std::string>,
                    std::optional<std::string>, std::optional<std::string>, std::optional<bool>,
                    double>(),
           py::arg("db"), py::arg("coordinator"), py::arg("token_file"), py::arg("ca_cert"),
           py::arg("insecure"), py::arg("timeout_seconds"))
      .def("sweeps", &Sweeps)
      .def("jobs", &Jobs, py::arg("sweep"))
      .def("episodes", &Episodes, py::arg("sweep"), py::arg("all_attempts"))
      .def("trials",
           [](PyConnection& self, const std::vector<std::string>& sweeps) {
             return RecordsJson(results::CompletedTrialFields(), ReadTrials(self, sweeps, "trials"));
           },
           py::arg("sweeps"))
      .def("success_table",
           [](PyConnection& self, const std::vector<std::string>& sweeps) {
             return RecordsJson(results::TableCellFields(),
                                results::SuccessTable(ReadTrials(self, sweeps, "success_table")));
           },
           py::arg("sweeps"))
      .def("compare", &Compare, py::arg("sweeps"), py::arg("baseline"), py::arg("alpha"))
      .def("diagnostics", &Diagnostics, py::arg("sweep"), py::arg("statistic"))
      .def("curves", &Curves, py::arg("sweep"), py::arg("top"))
      .def("table1", &Table1, py::arg("sweeps"), py::arg("view"), py::arg("thresholds"));
  AddSweepMethods(connection);
  module.def("_import_archive", &ImportArchiveIntoFile, py::arg("archive"), py::arg("db"));
}

}  // namespace totalgrad::python
