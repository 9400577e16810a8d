// Reading sweep files (sweep_spec.h: ParseSweepToml, LoadSweepFile): TOML
// to SweepSpec, each field checked on its own with FILE:LINE:COLUMN in the
// error; the whole-spec rules and the canonical form are in sweep_spec.cc.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <charconv>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <string_view>
#include <toml++/toml.h>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/learner/trial.h"
#include "io/study_file.h"
#include "runtime/status_macros.h"
#include "server/sweep/sweep_spec.h"

namespace totalgrad::sweep {
namespace {

// One option on the defaults a user's options start from: the scene's
// where the option is the scene (scene = "unicycle" takes its own cost and
// policy class; learner::TrialOptionsFromPairs).
absl::StatusOr<learner::TrialOptions> OptionAlone(const std::string& key, const std::string& value) {
  return learner::TrialOptionsFromPairs({{key, value}});
}

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

// Accepted by the runner and within the service's limits (the value's own
// check, before any whole-spec rule).
absl::Status CheckValue(const std::string& key, const std::string& value) {
  learner::TrialOptions scratch;
  RETURN_IF_ERROR(learner::SetTrialOption(key, value, &scratch));
  return CheckServiceLimits(key, value);
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
  if (!ValidSweepName(entry.name)) {
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

// The keys of `table` in the order the file gives them (toml++ iterates keys
// sorted; the file's order decides the job order).
std::vector<std::string> KeysInFileOrder(const toml::table& table) {
  std::vector<std::pair<toml::source_position, std::string>> order;
  for (auto&& [key, node] : table) {
    order.push_back({node.source().begin, std::string(key.str())});
  }
  std::sort(order.begin(), order.end(), [](const auto& a, const auto& b) {
    return a.first.line != b.first.line ? a.first.line < b.first.line
                                        : a.first.column < b.first.column;
  });
  std::vector<std::string> keys;
  for (auto& [position, key] : order) keys.push_back(std::move(key));
  return keys;
}

// One axis of [grid]: a list of values, or a range { first = A, count = N }
// of integers; each value checked on its own.
absl::StatusOr<GridAxis> ParseGridAxis(const toml::node& axis_node, const std::string& axis_key,
                                       const std::string& file_name) {
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
      absl::StatusOr<learner::TrialOptions> scratch = OptionAlone(axis_key, *value);
      absl::Status accepted = scratch.status();
      if (accepted.ok()) accepted = CheckServiceLimits(axis_key, *value);
      if (!accepted.ok()) {
        return FieldError(Where(file_name, item.source()), item_field, accepted.message());
      }
      // Checked alone against defaults, so an unknown method is named at its line.
      const absl::Status valid = scratch->Validate();
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
  return axis;
}

// [grid]: its axes in file order, appended to spec->grid.
absl::Status ParseGrid(const toml::table& grid, const std::string& file_name, SweepSpec* spec) {
  for (const std::string& axis_key : KeysInFileOrder(grid)) {
    absl::StatusOr<GridAxis> axis = ParseGridAxis(*grid.get(axis_key), axis_key, file_name);
    if (!axis.ok()) return axis.status();
    spec->grid.push_back(*std::move(axis));
  }
  return absl::OkStatus();
}

// [protocol]: each option checked on its own (OptionAlone), appended to spec->protocol in
// file order.
absl::Status ParseProtocol(const toml::table& protocol, const std::string& file_name,
                           SweepSpec* spec) {
  for (const std::string& option_key : KeysInFileOrder(protocol)) {
    const toml::node& option_node = *protocol.get(option_key);
    const std::string option_where = Where(file_name, option_node.source());
    const std::string field = absl::StrCat("protocol.", option_key);
    absl::StatusOr<std::string> value = ScalarText(option_node);
    if (!value.ok()) return FieldError(option_where, field, value.status().message());
    absl::StatusOr<learner::TrialOptions> scratch = OptionAlone(option_key, *value);
    absl::Status accepted = scratch.status();
    if (accepted.ok()) accepted = scratch->Validate();
    if (accepted.ok()) accepted = CheckServiceLimits(option_key, *value);
    if (!accepted.ok()) return FieldError(option_where, field, accepted.message());
    spec->protocol.emplace_back(option_key, *value);
  }
  return absl::OkStatus();
}

}  // namespace

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
      RETURN_IF_ERROR(ParseGrid(*grid, file_name, &spec));
    } else if (name == "protocol") {
      const auto* protocol = node.as_table();
      if (protocol == nullptr) return FieldError(where, name, "must be a table ([protocol])");
      RETURN_IF_ERROR(ParseProtocol(*protocol, file_name, &spec));
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
  if (status.ok()) {
    status = ForEachExpandedJob(checked, [](ExpandedJob&&) { return absl::OkStatus(); });
  }
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

}  // namespace totalgrad::sweep
