// totalgrad: the user CLI. In-process commands (trial, simulate, bench, ...)
// run the numerical core directly; service commands (sweep, job, results,
// worker, run) talk to a coordinator.
#include <CLI/CLI.hpp>

#include <cstdlib>
#include <iostream>
#include <string>
#include <vector>

#include "client/core_commands/cli_suggest.h"
#include "client/core_commands/commands.h"
#include "core/common/blas.h"
#ifdef TOTALGRAD_WITH_SERVICE
#include <grpc/support/log.h>

#include "client/service_commands/service_commands.h"
#include "runtime/build_info.h"
#endif

int main(int argc, char** argv) {
  totalgrad::SelectBlasKernels(argv);  // may re-execute this program (core/common/blas.h)
  CLI::App app{"totalgrad: total stochastic gradient experiments on the paper's cart-pole and "
               "PILCO's scenes (`totalgrad scenes`)"};
  app.require_subcommand(1);
#ifdef TOTALGRAD_WITH_SERVICE
  app.set_version_flag("--version", totalgrad::BuildId());
  // gRPC's own log lines (e.g. a TLS handshake against a plaintext server)
  // are noise next to the error the command prints; TOTALGRAD_GRPC_LOG=1
  // keeps them for debugging.
  const char* grpc_log = std::getenv("TOTALGRAD_GRPC_LOG");
  if (grpc_log == nullptr || std::string(grpc_log) != "1") {
    gpr_set_log_function([](gpr_log_func_args*) {});
  }
#else
  app.set_version_flag("--version", "totalgrad (core commands only)");
#endif
  int exit_code = 0;
  totalgrad::cli::AddSimulateCommand(&app, &exit_code);
  totalgrad::cli::AddTrialCommand(&app, &exit_code);
  totalgrad::cli::AddBenchCommand(&app, &exit_code);
  totalgrad::cli::AddPilcoCommand(&app, &exit_code);
  totalgrad::cli::AddStudyCommand(&app, &exit_code);
  totalgrad::cli::AddEvaluateCommand(&app, &exit_code);
  totalgrad::cli::AddScenesCommand(&app, &exit_code);
#ifdef TOTALGRAD_WITH_SERVICE
  totalgrad::cli::AddServiceCommands(&app, &exit_code);
#endif
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    if (code != 0) {
      const std::string hint =
          totalgrad::cli::SuggestFor(app, std::vector<std::string>(argv + 1, argv + argc));
      if (!hint.empty()) std::cerr << hint << "\n";
    }
    return code == 0 ? 0 : 2;
  }
  return exit_code;
}
