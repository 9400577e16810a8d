// Sweep specs after parsing (sweep_spec.h): the whole-spec rules and the
// canonical form, its hash (and the legacy hash), growing a stored sweep,
// expansion into jobs, and the cost estimate. Reading the TOML file is in
// sweep_toml.cc.
#include "server/sweep/sweep_spec.h"

#include "absl/strings/str_format.h"
#include "core/learner/cost_model.h"

#include <openssl/evp.h>

#include <algorithm>
#include <map>
#include <nlohmann/json.hpp>
#include <set>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "io/study_file.h"
#include "core/learner/trial.h"
#include "runtime/status_macros.h"

namespace totalgrad::sweep {
namespace {

// The runner's canonical text for one option value.
absl::StatusOr<std::string> CanonicalValue(const std::string& key, const std::string& value) {
  learner::TrialOptions options;
  RETURN_IF_ERROR(learner::SetTrialOption(key, value, &options));
  for (const auto& [k, v] : learner::TrialOptionPairs(options)) {
    if (k == key) return v;
  }
  return value;
}

// Options for one grid point: defaults (the scene's where the point's scene
// has its own, learner::TrialOptionsFromPairs), then protocol, then the
// point's values.
absl::StatusOr<learner::TrialOptions> OptionsAt(const SweepSpec& spec,
                                                const std::vector<size_t>& index) {
  OptionPairs pairs(spec.protocol.begin(), spec.protocol.end());
  for (size_t a = 0; a < spec.grid.size(); ++a) {
    pairs.emplace_back(spec.grid[a].key, spec.grid[a].values[index[a]]);
  }
  return learner::TrialOptionsFromPairs(pairs);
}

}  // namespace

bool ValidSweepName(const std::string& name) {
  if (name.empty() || name.size() > 64) return false;
  for (char c : name) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '.' || c == '_' || c == '-';
    if (!ok) return false;
  }
  return true;
}

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

absl::Status CanonicalizeSpec(SweepSpec* spec) {
  if (!ValidSweepName(spec->name)) {
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
    if (!ValidSweepName(entry.name)) {
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

absl::Status ForEachExpandedJob(const SweepSpec& spec,
                                const std::function<absl::Status(ExpandedJob&&)>& visit) {
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
    RETURN_IF_ERROR(visit(std::move(job)));
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
    RETURN_IF_ERROR(visit(std::move(job)));
  }
  return absl::OkStatus();
}

absl::StatusOr<std::vector<ExpandedJob>> ExpandJobs(const SweepSpec& spec) {
  std::vector<ExpandedJob> jobs;
  RETURN_IF_ERROR(ForEachExpandedJob(spec, [&](ExpandedJob&& job) {
    jobs.push_back(std::move(job));
    return absl::OkStatus();
  }));
  return jobs;
}

absl::StatusOr<OptionPairs> ResolveOptions(const OptionPairs& pairs) {
  ASSIGN_OR_RETURN(learner::TrialOptions options, learner::TrialOptionsFromPairs(pairs));
  RETURN_IF_ERROR(options.Validate());
  return learner::TrialOptionPairs(options);
}

std::string SweepCostEstimate::Text() const {
  const double hours = cpu_seconds / 3600.0;
  // A tiny sweep is seconds, not "about 0 CPU minutes".
  std::string text = hours >= 1.0 ? absl::StrFormat("about %.1f CPU hours", hours)
                     : cpu_seconds >= 90.0
                         ? absl::StrFormat("about %.0f CPU minutes", cpu_seconds / 60.0)
                         : absl::StrFormat("about %.0f CPU seconds", cpu_seconds);
  absl::StrAppend(&text, " for ", trials, trials == 1 ? " trial" : " trials",
                  " (cost model of docs/results/cost-model.md; reference machine: ",
                  reference_machine, ")");
  if (studies > 0) absl::StrAppend(&text, "; ", studies, " study jobs not estimated");
  return text;
}

absl::StatusOr<SweepCostEstimate> EstimateSweepCost(const SweepSpec& spec) {
  SweepSpec canonical = spec;
  if (absl::Status st = CanonicalizeSpec(&canonical); !st.ok()) return st;
  SweepCostEstimate estimate;
  estimate.reference_machine = learner::kReferenceMachine;
  RETURN_IF_ERROR(ForEachExpandedJob(canonical, [&](ExpandedJob&& job) -> absl::Status {
    if (job.kind == JobKind::kStudy) {
      ++estimate.studies;
      return absl::OkStatus();
    }
    learner::TrialOptions options;
    for (const auto& [key, value] : job.options) {
      RETURN_IF_ERROR(learner::SetTrialOption(key, value, &options));
    }
    ++estimate.trials;
    estimate.cpu_seconds += learner::EstimateTrialCost(options).total_cpu();
    return absl::OkStatus();
  }));
  return estimate;
}

}  // namespace totalgrad::sweep
