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

int EditDistance(const std::string& a, const std::string& b) {
  std::vector<int> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = static_cast<int>(j);
  for (size_t i = 1; i <= a.size(); ++i) {
    int diagonal = row[0];
    row[0] = static_cast<int>(i);
    for (size_t j = 1; j <= b.size(); ++j) {
      const int above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

std::string ClosestCandidate(const std::string& word, const std::vector<std::string>& candidates) {
  if (word.empty()) return "";
  std::string best;
  int best_distance = 1 << 30;
  for (const std::string& candidate : candidates) {
    const int d = EditDistance(word, candidate);
    if (d < best_distance) best_distance = d, best = candidate;
  }
  const int allowed = std::max<int>(1, static_cast<int>(word.size()) / 3);
  if (!best.empty() && best_distance > 0 && best_distance <= allowed) return best;
  std::string prefixed;
  for (const std::string& candidate : candidates) {
    if (candidate.size() > word.size() && candidate.compare(0, word.size(), word) == 0) {
      if (!prefixed.empty()) return "";  // ambiguous
      prefixed = candidate;
    }
  }
  return prefixed;
}

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
