#include "io/study_file.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "core/common/option_table.h"
#include "core/common/status_context.h"
#include "core/estimators/method.h"
#include "core/learner/trial.h"
#include "core/learner/trial_options.h"
#include "core/tasks/scene_catalog.h"
#include "io/snapshot_json.h"

namespace totalgrad::io {
namespace {

// A scene a study can build its problem on: a catalog scene whose trials
// run. InvalidArgument "scene: unknown scene ..." or "scene: 'unicycle' has
// no studies yet: <why>".
absl::Status CheckStudyScene(const std::string& scene) {
  return WithContext(tasks::RunnableScene(scene, "studies").status(), "scene");
}

using Json = nlohmann::json;

const Json* Find(const Json& obj, const std::string& key) {
  auto it = obj.find(key);
  return it == obj.end() ? nullptr : &*it;
}

absl::Status CheckKeys(const Json& obj, const std::string& where,
                       const std::vector<std::string>& known) {
  for (auto it = obj.begin(); it != obj.end(); ++it) {
    if (std::find(known.begin(), known.end(), it.key()) == known.end()) {
      return absl::InvalidArgumentError(absl::StrCat(where, ": unknown field '", it.key(),
                                                     "' (known: ", absl::StrJoin(known, ", "), ")"));
    }
  }
  return absl::OkStatus();
}

absl::Status ReadInt(const Json& obj, const std::string& key, const std::string& where, int* out) {
  const Json* v = Find(obj, key);
  if (v == nullptr) return absl::OkStatus();
  if (!v->is_number_integer()) {
    return absl::InvalidArgumentError(absl::StrCat(where, key, ": not an integer"));
  }
  *out = v->get<int>();
  return absl::OkStatus();
}

absl::Status ReadDouble(const Json& obj, const std::string& key, const std::string& where,
                        double* out) {
  const Json* v = Find(obj, key);
  if (v == nullptr) return absl::OkStatus();
  if (!v->is_number() || !std::isfinite(v->get<double>())) {
    return absl::InvalidArgumentError(absl::StrCat(where, key, ": not a finite number"));
  }
  *out = v->get<double>();
  return absl::OkStatus();
}

absl::Status ReadIntList(const Json& obj, const std::string& key, const std::string& where,
                         std::vector<int>* out) {
  const Json* v = Find(obj, key);
  if (v == nullptr) return absl::OkStatus();
  if (!v->is_array()) return absl::InvalidArgumentError(absl::StrCat(where, key, ": not an array"));
  out->clear();
  for (size_t i = 0; i < v->size(); ++i) {
    if (!(*v)[i].is_number_integer()) {
      return absl::InvalidArgumentError(absl::StrCat(where, key, "[", i, "]: not an integer"));
    }
    out->push_back((*v)[i].get<int>());
  }
  return absl::OkStatus();
}

absl::StatusOr<estimators::EstimatorOptions> ParseEstimatorOptions(const Json& obj,
                                                                  const std::string& where) {
  const OptionTable<estimators::EstimatorOptions>& table = estimators::EstimatorOptions::Table();
  estimators::EstimatorOptions options;
  for (auto it = obj.begin(); it != obj.end(); ++it) {
    const std::string& key = it.key();
    std::string text;
    if (it->is_string()) {
      text = it->get<std::string>();
    } else if (it->is_number()) {
      text = absl::StrFormat("%.17g", it->get<double>());
    } else {
      return absl::InvalidArgumentError(absl::StrCat(where, key, ": not a string or number"));
    }
    if (!table.Has(key)) {
      return absl::InvalidArgumentError(absl::StrCat(where, "unknown estimator option '", key,
                                                     "' (known: ", absl::StrJoin(table.Keys(), ", "), ")"));
    }
    if (absl::Status st = table.Set(key, text, &options); !st.ok()) {
      return absl::InvalidArgumentError(absl::StrCat(where, st.message()));
    }
  }
  return options;
}

absl::StatusOr<std::vector<study::EstimatorSpec>> ParseEstimatorList(const Json& v,
                                                                    const std::string& where) {
  if (!v.is_array()) return absl::InvalidArgumentError(absl::StrCat(where, ": not an array"));
  std::vector<study::EstimatorSpec> out;
  for (size_t i = 0; i < v.size(); ++i) {
    const std::string at = absl::StrCat(where, "[", i, "]");
    const Json& e = v[i];
    if (e.is_string()) {
      absl::StatusOr<estimators::Method> method = estimators::ParseMethod(e.get<std::string>());
      if (!method.ok()) return absl::InvalidArgumentError(absl::StrCat(at, ": ", method.status().message()));
      out.push_back({e.get<std::string>(), *method, {}});
      continue;
    }
    if (!e.is_object()) {
      return absl::InvalidArgumentError(absl::StrCat(at, ": not a name or an object"));
    }
    if (absl::Status st = CheckKeys(e, at, {"label", "method", "options"}); !st.ok()) return st;
    const Json* method = Find(e, "method");
    if (method == nullptr || !method->is_string()) {
      return absl::InvalidArgumentError(absl::StrCat(at, ".method: missing or not a string"));
    }
    study::EstimatorSpec spec;
    absl::StatusOr<estimators::Method> parsed = estimators::ParseMethod(method->get<std::string>());
    if (!parsed.ok()) return absl::InvalidArgumentError(absl::StrCat(at, ".method: ", parsed.status().message()));
    spec.method = *parsed;
    spec.label = method->get<std::string>();
    if (const Json* label = Find(e, "label"); label != nullptr) {
      if (!label->is_string()) return absl::InvalidArgumentError(absl::StrCat(at, ".label: not a string"));
      spec.label = label->get<std::string>();
    }
    if (const Json* options = Find(e, "options"); options != nullptr) {
      if (!options->is_object()) {
        return absl::InvalidArgumentError(absl::StrCat(at, ".options: not an object"));
      }
      absl::StatusOr<estimators::EstimatorOptions> eo =
          ParseEstimatorOptions(*options, at + ".options.");
      if (!eo.ok()) return eo.status();
      spec.options = *eo;
    }
    out.push_back(std::move(spec));
  }
  return out;
}


// problem = {"snapshot": FILE or an inlined snapshot, "episode", "policy"}.
absl::Status ParseSnapshotProblem(const Json& problem, const Json& snapshot_json,
                                  const std::string& base_dir, StudySpec* out) {
  const Json* snapshot = &snapshot_json;
  StudySpec& spec = *out;
  if (absl::Status st = CheckKeys(problem, "problem", {"snapshot", "episode", "policy"}); !st.ok()) {
    return st;
  }
  spec.from_snapshot = true;
  if (snapshot->is_object()) {
    absl::StatusOr<std::vector<learner::TrialSnapshot>> inline_snapshots =
        SnapshotsFromJson(*snapshot);
    if (!inline_snapshots.ok()) {
      return absl::InvalidArgumentError(
          absl::StrCat("problem.snapshot (inline): ", inline_snapshots.status().message()));
    }
    spec.inline_snapshots = *std::move(inline_snapshots);
  } else if (snapshot->is_string()) {
    std::filesystem::path path(snapshot->get<std::string>());
    if (path.is_relative() && !base_dir.empty()) path = std::filesystem::path(base_dir) / path;
    spec.snapshot_file = path.string();
  } else {
    return absl::InvalidArgumentError(
        "problem.snapshot: not a file name or an inlined snapshot object");
  }
  if (absl::Status st = ReadInt(problem, "episode", "problem.", &spec.snapshot_episode); !st.ok()) {
    return st;
  }
  if (const Json* policy = Find(problem, "policy"); policy != nullptr) {
    const std::string p = policy->is_string() ? policy->get<std::string>() : "";
    if (p == "before") spec.snapshot_policy = study::SnapshotPolicy::kBefore;
    else if (p == "after") spec.snapshot_policy = study::SnapshotPolicy::kAfter;
    else return absl::InvalidArgumentError("problem.policy: must be \"before\" or \"after\"");
  }
  return absl::OkStatus();
}

// problem = {"synthetic": {data, horizon, basis_functions, cost, scene, seed,
// train_iterations, angle_features}}.
absl::Status ParseSyntheticProblem(const Json& problem, const Json& synthetic_json,
                                   StudySpec* out) {
  const Json* synthetic = &synthetic_json;
  StudySpec& spec = *out;
  if (absl::Status st = CheckKeys(problem, "problem", {"synthetic"}); !st.ok()) return st;
  if (!synthetic->is_object()) return absl::InvalidArgumentError("problem.synthetic: not an object");
  if (absl::Status st = CheckKeys(*synthetic, "problem.synthetic",
                                  {"data", "horizon", "basis_functions", "cost", "scene", "seed",
                                   "train_iterations", "angle_features"});
      !st.ok()) {
    return st;
  }
  estimators::SyntheticProblemOptions& o = spec.synthetic;
  const std::string w = "problem.synthetic.";
  for (absl::Status st : {ReadInt(*synthetic, "data", w, &o.data),
                          ReadInt(*synthetic, "horizon", w, &o.horizon),
                          ReadInt(*synthetic, "basis_functions", w, &o.basis_functions),
                          ReadInt(*synthetic, "train_iterations", w, &o.train_iterations)}) {
    if (!st.ok()) return st;
  }
  for (const char* key : {"cost", "scene"}) {
    if (const Json* v = Find(*synthetic, key); v != nullptr) {
      if (!v->is_string()) return absl::InvalidArgumentError(absl::StrCat(w, key, ": not a string"));
      (std::string(key) == "cost" ? o.cost : o.scene) = v->get<std::string>();
    }
  }
  if (const Json* v = Find(*synthetic, "seed"); v != nullptr) {
    if (!v->is_number_integer() || v->get<int64_t>() < 0) {
      return absl::InvalidArgumentError(w + "seed: not a non-negative integer");
    }
    o.seed = v->get<uint64_t>();
  }
  if (const Json* v = Find(*synthetic, "angle_features"); v != nullptr) {
    const std::string text = v->is_string() ? v->get<std::string>() : "";
    if (absl::Status st = ParseEnum("angle_features", text, learner::AngleFeaturesNames(),
                                    &spec.synthetic_angle_features);
        !st.ok()) {
      return absl::InvalidArgumentError(absl::StrCat(w, st.message()));
    }
  }
  if (absl::Status st = CheckStudyScene(o.scene); !st.ok()) {
    return absl::InvalidArgumentError(absl::StrCat(w, st.message()));
  }
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<StudySpec> ParseStudySpec(const Json& doc, const std::string& base_dir) {
  if (!doc.is_object()) return absl::InvalidArgumentError("study file: not a JSON object");
  if (absl::Status st = CheckKeys(doc, "study file",
                                  {"problem", "estimators", "particles", "horizons", "replicates",
                                   "seed", "cell_budget_seconds", "ess_replicates",
                                   "ess_max_particles", "reference", "sweep_particles"});
      !st.ok()) {
    return st;
  }
  StudySpec spec;
  const Json* problem = Find(doc, "problem");
  if (problem == nullptr || !problem->is_object()) {
    return absl::InvalidArgumentError("study file: missing object 'problem'");
  }
  if (const Json* snapshot = Find(*problem, "snapshot"); snapshot != nullptr) {
    if (absl::Status st = ParseSnapshotProblem(*problem, *snapshot, base_dir, &spec); !st.ok()) {
      return st;
    }
  } else if (const Json* synthetic = Find(*problem, "synthetic"); synthetic != nullptr) {
    if (absl::Status st = ParseSyntheticProblem(*problem, *synthetic, &spec); !st.ok()) return st;
  } else {
    return absl::InvalidArgumentError("problem: needs 'snapshot' or 'synthetic'");
  }

  study::StudyOptions& o = spec.options;
  if (const Json* e = Find(doc, "estimators"); e != nullptr) {
    absl::StatusOr<std::vector<study::EstimatorSpec>> list = ParseEstimatorList(*e, "estimators");
    if (!list.ok()) return list.status();
    o.estimators = *std::move(list);
  }
  for (absl::Status st : {ReadIntList(doc, "particles", "", &o.particles),
                          ReadIntList(doc, "horizons", "", &o.horizons),
                          ReadInt(doc, "replicates", "", &o.replicates),
                          ReadDouble(doc, "cell_budget_seconds", "", &o.cell_budget_seconds),
                          ReadInt(doc, "ess_replicates", "", &o.ess_replicates),
                          ReadInt(doc, "ess_max_particles", "", &o.ess_max_particles),
                          ReadInt(doc, "sweep_particles", "", &spec.sweep_particles)}) {
    if (!st.ok()) return st;
  }
  if (const Json* v = Find(doc, "seed"); v != nullptr) {
    if (!v->is_number_integer() || v->get<int64_t>() < 0) {
      return absl::InvalidArgumentError("seed: not a non-negative integer");
    }
    o.seed = v->get<uint64_t>();
  }
  if (const Json* ref = Find(doc, "reference"); ref != nullptr) {
    if (!ref->is_object()) return absl::InvalidArgumentError("reference: not an object");
    if (absl::Status st = CheckKeys(*ref, "reference",
                                    {"estimators", "particles", "replicates", "budget_seconds",
                                     "agreement_max_z", "agreement_mean_z2"});
        !st.ok()) {
      return st;
    }
    if (const Json* e = Find(*ref, "estimators"); e != nullptr) {
      absl::StatusOr<std::vector<study::EstimatorSpec>> list =
          ParseEstimatorList(*e, "reference.estimators");
      if (!list.ok()) return list.status();
      o.reference.estimators = *std::move(list);
    }
    for (absl::Status st :
         {ReadInt(*ref, "particles", "reference.", &o.reference.particles),
          ReadInt(*ref, "replicates", "reference.", &o.reference.replicates),
          ReadDouble(*ref, "budget_seconds", "reference.", &o.reference.budget_seconds),
          ReadDouble(*ref, "agreement_max_z", "reference.", &o.reference.agreement_max_z),
          ReadDouble(*ref, "agreement_mean_z2", "reference.", &o.reference.agreement_mean_z2)}) {
      if (!st.ok()) return st;
    }
  }
  if (spec.sweep_particles < 1) return absl::InvalidArgumentError("sweep_particles: must be >= 1");
  if (absl::Status st = o.Validate(); !st.ok()) return st;
  return spec;
}

absl::StatusOr<std::unique_ptr<study::FrozenProblem>> LoadStudyProblem(const StudySpec& spec) {
  if (!spec.from_snapshot) {
    return study::FrozenProblemFromSynthetic(spec.synthetic, spec.synthetic_angle_features);
  }
  absl::StatusOr<std::vector<learner::TrialSnapshot>> snapshots =
      spec.snapshot_file.empty() ? absl::StatusOr<std::vector<learner::TrialSnapshot>>(
                                       spec.inline_snapshots)
                                 : ReadSnapshotFile(spec.snapshot_file);
  if (!snapshots.ok()) return snapshots.status();
  if (snapshots->empty()) {
    return absl::InvalidArgumentError(absl::StrCat(
        spec.snapshot_file.empty() ? "the inline snapshot" : "'" + spec.snapshot_file + "'",
        " holds no snapshots"));
  }
  const learner::TrialSnapshot* chosen = nullptr;
  std::vector<std::string> available;
  for (const learner::TrialSnapshot& s : *snapshots) {
    available.push_back(std::to_string(s.episode));
    if (spec.snapshot_episode < 0 || s.episode == spec.snapshot_episode) {
      chosen = &s;
      break;
    }
  }
  if (chosen == nullptr) {
    for (const learner::TrialSnapshot& s : *snapshots) available.push_back(std::to_string(s.episode));
    return absl::InvalidArgumentError(absl::StrCat(
        spec.snapshot_file.empty() ? "the inline snapshot" : "'" + spec.snapshot_file + "'",
        " has no snapshot of episode ",
                                                   spec.snapshot_episode, " (it has ",
                                                   absl::StrJoin(available, ", "), ")"));
  }
  return study::FrozenProblemFromSnapshot(*chosen, spec.snapshot_policy);
}

absl::StatusOr<Json> ReadStudyDocument(const std::string& path) {
  std::ifstream in(path);
  if (!in) return absl::NotFoundError(absl::StrCat("cannot open study file '", path, "'"));
  Json doc = Json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) {
    return absl::InvalidArgumentError(absl::StrCat("study file '", path, "' is not valid JSON"));
  }
  return doc;
}

absl::StatusOr<Json> InlineStudyDocument(const Json& doc, const std::string& base_dir) {
  if (!doc.is_object()) return absl::InvalidArgumentError("study file: not a JSON object");
  const Json* problem = Find(doc, "problem");
  if (problem == nullptr || !problem->is_object()) return doc;  // ParseStudySpec names it
  const Json* snapshot = Find(*problem, "snapshot");
  if (snapshot == nullptr || !snapshot->is_string()) return doc;
  std::filesystem::path path(snapshot->get<std::string>());
  if (path.is_relative() && !base_dir.empty()) path = std::filesystem::path(base_dir) / path;
  std::ifstream in(path);
  if (!in) {
    return absl::NotFoundError(absl::StrCat("problem.snapshot: cannot open snapshot file '",
                                            path.string(), "'"));
  }
  Json file = Json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (file.is_discarded()) {
    return absl::InvalidArgumentError(
        absl::StrCat("problem.snapshot: '", path.string(), "' is not valid JSON"));
  }
  if (absl::StatusOr<std::vector<learner::TrialSnapshot>> parsed = SnapshotsFromJson(file);
      !parsed.ok()) {
    return absl::InvalidArgumentError(
        absl::StrCat("problem.snapshot: '", path.string(), "': ", parsed.status().message()));
  }
  int episode = -1;
  if (absl::Status st = ReadInt(*problem, "episode", "problem.", &episode); !st.ok()) return st;
  // Keep only the snapshot the study uses (the same choice LoadStudyProblem makes).
  const Json& all = file["snapshots"];
  Json kept = Json::array();
  std::vector<std::string> available;
  for (const Json& s : all) {
    const int e = s.value("episode", -1);
    available.push_back(std::to_string(e));
    if (episode < 0 || e == episode) {
      kept.push_back(s);
      break;
    }
  }
  if (kept.empty()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "problem.episode: '", path.string(), "' has no snapshot of episode ", episode,
        " (it has ", absl::StrJoin(available, ", "), ")"));
  }
  file["snapshots"] = std::move(kept);
  Json out = doc;
  out["problem"]["snapshot"] = std::move(file);
  return out;
}

absl::StatusOr<Json> SetStudyScene(const Json& doc, const std::string& scene) {
  if (absl::Status st = CheckStudyScene(scene); !st.ok()) return st;
  if (!doc.is_object()) return absl::InvalidArgumentError("study file: not a JSON object");
  const Json* problem = Find(doc, "problem");
  if (problem == nullptr || !problem->is_object()) {
    return absl::InvalidArgumentError("study file: missing object 'problem'");
  }
  Json out = doc;
  if (const Json* synthetic = Find(*problem, "synthetic"); synthetic != nullptr) {
    if (!synthetic->is_object()) return absl::InvalidArgumentError("problem.synthetic: not an object");
    out["problem"]["synthetic"]["scene"] = scene;
    return out;
  }
  const Json* snapshot = Find(*problem, "snapshot");
  if (snapshot == nullptr || !snapshot->is_object()) {
    return absl::InvalidArgumentError(
        "scene: needs a synthetic problem or an inlined snapshot (a snapshot file is read first)");
  }
  absl::StatusOr<std::vector<learner::TrialSnapshot>> snapshots = SnapshotsFromJson(*snapshot);
  if (!snapshots.ok() || snapshots->empty()) {
    return absl::InvalidArgumentError("scene: the inlined snapshot cannot be read");
  }
  // InlineStudyDocument keeps only the snapshot the study uses.
  std::string snapshot_scene = learner::TrialOptions{}.scene.scene;
  for (const auto& [key, value] : snapshots->front().options) {
    if (key == "scene") snapshot_scene = value;
  }
  if (snapshot_scene != scene) {
    return absl::InvalidArgumentError(absl::StrCat("scene: the study's snapshot is of scene '",
                                                   snapshot_scene, "', not '", scene, "'"));
  }
  return out;
}

}  // namespace totalgrad::io
