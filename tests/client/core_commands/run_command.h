// Runs `totalgrad <args>` in process for the CLI tests: the in-process
// subcommands registered as main() registers them, parsed by CLI11, with
// stdout and stderr captured.
#ifndef TOTALGRAD_TESTS_CLIENT_CORE_COMMANDS_RUN_COMMAND_H_
#define TOTALGRAD_TESTS_CLIENT_CORE_COMMANDS_RUN_COMMAND_H_

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "client/core_commands/commands.h"
#include "tests/testutil/test_base.h"

namespace totalgrad::cli::testing_support {

struct CommandRun {
  int exit_code = -1;  // 0 success, 1 the run failed, 2 bad usage or input
  std::string out, err;
};

inline CommandRun RunCommand(std::vector<std::string> args) {
  CLI::App app;
  app.require_subcommand(1);
  CommandRun run;
  run.exit_code = 0;
  AddSimulateCommand(&app, &run.exit_code);
  AddTrialCommand(&app, &run.exit_code);
  AddStudyCommand(&app, &run.exit_code);
  AddEvaluateCommand(&app, &run.exit_code);
  std::reverse(args.begin(), args.end());  // CLI11 takes the arguments reversed
  ::testing::internal::CaptureStdout();
  ::testing::internal::CaptureStderr();
  try {
    app.parse(args);
  } catch (const CLI::ParseError& e) {
    run.exit_code = app.exit(e) == 0 ? 0 : 2;
  }
  run.out = ::testing::internal::GetCapturedStdout();
  run.err = ::testing::internal::GetCapturedStderr();
  return run;
}

// An empty directory `name` under the test's temporary directory (emptied
// if a previous run left it).
inline std::string FreshDir(const std::string& name) {
  const std::string dir =
      (std::filesystem::path(::totalgrad::testing::MakeTempDir()) / name).string();
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace totalgrad::cli::testing_support

#endif  // TOTALGRAD_TESTS_CLIENT_CORE_COMMANDS_RUN_COMMAND_H_
