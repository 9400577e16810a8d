// "Did you mean ...?" for the `totalgrad` command line: after CLI11 refuses
// the arguments, finds the first word it could not place and the closest
// subcommand or flag of the command it was parsing.
#ifndef TOTALGRAD_CLIENT_CORE_COMMANDS_CLI_SUGGEST_H_
#define TOTALGRAD_CLIENT_CORE_COMMANDS_CLI_SUGGEST_H_

#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "core/common/closest_word.h"

namespace totalgrad::cli {

using ::totalgrad::ClosestCandidate;  // core/common/closest_word.h
using ::totalgrad::EditDistance;

// A hint line ("did you mean 'sweep'?") for arguments `args` (argv without
// the program) that `app` refused, or "" when there is nothing to suggest.
// Looks at the deepest subcommand named in `args` and the first word after it
// that is neither one of its subcommands nor one of its options.
std::string SuggestFor(const CLI::App& app, const std::vector<std::string>& args);

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_CORE_COMMANDS_CLI_SUGGEST_H_
