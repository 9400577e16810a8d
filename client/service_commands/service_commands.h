// Registration of the `totalgrad` subcommands that talk to a coordinator:
// sweep, job, worker, results, admin, and `run` (the embedded default).
//
// Exit codes: 0 success; 1 the operation failed (e.g. a sweep waited on
// finished with failed jobs, or the coordinator refused a call); 2 bad usage
// or input (malformed sweep file, unknown name); 3 the coordinator could not
// be reached. Errors go to stderr naming the cause; results go to stdout.
#ifndef TOTALGRAD_CLIENT_SERVICE_COMMANDS_SERVICE_COMMANDS_H_
#define TOTALGRAD_CLIENT_SERVICE_COMMANDS_SERVICE_COMMANDS_H_

#include <CLI/CLI.hpp>

namespace totalgrad::cli {

void AddServiceCommands(CLI::App* app, int* exit_code);

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_SERVICE_COMMANDS_SERVICE_COMMANDS_H_
