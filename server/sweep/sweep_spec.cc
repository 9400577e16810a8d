#include "server/sweep/sweep_spec.h"

#include "absl/strings/str_format.h"
#include "core/learner/cost_model.h"

#include <openssl/evp.h>

#include <algorithm>
#include <charconv>
#include <limits>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string_view>
#include <toml++/toml.h>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "io/study_file.h"
#include "core/learner/trial.h"
#include "server/common/status_macros.h"

namespace totalgrad::sweep {
namespace {

// Where a field came from, for error messages.
std::string Where(const std::string& file, const toml::source_region& source) {
  return absl::StrCat(file, ":", source.begin.line, ":", source.begin.column);
}

absl::Status FieldError(const std::string& where, absl::string_view field,
                        absl::string_view message) {
  return absl::InvalidArgumentError(absl::StrCat(where, ": ", field, ": ", message));
}

std::string FormatDouble(double value) {
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

// A scalar TOML value as the text the trial runner parses.
absl::StatusOr<std::string> ScalarText(const toml::node& node) {
  if (const auto* s = node.as_string()) return std::string(s->get());
  if (const auto* i = node.as_integer()) return std::to_string(i->get());
  if (const auto* f = node.as_floating_point()) return FormatDouble(f->get());
  if (const auto* b = node.as_boolean()) return std::string(b->get() ? "true" : "false");
  return absl::InvalidArgumentError("must be a string, number or boolean");
}

absl::StatusOr<int> NonNegativeInt(const toml::node& node) {
  const auto* i = node.as_integer();
  if (i == nullptr) return absl::InvalidArgumentError("must be an integer");
  if (i->get() < 0 || i->get() > 1'000'000) {
    return absl::InvalidArgumentError(absl::StrCat("must be in 0..1000000, got ", i->get()));
  }
  return static_cast<int>(i->get());
}

// The runner's canonical text for one option value.
absl::StatusOr<std::string> CanonicalValue(const std::string& key, const std::string& value) {
  learner::TrialOptions options;
  RETURN_IF_ERROR(learner::SetTrialOption(key, value, &options));
  for (const auto& [k, v] : learner::TrialOptionPairs(options)) {
    if (k == key) return v;
  }
  return value;
}

// Accepted by the runner and within the service's limits (the value's own
// check, before any whole-spec rule).
absl::Status CheckValue(const std::string& key, const std::string& value) {
  learner::TrialOptions scratch;
  RETURN_IF_ERROR(learner::SetTrialOption(key, value, &scratch));
  return CheckServiceLimits(key, value);
}

bool ValidName(const std::string& name) {
  if (name.empty() || name.size() > 64) return false;
  for (char c : name) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '.' || c == '_' || c == '-';
    if (!ok) return false;
  }
  return true;
}

// Options for one grid point: defaults, then protocol, then the point's values.
absl::StatusOr<learner::TrialOptions> OptionsAt(const SweepSpec& spec,
                                                const std::vector<size_t>& index) {
  learner::TrialOptions options;
  for (const auto& [key, value] : spec.protocol) {
    RETURN_IF_ERROR(learner::SetTrialOption(key, value, &options));
  }
  for (size_t a = 0; a < spec.grid.size(); ++a) {
    RETURN_IF_ERROR(
        learner::SetTrialOption(spec.grid[a].key, spec.grid[a].values[index[a]], &options));
  }
  return options;
}

// One [[study]] table of a sweep file: name, and the study from `file` or
// `spec`, made self-contained (snapshot inlined) and checked.
absl::StatusOr<StudyEntry> ParseStudyEntry(const toml::table& table, size_t index,
                                           const std::string& file_name) {
  const std::string entry_where = Where(file_name, table.source());
  std::string field = absl::StrCat("study[", index, "]");
  for (auto&& [key, node] : table) {
    const std::string k(key.str());
    if (k != "name" && k != "file" && k != "spec" && k != "scene") {
      return FieldError(Where(file_name, node.source()), absl::StrCat(field, ".", k),
                        "unknown field; a [[study]] has name, one of file or spec, and "
                        "optionally scene");
    }
    if (node.as_string() == nullptr) {
      return FieldError(Where(file_name, node.source()), absl::StrCat(field, ".", k),
                        "must be a string");
    }
  }
  StudyEntry entry;
  const auto name = table["name"].value<std::string>();
  if (!name) return FieldError(entry_where, field, "name: missing (name = \"...\")");
  entry.name = *name;
  field = absl::StrCat("study[", index, "] '", entry.name, "'");
  if (!ValidName(entry.name)) {
    return FieldError(Where(file_name, table["name"].node()->source()), field,
                      "name: not a valid name (1 to 64 characters from A-Z a-z 0-9 . _ -)");
  }
  const auto file = table["file"].value<std::string>();
  const auto inline_spec = table["spec"].value<std::string>();
  if (file.has_value() == inline_spec.has_value()) {
    return FieldError(entry_where, field,
                      "needs exactly one of file = \"STUDY.json\" or spec = '''{...}'''");
  }
  const std::filesystem::path sweep_dir = std::filesystem::path(file_name).parent_path();
  nlohmann::json doc;
  std::string base_dir = sweep_dir.string();
  if (file) {
    std::filesystem::path path(*file);
    if (path.is_relative()) path = sweep_dir / path;
    absl::StatusOr<nlohmann::json> read = io::ReadStudyDocument(path.string());
    if (!read.ok()) {
      return FieldError(Where(file_name, table["file"].node()->source()), field,
                        read.status().message());
    }
    doc = *std::move(read);
    base_dir = path.parent_path().string();
    entry.source = path.string();
  } else {
    doc = nlohmann::json::parse(*inline_spec, nullptr, /*allow_exceptions=*/false);
    if (doc.is_discarded()) {
      return FieldError(Where(file_name, table["spec"].node()->source()), field,
                        "spec: not valid JSON");
    }
    entry.source = "inline";
  }
  const std::string study_where = file ? absl::StrCat(field, " (", entry.source, ")") : field;
  absl::StatusOr<nlohmann::json> inlined = io::InlineStudyDocument(doc, base_dir);
  if (!inlined.ok()) return FieldError(entry_where, study_where, inlined.status().message());
  if (const auto scene = table["scene"].value<std::string>(); scene) {
    inlined = io::SetStudyScene(*inlined, *scene);
    if (!inlined.ok()) {
      return FieldError(Where(file_name, table["scene"].node()->source()), study_where,
                        inlined.status().message());
    }
  }
  absl::StatusOr<std::string> canonical = CanonicalStudySpec(inlined->dump());
  if (!canonical.ok()) return FieldError(entry_where, study_where, canonical.status().message());
  entry.spec_json = *std::move(canonical);
  return entry;
}

}  // namespace

absl::StatusOr<std::string> CanonicalStudySpec(const std::string& spec_json) {
  if (spec_json.size() > kMaxStudySpecBytes) {
    return absl::InvalidArgumentError(absl::StrCat("the study spec is ", spec_json.size(),
                                                   " bytes with its snapshot; at most ",
                                                   kMaxStudySpecBytes));
  }
  const nlohmann::json doc = nlohmann::json::parse(spec_json, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded() || !doc.is_object()) {
    return absl::InvalidArgumentError("the study spec is not a JSON object");
  }
  absl::StatusOr<io::StudySpec> spec = io::ParseStudySpec(doc, /*base_dir=*/"");
  if (!spec.ok()) return spec.status();
  if (!spec->snapshot_file.empty()) {
    return absl::InvalidArgumentError(
        "problem.snapshot: a file name; a study sent to the service carries its snapshot "
        "inline (the sweep-file parser inlines it)");
  }
  return doc.dump();
}

absl::StatusOr<SweepSpec> ParseSweepToml(absl::string_view text, const std::string& file_name) {
  if (text.size() > kMaxSourceBytes) {
    return absl::InvalidArgumentError(absl::StrCat(file_name, ": the file is ", text.size(),
                                                   " bytes; sweep files are at most ",
                                                   kMaxSourceBytes));
  }
  toml::table root;
  try {
    root = toml::parse(std::string_view(text.data(), text.size()), file_name);
  } catch (const toml::parse_error& error) {
    return absl::InvalidArgumentError(
        absl::StrCat(Where(file_name, error.source()), ": ", std::string(error.description())));
  }
  SweepSpec spec;
  bool have_grid = false;
  for (auto&& [key, node] : root) {
    const std::string name(key.str());
    const std::string where = Where(file_name, node.source());
    if (name == "name" || name == "description") {
      const auto* value = node.as_string();
      if (value == nullptr) return FieldError(where, name, "must be a string");
      (name == "name" ? spec.name : spec.description) = std::string(value->get());
    } else if (name == "max_attempts" || name == "max_lost_leases" || name == "max_concurrent") {
      absl::StatusOr<int> value = NonNegativeInt(node);
      if (!value.ok()) return FieldError(where, name, value.status().message());
      (name == "max_attempts"      ? spec.max_attempts
       : name == "max_lost_leases" ? spec.max_lost_leases
                                   : spec.max_concurrent) = *value;
    } else if (name == "grid") {
      const auto* grid = node.as_table();
      if (grid == nullptr) return FieldError(where, name, "must be a table ([grid])");
      have_grid = true;
      // toml++ iterates keys sorted; the file's order decides the job order.
      std::vector<std::pair<toml::source_position, std::string>> order;
      for (auto&& [axis_key, axis_node] : *grid) {
        order.push_back({axis_node.source().begin, std::string(axis_key.str())});
      }
      std::sort(order.begin(), order.end(), [](const auto& a, const auto& b) {
        return a.first.line != b.first.line ? a.first.line < b.first.line
                                            : a.first.column < b.first.column;
      });
      for (const auto& [position, axis_key] : order) {
        const toml::node& axis_node = *grid->get(axis_key);
        const std::string axis_where = Where(file_name, axis_node.source());
        const std::string field = absl::StrCat("grid.", axis_key);
        GridAxis axis;
        axis.key = axis_key;
        if (const auto* array = axis_node.as_array()) {
          for (size_t i = 0; i < array->size(); ++i) {
            const toml::node& item = *array->get(i);
            absl::StatusOr<std::string> value = ScalarText(item);
            const std::string item_field = absl::StrCat(field, "[", i, "]");
            if (!value.ok()) {
              return FieldError(Where(file_name, item.source()), item_field,
                                value.status().message());
            }
            learner::TrialOptions scratch;
            absl::Status accepted = learner::SetTrialOption(axis_key, *value, &scratch);
            if (accepted.ok()) accepted = CheckServiceLimits(axis_key, *value);
            if (!accepted.ok()) {
              return FieldError(Where(file_name, item.source()), item_field, accepted.message());
            }
            // Checked alone against defaults, so an unknown method is named at its line.
            const absl::Status valid = scratch.Validate();
            if (!valid.ok()) {
              return FieldError(Where(file_name, item.source()), item_field, valid.message());
            }
            axis.values.push_back(*value);
          }
        } else if (const auto* range = axis_node.as_table()) {
          // { first = A, count = N }: A, A+1, ..., A+N-1 (integers, e.g. seeds).
          const auto first = (*range)["first"].value<int64_t>();
          const auto count = (*range)["count"].value<int64_t>();
          if (!first || !count || range->size() != 2) {
            return FieldError(axis_where, field,
                              "a range must be { first = INTEGER, count = INTEGER }");
          }
          if (*count < 1 || *count > kMaxJobsPerSweep) {
            return FieldError(axis_where, field, absl::StrCat("count must be in 1..",
                                                              kMaxJobsPerSweep));
          }
          if (*first > std::numeric_limits<int64_t>::max() - (*count - 1)) {
            return FieldError(axis_where, field, absl::StrCat(
                "first + count - 1 exceeds ", std::numeric_limits<int64_t>::max(),
                ", the largest integer a sweep file holds"));
          }
          for (int64_t i = 0; i < *count; ++i) {
            const std::string v = std::to_string(*first + i);
            const absl::Status accepted = CheckValue(axis_key, v);
            if (!accepted.ok()) return FieldError(axis_where, field, accepted.message());
            axis.values.push_back(v);
          }
        } else {
          return FieldError(axis_where, field,
                            "must be a list of values or a range { first = A, count = N }");
        }
        spec.grid.push_back(std::move(axis));
      }
    } else if (name == "protocol") {
      const auto* protocol = node.as_table();
      if (protocol == nullptr) return FieldError(where, name, "must be a table ([protocol])");
      std::vector<std::pair<toml::source_position, std::string>> order;
      for (auto&& [option_key, option_node] : *protocol) {
        order.push_back({option_node.source().begin, std::string(option_key.str())});
      }
      std::sort(order.begin(), order.end(), [](const auto& a, const auto& b) {
        return a.first.line != b.first.line ? a.first.line < b.first.line
                                            : a.first.column < b.first.column;
      });
      for (const auto& [position, option_key] : order) {
        const toml::node& option_node = *protocol->get(option_key);
        const std::string option_where = Where(file_name, option_node.source());
        const std::string field = absl::StrCat("protocol.", option_key);
        absl::StatusOr<std::string> value = ScalarText(option_node);
        if (!value.ok()) return FieldError(option_where, field, value.status().message());
        learner::TrialOptions scratch;
        absl::Status accepted = learner::SetTrialOption(option_key, *value, &scratch);
        if (accepted.ok()) accepted = scratch.Validate();
        if (accepted.ok()) accepted = CheckServiceLimits(option_key, *value);
        if (!accepted.ok()) return FieldError(option_where, field, accepted.message());
        spec.protocol.emplace_back(option_key, *value);
      }
    } else if (name == "study") {
      const auto* studies = node.as_array();
      if (studies == nullptr || !studies->is_array_of_tables()) {
        return FieldError(where, name, "must be an array of tables ([[study]] entries)");
      }
      for (size_t i = 0; i < studies->size(); ++i) {
        absl::StatusOr<StudyEntry> entry =
            ParseStudyEntry(*studies->get(i)->as_table(), i, file_name);
        if (!entry.ok()) return entry.status();
        spec.studies.push_back(*std::move(entry));
      }
    } else {
      return FieldError(where, name,
                        "unknown field; expected name, description, max_attempts, "
                        "max_lost_leases, max_concurrent, [grid], [protocol] or [[study]]");
    }
  }
  if (spec.name.empty()) {
    return absl::InvalidArgumentError(absl::StrCat(file_name, ": name: missing (name = \"...\")"));
  }
  if (!have_grid && spec.studies.empty()) {
    return absl::InvalidArgumentError(absl::StrCat(
        file_name, ": grid: missing ([grid] with at least method = [...], or [[study]] entries)"));
  }
  // Whole-spec rules (method axis, duplicates, limits, combinations), with the
  // file name in front.
  SweepSpec checked = spec;
  absl::Status status = CanonicalizeSpec(&checked);
  if (status.ok()) status = ExpandJobs(checked).status();
  if (!status.ok()) {
    return absl::InvalidArgumentError(absl::StrCat(file_name, ": ", status.message()));
  }
  return spec;
}

absl::StatusOr<SweepSpec> LoadSweepFile(const std::string& path, std::string* source_text) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::NotFoundError(absl::StrCat(path, ": cannot open the sweep file"));
  std::ostringstream buffer;
  buffer << in.rdbuf();
  std::string text = buffer.str();
  absl::StatusOr<SweepSpec> spec = ParseSweepToml(text, path);
  if (source_text != nullptr) *source_text = std::move(text);
  return spec;
}

absl::Status CanonicalizeSpec(SweepSpec* spec) {
  if (!ValidName(spec->name)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "name: '", spec->name, "' is not a valid sweep name (1 to 64 characters from "
        "A-Z a-z 0-9 . _ -)"));
  }
  if (spec->description.size() > 4096) {
    return absl::InvalidArgumentError("description: at most 4096 bytes");
  }
  if (spec->max_attempts < 0 || spec->max_lost_leases < 0 || spec->max_concurrent < 0) {
    return absl::InvalidArgumentError(
        "max_attempts, max_lost_leases and max_concurrent must be >= 0");
  }
  if (spec->max_attempts == 0) spec->max_attempts = kDefaultMaxAttempts;
  if (spec->max_lost_leases == 0) spec->max_lost_leases = kDefaultMaxLostLeases;
  std::set<std::string> keys;
  bool have_method = false;
  int64_t jobs = 1;
  for (GridAxis& axis : spec->grid) {
    const std::string field = absl::StrCat("grid.", axis.key);
    if (!keys.insert(axis.key).second) {
      return absl::InvalidArgumentError(absl::StrCat(field, ": the axis appears twice"));
    }
    if (axis.values.empty()) {
      return absl::InvalidArgumentError(absl::StrCat(field, ": needs at least one value"));
    }
    std::set<std::string> seen;
    for (size_t i = 0; i < axis.values.size(); ++i) {
      absl::StatusOr<std::string> canonical = CanonicalValue(axis.key, axis.values[i]);
      if (canonical.ok()) {
        const absl::Status limit = CheckServiceLimits(axis.key, *canonical);
        if (!limit.ok()) canonical = limit;
      }
      if (!canonical.ok()) {
        return absl::InvalidArgumentError(
            absl::StrCat(field, "[", i, "]: ", canonical.status().message()));
      }
      if (!seen.insert(*canonical).second) {
        return absl::InvalidArgumentError(absl::StrCat(
            field, "[", i, "]: '", axis.values[i], "' repeats an earlier value of the axis"));
      }
      axis.values[i] = *canonical;
    }
    if (axis.key == "method") have_method = true;
    jobs *= static_cast<int64_t>(axis.values.size());
    if (jobs > kMaxJobsPerSweep) {
      return absl::InvalidArgumentError(
          absl::StrCat("grid: more than ", kMaxJobsPerSweep, " jobs; split the sweep"));
    }
  }
  if (!have_method && !(spec->grid.empty() && !spec->studies.empty())) {
    return absl::InvalidArgumentError("grid.method: missing; a sweep names its methods");
  }
  if (spec->grid.empty() && !spec->protocol.empty()) {
    return absl::InvalidArgumentError("protocol: given without a [grid]; it applies to trials only");
  }
  if (static_cast<int>(spec->studies.size()) > kMaxStudiesPerSweep) {
    return absl::InvalidArgumentError(
        absl::StrCat("study: more than ", kMaxStudiesPerSweep, " entries; split the sweep"));
  }
  std::set<std::string> study_names;
  for (size_t i = 0; i < spec->studies.size(); ++i) {
    StudyEntry& entry = spec->studies[i];
    const std::string field = absl::StrCat("study[", i, "] '", entry.name, "'");
    if (!ValidName(entry.name)) {
      return absl::InvalidArgumentError(absl::StrCat(
          field, ": name: not a valid name (1 to 64 characters from A-Z a-z 0-9 . _ -)"));
    }
    if (!study_names.insert(entry.name).second) {
      return absl::InvalidArgumentError(
          absl::StrCat(field, ": name: repeats an earlier study's name"));
    }
    absl::StatusOr<std::string> canonical = CanonicalStudySpec(entry.spec_json);
    if (!canonical.ok()) {
      return absl::InvalidArgumentError(absl::StrCat(field, ": ", canonical.status().message()));
    }
    entry.spec_json = *std::move(canonical);
  }
  if (jobs + static_cast<int64_t>(spec->studies.size()) > kMaxJobsPerSweep) {
    return absl::InvalidArgumentError(
        absl::StrCat("more than ", kMaxJobsPerSweep, " jobs; split the sweep"));
  }
  std::set<std::string> protocol_keys;
  for (auto& [key, value] : spec->protocol) {
    const std::string field = absl::StrCat("protocol.", key);
    if (keys.count(key)) {
      return absl::InvalidArgumentError(
          absl::StrCat(field, ": also a grid axis; give it in one place"));
    }
    if (!protocol_keys.insert(key).second) {
      return absl::InvalidArgumentError(absl::StrCat(field, ": given twice"));
    }
    absl::StatusOr<std::string> canonical = CanonicalValue(key, value);
    if (canonical.ok()) {
      const absl::Status limit = CheckServiceLimits(key, *canonical);
      if (!limit.ok()) canonical = limit;
    }
    if (!canonical.ok()) {
      return absl::InvalidArgumentError(absl::StrCat(field, ": ", canonical.status().message()));
    }
    value = *canonical;
  }
  // Each key sets its own option: the order of [protocol] means nothing, so
  // the canonical form sorts it (reordered files are the same sweep).
  std::sort(spec->protocol.begin(), spec->protocol.end());
  return absl::OkStatus();
}

absl::Status CheckServiceLimits(const std::string& key, const std::string& value) {
  if (key == "episodes") {
    int64_t episodes = 0;
    if (absl::SimpleAtoi(value, &episodes) && episodes > kMaxTrialEpisodes) {
      return absl::InvalidArgumentError(absl::StrCat(
          "option 'episodes' is ", value, "; the service runs trials of at most ",
          kMaxTrialEpisodes, " learned episodes"));
    }
  }
  if (key == "seed") {
    // Seeds travel as JSON numbers (archives, the dashboard, pandas); a double
    // holds every integer below 2^53 exactly and no larger one reliably.
    uint64_t seed = 0;
    if (absl::SimpleAtoi(value, &seed) && seed >= kMaxExactSeed) {
      return absl::InvalidArgumentError(absl::StrCat(
          "seed ", value, " is too large; the service takes seeds in [0, 2^53) = [0, ",
          kMaxExactSeed, ") so that every reader of the results sees the same integer"));
    }
  }
  return absl::OkStatus();
}

std::string LegacySpecHash(const SweepSpec& canonical,
                           const std::vector<std::string>& protocol_order) {
  SweepSpec legacy = canonical;
  std::stable_sort(legacy.protocol.begin(), legacy.protocol.end(),
                   [&](const auto& a, const auto& b) {
                     const auto rank = [&](const std::string& key) {
                       return std::find(protocol_order.begin(), protocol_order.end(), key) -
                              protocol_order.begin();
                     };
                     return rank(a.first) < rank(b.first);
                   });
  return SpecHash(legacy);
}

std::string CanonicalJson(const SweepSpec& spec) {
  nlohmann::json grid = nlohmann::json::array();
  for (const GridAxis& axis : spec.grid) grid.push_back({axis.key, axis.values});
  nlohmann::json protocol = nlohmann::json::array();
  for (const auto& [key, value] : spec.protocol) protocol.push_back({key, value});
  nlohmann::json json = {{"name", spec.name},
                         {"description", spec.description},
                         {"grid", grid},
                         {"protocol", protocol},
                         {"max_attempts", spec.max_attempts},
                         {"max_lost_leases", spec.max_lost_leases},
                         {"max_concurrent", spec.max_concurrent}};
  // Only sweeps with studies carry the key, so older sweeps keep their hash.
  if (!spec.studies.empty()) {
    nlohmann::json studies = nlohmann::json::array();
    for (const StudyEntry& entry : spec.studies) studies.push_back({entry.name, entry.spec_json});
    json["studies"] = studies;
  }
  return json.dump();  // keys sorted, no whitespace: deterministic
}

absl::StatusOr<SweepSpec> UnionOfSweeps(const SweepSpec& stored, const SweepSpec& submitted) {
  auto differs = [&](const std::string& what) {
    return absl::FailedPreconditionError(absl::StrCat(
        "sweep '", stored.name, "' exists with another ", what,
        "; a submitted sweep may only add values to the grid's axes or add studies (use a new "
        "sweep name for another protocol)"));
  };
  if (stored.grid.size() != submitted.grid.size()) {
    return differs(absl::StrCat("grid (", stored.grid.size(), " axes there, ",
                                submitted.grid.size(), " here)"));
  }
  SweepSpec merged = stored;
  merged.description = submitted.description;
  for (size_t a = 0; a < stored.grid.size(); ++a) {
    if (stored.grid[a].key != submitted.grid[a].key) {
      return differs(absl::StrCat("grid: axis ", a + 1, " is '", stored.grid[a].key,
                                  "' there and '", submitted.grid[a].key, "' here"));
    }
    std::vector<std::string>& values = merged.grid[a].values;
    for (const std::string& value : submitted.grid[a].values) {
      if (std::find(values.begin(), values.end(), value) == values.end()) values.push_back(value);
    }
  }
  std::map<std::string, std::string> stored_protocol(stored.protocol.begin(), stored.protocol.end());
  std::map<std::string, std::string> submitted_protocol(submitted.protocol.begin(),
                                                        submitted.protocol.end());
  for (const auto& [key, value] : submitted_protocol) {
    auto it = stored_protocol.find(key);
    if (it == stored_protocol.end()) return differs(absl::StrCat("protocol (no '", key, "' there)"));
    if (it->second != value) {
      return differs(absl::StrCat("protocol (", key, " = ", it->second, " there, ", value, " here)"));
    }
  }
  for (const auto& [key, value] : stored_protocol) {
    if (submitted_protocol.count(key) == 0) return differs(absl::StrCat("protocol (no '", key, "' here)"));
  }
  if (stored.max_attempts != submitted.max_attempts) return differs("max_attempts");
  if (stored.max_lost_leases != submitted.max_lost_leases) return differs("max_lost_leases");
  if (stored.max_concurrent != submitted.max_concurrent) return differs("max_concurrent");
  for (const StudyEntry& study : submitted.studies) {
    auto it = std::find_if(merged.studies.begin(), merged.studies.end(),
                           [&](const StudyEntry& s) { return s.name == study.name; });
    if (it == merged.studies.end()) {
      merged.studies.push_back(study);
    } else if (it->spec_json != study.spec_json) {
      return differs(absl::StrCat("study '", study.name, "'"));
    }
  }
  return merged;
}

absl::StatusOr<SweepSpec> SpecFromCanonicalJson(const std::string& text) {
  const nlohmann::json json = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!json.is_object()) return absl::InvalidArgumentError("canonical spec: not a JSON object");
  auto bad = [](const std::string& field) {
    return absl::InvalidArgumentError(absl::StrCat("canonical spec: '", field, "' is missing or mistyped"));
  };
  SweepSpec spec;
  if (!json.contains("name") || !json["name"].is_string()) return bad("name");
  spec.name = json["name"].get<std::string>();
  if (!json.contains("description") || !json["description"].is_string()) return bad("description");
  spec.description = json["description"].get<std::string>();
  for (const char* key : {"max_attempts", "max_lost_leases", "max_concurrent"}) {
    if (!json.contains(key) || !json[key].is_number_integer()) return bad(key);
  }
  spec.max_attempts = json["max_attempts"].get<int>();
  spec.max_lost_leases = json["max_lost_leases"].get<int>();
  spec.max_concurrent = json["max_concurrent"].get<int>();
  if (!json.contains("grid") || !json["grid"].is_array()) return bad("grid");
  for (const auto& axis : json["grid"]) {
    if (!axis.is_array() || axis.size() != 2 || !axis[0].is_string() || !axis[1].is_array())
      return bad("grid[]");
    GridAxis g;
    g.key = axis[0].get<std::string>();
    for (const auto& value : axis[1]) {
      if (!value.is_string()) return bad("grid[].values");
      g.values.push_back(value.get<std::string>());
    }
    spec.grid.push_back(std::move(g));
  }
  if (!json.contains("protocol") || !json["protocol"].is_array()) return bad("protocol");
  for (const auto& pair : json["protocol"]) {
    if (!pair.is_array() || pair.size() != 2 || !pair[0].is_string() || !pair[1].is_string())
      return bad("protocol[]");
    spec.protocol.emplace_back(pair[0].get<std::string>(), pair[1].get<std::string>());
  }
  if (json.contains("studies")) {
    if (!json["studies"].is_array()) return bad("studies");
    for (const auto& entry : json["studies"]) {
      if (!entry.is_array() || entry.size() != 2 || !entry[0].is_string() || !entry[1].is_string())
        return bad("studies[]");
      StudyEntry study;
      study.name = entry[0].get<std::string>();
      study.spec_json = entry[1].get<std::string>();
      study.source = "inline";
      spec.studies.push_back(std::move(study));
    }
  }
  return spec;
}

std::string SpecHash(const SweepSpec& spec) {
  const std::string text = CanonicalJson(spec);
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  EVP_Digest(text.data(), text.size(), digest, &length, EVP_sha256(), nullptr);
  static constexpr char kHex[] = "0123456789abcdef";
  std::string hex;
  for (unsigned int i = 0; i < length; ++i) {
    hex.push_back(kHex[digest[i] >> 4]);
    hex.push_back(kHex[digest[i] & 15]);
  }
  return hex;
}

absl::StatusOr<std::vector<ExpandedJob>> ExpandJobs(const SweepSpec& spec) {
  std::vector<ExpandedJob> jobs;
  if (spec.grid.empty() && spec.studies.empty()) return absl::InvalidArgumentError("grid: empty");
  std::vector<size_t> index(spec.grid.size(), 0);
  while (!spec.grid.empty()) {
    absl::StatusOr<learner::TrialOptions> options = OptionsAt(spec, index);
    absl::Status valid = options.ok() ? options->Validate() : options.status();
    std::vector<std::string> point;
    std::vector<std::string> variant;
    for (size_t a = 0; a < spec.grid.size(); ++a) {
      const std::string pair = absl::StrCat(spec.grid[a].key, "=", spec.grid[a].values[index[a]]);
      point.push_back(pair);
      if (spec.grid[a].key != "method" && spec.grid[a].key != "seed") variant.push_back(pair);
    }
    if (!valid.ok()) {
      return absl::InvalidArgumentError(
          absl::StrCat("grid point {", absl::StrJoin(point, ", "), "}: ", valid.message()));
    }
    if (options->episodes > kMaxTrialEpisodes) {  // e.g. a default changed; never overflow below
      return absl::InvalidArgumentError(absl::StrCat(
          "grid point {", absl::StrJoin(point, ", "), "}: option 'episodes' is ",
          options->episodes, "; the service runs trials of at most ", kMaxTrialEpisodes,
          " learned episodes"));
    }
    ExpandedJob job;
    job.method = estimators::MethodName(options->method);
    job.seed = std::to_string(options->seed);
    job.variant = absl::StrJoin(variant, " ");
    job.options = learner::TrialOptionPairs(*options);
    job.episodes_expected = options->episodes + 1;
    jobs.push_back(std::move(job));
    // Odometer: the last axis varies fastest.
    size_t a = spec.grid.size();
    bool done = false;
    while (a > 0) {
      --a;
      if (++index[a] < spec.grid[a].values.size()) break;
      index[a] = 0;
      if (a == 0) done = true;
    }
    if (done) break;
  }
  for (size_t i = 0; i < spec.studies.size(); ++i) {
    const StudyEntry& entry = spec.studies[i];
    const nlohmann::json doc =
        nlohmann::json::parse(entry.spec_json, nullptr, /*allow_exceptions=*/false);
    absl::StatusOr<io::StudySpec> parsed =
        doc.is_object() ? io::ParseStudySpec(doc, "")
                        : absl::StatusOr<io::StudySpec>(
                              absl::InvalidArgumentError("not a JSON object"));
    if (!parsed.ok()) {
      return absl::InvalidArgumentError(
          absl::StrCat("study[", i, "] '", entry.name, "': ", parsed.status().message()));
    }
    ExpandedJob job;
    job.kind = JobKind::kStudy;
    job.payload = entry.spec_json;
    job.method = "study";
    job.seed = std::to_string(parsed->options.seed);
    job.variant = entry.name;
    job.episodes_expected = 0;
    jobs.push_back(std::move(job));
  }
  return jobs;
}

absl::StatusOr<OptionList> ResolveOptions(const OptionList& pairs) {
  learner::TrialOptions options;
  for (const auto& [key, value] : pairs) {
    RETURN_IF_ERROR(learner::SetTrialOption(key, value, &options));
  }
  RETURN_IF_ERROR(options.Validate());
  return learner::TrialOptionPairs(options);
}

std::string SweepCostEstimate::Text() const {
  const double hours = cpu_seconds / 3600.0;
  std::string text = hours >= 1.0 ? absl::StrFormat("about %.1f CPU hours", hours)
                                  : absl::StrFormat("about %.0f CPU minutes", cpu_seconds / 60.0);
  absl::StrAppend(&text, " for ", trials, trials == 1 ? " trial" : " trials",
                  " (cost model of docs/results/cost-model.md; reference machine: ",
                  reference_machine, ")");
  if (studies > 0) absl::StrAppend(&text, "; ", studies, " study jobs not estimated");
  return text;
}

absl::StatusOr<SweepCostEstimate> EstimateSweepCost(const SweepSpec& spec) {
  SweepSpec canonical = spec;
  if (absl::Status st = CanonicalizeSpec(&canonical); !st.ok()) return st;
  absl::StatusOr<std::vector<ExpandedJob>> jobs = ExpandJobs(canonical);
  if (!jobs.ok()) return jobs.status();
  SweepCostEstimate estimate;
  estimate.reference_machine = learner::kReferenceMachine;
  for (const ExpandedJob& job : *jobs) {
    if (job.kind == JobKind::kStudy) {
      ++estimate.studies;
      continue;
    }
    learner::TrialOptions options;
    for (const auto& [key, value] : job.options) {
      if (absl::Status st = learner::SetTrialOption(key, value, &options); !st.ok()) return st;
    }
    ++estimate.trials;
    estimate.cpu_seconds += learner::EstimateTrialCost(options).total_cpu();
  }
  return estimate;
}

}  // namespace totalgrad::sweep
