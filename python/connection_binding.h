// The connection every results and sweep call of the Python module goes
// through: cli::Connection as the CLI opens it (a coordinator over gRPC with
// the CLI's TLS, token and environment defaults, or a database file read
// in-process through the same service handlers), and the one mapping of its
// errors to Python exceptions.
#ifndef TOTALGRAD_PYTHON_CONNECTION_BINDING_H_
#define TOTALGRAD_PYTHON_CONNECTION_BINDING_H_

#include <pybind11/pybind11.h>

#include <optional>
#include <string>

#include <grpcpp/support/status.h>

#include "absl/status/status.h"
#include "client/service_commands/connection.h"

namespace totalgrad::python {

// Raises the exception Python sees for a failed call: KeyError for a name
// that is not there (a sweep), ValueError for bad input, ConnectionError when
// no coordinator answered, RuntimeError otherwise; the message is the CLI's,
// prefixed with `what`.
[[noreturn]] void Raise(const absl::Status& status, const std::string& what);
[[noreturn]] void Raise(const grpc::Status& status, const std::string& what);

// Not thread-safe (one connection's calls), as the CLI's. Calls release the
// GIL while they wait.
class PyConnection {
 public:
  // Unset arguments take the CLI's defaults (TOTALGRAD_* variables); an
  // explicit coordinator wins over TOTALGRAD_DB.
  PyConnection(std::optional<std::string> db, std::optional<std::string> coordinator,
               std::optional<std::string> token_file, std::optional<std::string> ca_cert,
               std::optional<bool> insecure, double timeout_seconds);

  cli::Connection& connection() { return *connection_; }

 private:
  std::optional<cli::Connection> connection_;
};

// The sweep calls on the connection class (sweep_binding.cc): submit,
// sweep, cancel, pause, resume, export_archive.
void AddSweepMethods(pybind11::class_<PyConnection>& connection);

}  // namespace totalgrad::python

#endif  // TOTALGRAD_PYTHON_CONNECTION_BINDING_H_
