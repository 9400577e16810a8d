#include "client/core_commands/cli_suggest.h"

#include <algorithm>

namespace totalgrad::cli {
namespace {

std::vector<std::string> SubcommandNames(const CLI::App& app) {
  std::vector<std::string> names;
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; }))
    names.push_back(sub->get_name());
  return names;
}

std::vector<std::string> LongFlags(const CLI::App& app) {
  std::vector<std::string> flags;
  for (const CLI::Option* option : app.get_options()) {
    for (const std::string& name : option->get_lnames()) flags.push_back("--" + name);
  }
  return flags;
}

const CLI::App* Subcommand(const CLI::App& app, const std::string& name) {
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; }))
    if (sub->get_name() == name) return sub;
  return nullptr;
}

}  // namespace

std::string SuggestFor(const CLI::App& app, const std::vector<std::string>& args) {
  const CLI::App* current = &app;
  std::string path = app.get_name();  // CLI11 takes it from argv[0]
  if (const size_t slash = path.rfind('/'); slash != std::string::npos) path = path.substr(slash + 1);
  if (path.empty()) path = "totalgrad";
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& word = args[i];
    if (word.rfind("--", 0) == 0) {
      const std::string flag = word.substr(0, word.find('='));
      const std::vector<std::string> flags = LongFlags(*current);
      if (std::find(flags.begin(), flags.end(), flag) != flags.end()) continue;
      const std::string close = ClosestCandidate(flag, flags);
      if (close.empty()) return "";
      return "did you mean '" + close + "'? (`" + path + " --help` lists the options)";
    }
    if (word.rfind("-", 0) == 0) continue;  // a short flag or a negative number
    if (const CLI::App* sub = Subcommand(*current, word)) {
      current = sub;
      path += " " + word;
      continue;
    }
    const std::vector<std::string> names = SubcommandNames(*current);
    if (names.empty()) continue;  // a positional argument of a leaf command
    const std::string close = ClosestCandidate(word, names);
    if (close.empty()) return "";
    return "did you mean '" + path + " " + close + "'?";
  }
  return "";
}

}  // namespace totalgrad::cli
