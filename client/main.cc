// totalgrad: the user CLI. In-process commands (trial, simulate, bench, ...)
// run the numerical core directly; service commands (sweep, job, results,
// worker, run) talk to a coordinator.
#include <CLI/CLI.hpp>

#include "client/core_commands/commands.h"
#include "core/common/blas.h"
#ifdef TOTALGRAD_WITH_SERVICE
#include "client/service_commands/service_commands.h"
#endif

int main(int argc, char** argv) {
  totalgrad::SelectBlasKernels(argv);  // may re-execute this program (core/common/blas.h)
  CLI::App app{"totalgrad: total stochastic gradient experiments on the cart-pole"};
  app.require_subcommand(1);
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
    return code == 0 ? 0 : 2;
  }
  return exit_code;
}
