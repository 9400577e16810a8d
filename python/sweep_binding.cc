// A coordinator's sweeps from Python, over the connection of
// results_binding.cc: submit a sweep (TOML text, parsed and validated by the
// sweep library as `totalgrad sweep submit` does), read its state, cancel,
// pause or resume it, and write its archive (`results export -f json`).
// Waiting with a progress line is the package's loop over `sweep`
// (python/totalgrad/__init__.py), so Ctrl-C simply ends the wait.
#include <pybind11/pybind11.h>

#include <fstream>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "client/service_commands/archive_export.h"
#include "client/service_commands/connection.h"
#include "client/service_commands/format.h"
#include "client/service_commands/output_file.h"
#include "io/record_format.h"
#include "python/connection_binding.h"
#include "server/service/convert.h"
#include "server/storage/service_records.h"
#include "server/sweep/sweep_proto.h"
#include "server/sweep/sweep_spec.h"

namespace py = pybind11;

namespace totalgrad::python {
namespace {

std::string SweepJson(const v1::SweepInfo& info) {
  return io::RecordToJson(storage::SweepFields(), service::FromProto(info)).dump();
}

// {"created", "jobs_added", "dry_run", "sweep": the sweep's record}.
std::string Submit(PyConnection& self, const std::string& toml_text,
                   const std::string& source_name, bool dry_run) {
  absl::StatusOr<sweep::SweepSpec> spec = sweep::ParseSweepToml(toml_text, source_name);
  if (!spec.ok()) throw py::value_error(std::string(spec.status().message()));
  v1::SubmitSweepRequest request;
  sweep::SweepSpecToProto(*spec, request.mutable_spec());
  request.set_source_name(source_name);
  request.set_source_text(toml_text);
  request.set_dry_run(dry_run);
  v1::SubmitSweepResponse response;
  grpc::Status status;
  {
    py::gil_scoped_release release;
    status = self.connection().Call(&v1::ControlService::Stub::SubmitSweep, request, &response);
  }
  if (!status.ok()) Raise(status, "submit " + source_name);
  const nlohmann::json out = {{"created", response.created()},
                              {"jobs_added", response.jobs_added()},
                              {"dry_run", dry_run},
                              {"sweep", nlohmann::json::parse(SweepJson(response.sweep()))}};
  return out.dump();
}

using SweepCall = grpc::Status (v1::ControlService::Stub::*)(grpc::ClientContext*,
                                                            const v1::SweepRequest&,
                                                            v1::SweepInfo*);

std::string CallOnSweep(PyConnection& self, const std::string& name, SweepCall method,
                        const std::string& what) {
  v1::SweepRequest request;
  request.set_name(name);
  v1::SweepInfo info;
  grpc::Status status;
  {
    py::gil_scoped_release release;
    status = self.connection().Call(method, request, &info);
  }
  if (!status.ok()) Raise(status, what + " " + name);
  return SweepJson(info);
}

// `results export SWEEP -f json [--checkpoints] -o PATH`: written to a
// temporary file renamed into place, so a failed export leaves no partial
// archive under `path`.
void ExportArchiveFile(PyConnection& self, const std::string& sweep_name, const std::string& path,
                       bool with_checkpoints) {
  absl::StatusOr<std::unique_ptr<cli::OutputFile>> file =
      cli::OutputFile::Create(path, cli::OutputFile::Existing::kReplace, 0644);
  if (!file.ok()) Raise(file.status(), "export " + sweep_name);
  int code;
  std::ostringstream errors;
  {
    py::gil_scoped_release release;
    // ExportArchive reports its errors on stderr; keep them for the exception.
    std::streambuf* previous = std::cerr.rdbuf(errors.rdbuf());
    code = cli::ExportArchive(&self.connection(), sweep_name, (*file)->stream(), with_checkpoints,
                              nullptr);
    std::cerr.rdbuf(previous);
  }
  if (code != 0) {
    throw std::runtime_error("export " + sweep_name + ": " + errors.str());
  }
  if (absl::Status st = (*file)->Commit(); !st.ok()) Raise(st, "export " + sweep_name);
}

}  // namespace

void AddSweepMethods(py::class_<PyConnection>& connection) {
  connection.def("submit", &Submit, py::arg("toml_text"), py::arg("source_name"),
                 py::arg("dry_run"));
  // Calls on one sweep by name, each returning the sweep's record.
  struct SweepControl {
    const char* name;
    SweepCall method;
  };
  for (const SweepControl& control :
       {SweepControl{"sweep", &v1::ControlService::Stub::GetSweep},
        SweepControl{"cancel", &v1::ControlService::Stub::CancelSweep},
        SweepControl{"pause", &v1::ControlService::Stub::PauseSweep},
        SweepControl{"resume", &v1::ControlService::Stub::ResumeSweep}}) {
    connection.def(
        control.name,
        [control](PyConnection& self, const std::string& name) {
          return CallOnSweep(self, name, control.method, control.name);
        },
        py::arg("name"));
  }
  connection.def("export_archive", &ExportArchiveFile, py::arg("sweep"), py::arg("path"),
                 py::arg("checkpoints"));
}

}  // namespace totalgrad::python
