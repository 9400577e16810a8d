#include "client/core_commands/trial_flags.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <set>

#include "absl/strings/numbers.h"

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_replace.h"

namespace totalgrad::cli {

namespace {

// A number as people write it: the shortest text that reads back as the same
// double ("0.1", not the canonical "0.10000000000000001"); other text as is.
std::string DisplayValue(const std::string& text) {
  double value;
  if (!absl::SimpleAtod(text, &value) || !std::isfinite(value)) return text;
  char buffer[64];
  const std::to_chars_result result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  if (result.ec != std::errc()) return text;
  return std::string(buffer, result.ptr);
}

}  // namespace

void AddTrialOptionFlags(CLI::App* cmd, const learner::TrialOptions& defaults,
                         TrialFlagValues* values, const std::vector<std::string>& skip) {
  for (const auto& [key, value] : learner::TrialOptionPairs(defaults)) {
    if (std::find(skip.begin(), skip.end(), key) != skip.end()) continue;
    const std::string flag = "--" + absl::StrReplaceAll(key, {{"_", "-"}});
    const bool scene_default = std::find(learner::SceneDefaultedKeys().begin(),
                                         learner::SceneDefaultedKeys().end(),
                                         key) != learner::SceneDefaultedKeys().end();
    const std::string default_text =
        scene_default ? absl::StrCat("default: the scene's (`totalgrad scenes`), ", DisplayValue(value),
                                     " on ", defaults.scene.scene)
                      : absl::StrCat("default ", DisplayValue(value));
    CLI::Option* option =
        cmd->add_option(flag, values->values[key], "trial option '" + key + "' (" + default_text + ")");
    // The value's type in the help (the option table's; the value itself is
    // parsed and checked by the table, so its messages stay the same).
    if (const auto* field = learner::TrialOptions::Table().Find(key); field != nullptr) {
      switch (field->type) {
        case OptionType::kNumber: option->type_name("NUMBER"); break;
        case OptionType::kInteger: option->type_name("INT"); break;
        case OptionType::kBool: option->type_name("true|false"); break;
        case OptionType::kChoice: option->type_name(absl::StrJoin(field->choices, "|")); break;
        case OptionType::kText: option->type_name("TEXT"); break;
      }
    }
  }
  cmd->add_option("--set", values->sets, "KEY=VALUE for any trial option (repeatable)");
}

absl::Status ApplyTrialOptionFlags(const TrialFlagValues& values, learner::TrialOptions* options) {
  std::vector<std::pair<std::string, std::string>> pairs;
  std::set<std::string> given;
  for (const auto& [key, value] : values.values) {
    if (value.empty()) continue;
    given.insert(key);
    pairs.emplace_back(key, value);
  }
  for (const std::string& kv : values.sets) {
    const size_t eq = kv.find('=');
    if (eq == std::string::npos)
      return absl::InvalidArgumentError(absl::StrCat("--set expects KEY=VALUE, got '", kv, "'"));
    const std::string key = kv.substr(0, eq);
    if (given.count(key) > 0) {
      return absl::InvalidArgumentError(absl::StrCat(
          "option '", key, "' is given twice (as --", absl::StrReplaceAll(key, {{"_", "-"}}),
          " and as --set ", key, "=...): give it once"));
    }
    given.insert(key);
    pairs.emplace_back(key, kv.substr(eq + 1));
  }
  // The scene's defaults (horizon, threshold) for what was not given.
  absl::StatusOr<learner::TrialOptions> parsed = learner::TrialOptionsFromPairs(pairs);
  if (!parsed.ok()) return parsed.status();
  *options = *std::move(parsed);
  return options->Validate();
}

}  // namespace totalgrad::cli
