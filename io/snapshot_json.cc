#include "io/snapshot_json.h"

#include <cmath>
#include <cstdio>
#include <fstream>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"

namespace totalgrad::io {
namespace {

using Json = nlohmann::json;
using OrderedJson = nlohmann::ordered_json;

constexpr char kFormat[] = "totalgrad-trial-snapshots";

OrderedJson VectorJson(const Vector& v) {
  OrderedJson a = OrderedJson::array();
  for (Eigen::Index i = 0; i < v.size(); ++i) a.push_back(v(i));
  return a;
}

OrderedJson MatrixJson(const RowMatrix& m) {
  OrderedJson a = OrderedJson::array();
  for (Eigen::Index r = 0; r < m.rows(); ++r) a.push_back(VectorJson(m.row(r).transpose()));
  return a;
}

const Json* Find(const Json& obj, const std::string& key) {
  auto it = obj.find(key);
  return it == obj.end() ? nullptr : &*it;
}

absl::StatusOr<Vector> ReadVector(const Json& obj, const std::string& key, const std::string& where) {
  const Json* v = Find(obj, key);
  if (v == nullptr) return absl::InvalidArgumentError(absl::StrCat(where, ": missing '", key, "'"));
  if (!v->is_array()) return absl::InvalidArgumentError(absl::StrCat(where, ".", key, ": not an array"));
  Vector out(v->size());
  for (size_t i = 0; i < v->size(); ++i) {
    const Json& x = (*v)[i];
    if (!x.is_number() || !std::isfinite(x.get<double>())) {
      return absl::InvalidArgumentError(absl::StrCat(where, ".", key, "[", i, "]: not a finite number"));
    }
    out(i) = x.get<double>();
  }
  return out;
}

absl::StatusOr<RowMatrix> ReadMatrix(const Json& obj, const std::string& key, const std::string& where) {
  const Json* v = Find(obj, key);
  if (v == nullptr) return absl::InvalidArgumentError(absl::StrCat(where, ": missing '", key, "'"));
  if (!v->is_array()) return absl::InvalidArgumentError(absl::StrCat(where, ".", key, ": not an array"));
  RowMatrix out;
  for (size_t r = 0; r < v->size(); ++r) {
    const Json& row = (*v)[r];
    if (!row.is_array()) {
      return absl::InvalidArgumentError(absl::StrCat(where, ".", key, "[", r, "]: not an array"));
    }
    if (r == 0) out.resize(static_cast<Eigen::Index>(v->size()), static_cast<Eigen::Index>(row.size()));
    if (static_cast<Eigen::Index>(row.size()) != out.cols()) {
      return absl::InvalidArgumentError(absl::StrCat(where, ".", key, "[", r, "]: has ", row.size(),
                                                     " entries, row 0 has ", out.cols()));
    }
    for (size_t c = 0; c < row.size(); ++c) {
      if (!row[c].is_number() || !std::isfinite(row[c].get<double>())) {
        return absl::InvalidArgumentError(
            absl::StrCat(where, ".", key, "[", r, "][", c, "]: not a finite number"));
      }
      out(r, c) = row[c].get<double>();
    }
  }
  return out;
}

}  // namespace

OrderedJson SnapshotsToJson(const std::vector<learner::TrialSnapshot>& snapshots) {
  OrderedJson doc;
  doc["format"] = kFormat;
  doc["version"] = 1;
  OrderedJson list = OrderedJson::array();
  for (const learner::TrialSnapshot& s : snapshots) {
    OrderedJson j;
    j["episode"] = s.episode;
    OrderedJson options = OrderedJson::object();
    for (const auto& [key, value] : s.options) options[key] = value;
    j["options"] = options;
    j["states"] = MatrixJson(s.states);
    j["forces"] = VectorJson(s.forces);
    j["next_states"] = MatrixJson(s.next_states);
    j["hyperparameters"] = {{"log_lengthscales", MatrixJson(s.hyperparameters.log_lengthscales)},
                            {"log_signal_std", VectorJson(s.hyperparameters.log_signal_std)},
                            {"log_noise_std", VectorJson(s.hyperparameters.log_noise_std)}};
    j["policy_parameters_before"] = VectorJson(s.policy_parameters_before);
    j["policy_parameters"] = VectorJson(s.policy_parameters);
    list.push_back(std::move(j));
  }
  doc["snapshots"] = std::move(list);
  return doc;
}

absl::StatusOr<std::vector<learner::TrialSnapshot>> SnapshotsFromJson(const Json& doc) {
  if (!doc.is_object()) return absl::InvalidArgumentError("snapshot file: not a JSON object");
  const Json* format = Find(doc, "format");
  if (format == nullptr || !format->is_string() || format->get<std::string>() != kFormat) {
    return absl::InvalidArgumentError(
        absl::StrCat("snapshot file: 'format' must be \"", kFormat, "\""));
  }
  const Json* list = Find(doc, "snapshots");
  if (list == nullptr || !list->is_array()) {
    return absl::InvalidArgumentError("snapshot file: missing array 'snapshots'");
  }
  std::vector<learner::TrialSnapshot> out;
  for (size_t i = 0; i < list->size(); ++i) {
    const Json& j = (*list)[i];
    const std::string where = absl::StrCat("snapshots[", i, "]");
    if (!j.is_object()) return absl::InvalidArgumentError(absl::StrCat(where, ": not an object"));
    learner::TrialSnapshot s;
    const Json* episode = Find(j, "episode");
    if (episode == nullptr || !episode->is_number_integer()) {
      return absl::InvalidArgumentError(absl::StrCat(where, ".episode: missing or not an integer"));
    }
    s.episode = episode->get<int>();
    const Json* options = Find(j, "options");
    if (options == nullptr || !options->is_object()) {
      return absl::InvalidArgumentError(absl::StrCat(where, ".options: missing or not an object"));
    }
    for (auto it = options->begin(); it != options->end(); ++it) {
      if (!it->is_string()) {
        return absl::InvalidArgumentError(
            absl::StrCat(where, ".options.", it.key(), ": not a string"));
      }
      s.options.emplace_back(it.key(), it->get<std::string>());
    }
    absl::StatusOr<RowMatrix> states = ReadMatrix(j, "states", where);
    if (!states.ok()) return states.status();
    s.states = *std::move(states);
    absl::StatusOr<Vector> forces = ReadVector(j, "forces", where);
    if (!forces.ok()) return forces.status();
    s.forces = *std::move(forces);
    absl::StatusOr<RowMatrix> next = ReadMatrix(j, "next_states", where);
    if (!next.ok()) return next.status();
    s.next_states = *std::move(next);
    const Json* hyp = Find(j, "hyperparameters");
    if (hyp == nullptr || !hyp->is_object()) {
      return absl::InvalidArgumentError(absl::StrCat(where, ".hyperparameters: missing or not an object"));
    }
    const std::string hyp_where = where + ".hyperparameters";
    absl::StatusOr<RowMatrix> ls = ReadMatrix(*hyp, "log_lengthscales", hyp_where);
    if (!ls.ok()) return ls.status();
    absl::StatusOr<Vector> sf = ReadVector(*hyp, "log_signal_std", hyp_where);
    if (!sf.ok()) return sf.status();
    absl::StatusOr<Vector> sn = ReadVector(*hyp, "log_noise_std", hyp_where);
    if (!sn.ok()) return sn.status();
    s.hyperparameters.log_lengthscales = *std::move(ls);
    s.hyperparameters.log_signal_std = *std::move(sf);
    s.hyperparameters.log_noise_std = *std::move(sn);
    absl::StatusOr<Vector> before = ReadVector(j, "policy_parameters_before", where);
    if (!before.ok()) return before.status();
    s.policy_parameters_before = *std::move(before);
    absl::StatusOr<Vector> after = ReadVector(j, "policy_parameters", where);
    if (!after.ok()) return after.status();
    s.policy_parameters = *std::move(after);
    out.push_back(std::move(s));
  }
  return out;
}

absl::Status WriteSnapshotFile(const std::string& path,
                               const std::vector<learner::TrialSnapshot>& snapshots) {
  const std::string temporary = path + ".tmp";
  {
    std::ofstream out(temporary);
    if (!out) return absl::UnavailableError(absl::StrCat("cannot write '", temporary, "'"));
    out << SnapshotsToJson(snapshots).dump() << "\n";
    if (!out) return absl::UnavailableError(absl::StrCat("error writing '", temporary, "'"));
  }
  if (std::rename(temporary.c_str(), path.c_str()) != 0) {
    return absl::UnavailableError(absl::StrCat("cannot rename '", temporary, "' to '", path, "'"));
  }
  return absl::OkStatus();
}

absl::StatusOr<std::vector<learner::TrialSnapshot>> ReadSnapshotFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) return absl::NotFoundError(absl::StrCat("cannot open snapshot file '", path, "'"));
  Json doc = Json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) {
    return absl::InvalidArgumentError(absl::StrCat("snapshot file '", path, "' is not valid JSON"));
  }
  absl::StatusOr<std::vector<learner::TrialSnapshot>> s = SnapshotsFromJson(doc);
  if (!s.ok()) {
    return absl::Status(s.status().code(), absl::StrCat("'", path, "': ", s.status().message()));
  }
  return s;
}

absl::StatusOr<std::vector<int>> ParseEpisodeList(const std::string& text) {
  std::vector<int> out;
  for (absl::string_view part : absl::StrSplit(text, ',', absl::SkipWhitespace())) {
    int e = 0;
    if (!absl::SimpleAtoi(part, &e) || e < 1) {
      return absl::InvalidArgumentError(
          absl::StrCat("episode list '", text, "': '", part, "' is not a positive integer"));
    }
    out.push_back(e);
  }
  if (out.empty()) return absl::InvalidArgumentError("episode list is empty");
  return out;
}

}  // namespace totalgrad::io
