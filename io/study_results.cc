#include "io/study_results.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include "absl/strings/str_cat.h"
#include "core/common/blas.h"
#include "io/record_format.h"

namespace totalgrad::io {
namespace {

using Json = nlohmann::json;
using OrderedJson = nlohmann::ordered_json;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The top level's field readers (references and cells are records:
// io/record_format.h): a missing field keeps the default; a mistyped one is
// an error naming `where` and the key.
class FieldReader {
 public:
  FieldReader(const Json& obj, std::string where) : obj_(obj), where_(std::move(where)) {}
  const absl::Status& status() const { return status_; }

  void Number(const char* key, double* out) {
    const Json* v = Find(key);
    if (v == nullptr) return;
    if (v->is_null()) *out = kNaN;
    else if (v->is_number()) *out = v->get<double>();
    else Fail(key, "not a number or null");
  }
  void Int(const char* key, int* out) {
    const Json* v = Find(key);
    if (v == nullptr) return;
    if (v->is_number_integer()) *out = v->get<int>();
    else Fail(key, "not an integer");
  }
  void Text(const char* key, std::string* out) {
    const Json* v = Find(key);
    if (v == nullptr) return;
    if (v->is_string()) *out = v->get<std::string>();
    else Fail(key, "not a string");
  }

 private:
  const Json* Find(const char* key) const {
    auto it = obj_.find(key);
    return it == obj_.end() ? nullptr : &*it;
  }
  void Fail(const char* key, const char* what) {
    if (status_.ok()) status_ = absl::InvalidArgumentError(absl::StrCat(where_, key, ": ", what));
  }
  const Json& obj_;
  std::string where_;
  absl::Status status_;
};

}  // namespace

OrderedJson StudyResultToJson(const study::StudyResult& r, const StudySpec& spec) {
  OrderedJson j;
  j["source"] = r.source;
  j["scene"] = r.scene;
  j["num_parameters"] = r.num_parameters;
  j["seconds"] = r.seconds;
  j["blas"] = BlasConfig();
  const study::StudyOptions& o = spec.options;
  OrderedJson estimators = OrderedJson::array();
  for (const auto& e : o.estimators) estimators.push_back(e.label);
  OrderedJson ref_estimators = OrderedJson::array();
  for (const auto& e : o.reference.estimators) ref_estimators.push_back(e.label);
  j["options"] = {{"estimators", estimators},
                  {"particles", o.particles},
                  {"horizons", o.horizons},
                  {"replicates", o.replicates},
                  {"seed", o.seed},
                  {"cell_budget_seconds", o.cell_budget_seconds},
                  {"ess_replicates", o.ess_replicates},
                  {"reference", {{"estimators", ref_estimators},
                                 {"particles", o.reference.particles},
                                 {"replicates", o.reference.replicates},
                                 {"agreement_max_z", o.reference.agreement_max_z},
                                 {"agreement_mean_z2", o.reference.agreement_mean_z2}}}};
  OrderedJson refs = OrderedJson::array();
  for (const auto& ref : r.references) refs.push_back(RecordToJson(study::ReferenceFields(), ref));
  j["references"] = refs;
  OrderedJson cells = OrderedJson::array();
  for (const auto& c : r.cells) cells.push_back(RecordToJson(study::CellFields(), c));
  j["cells"] = cells;
  return j;
}


absl::StatusOr<study::StudyResult> StudyResultFromJson(const Json& doc) {
  if (!doc.is_object()) return absl::InvalidArgumentError("study results: not a JSON object");
  study::StudyResult r;
  FieldReader top(doc, "study results: ");
  top.Text("source", &r.source);
  top.Text("scene", &r.scene);
  top.Int("num_parameters", &r.num_parameters);
  top.Number("seconds", &r.seconds);
  if (!top.status().ok()) return top.status();
  const auto refs = doc.find("references");
  const auto cells = doc.find("cells");
  if (refs == doc.end() || !refs->is_array()) {
    return absl::InvalidArgumentError("study results: references: missing or not an array");
  }
  if (cells == doc.end() || !cells->is_array()) {
    return absl::InvalidArgumentError("study results: cells: missing or not an array");
  }
  for (size_t i = 0; i < refs->size(); ++i) {
    if (!(*refs)[i].is_object()) {
      return absl::InvalidArgumentError(absl::StrCat("references[", i, "]: not an object"));
    }
    study::ReferenceGradient ref;
    // agreement_resolution is absent from files written before 2026-11-24
    // and reads as NaN (not computed).
    const absl::Status read = RecordFromJson(study::ReferenceFields(), (*refs)[i],
                                             absl::StrCat("references[", i, "]."), &ref);
    if (!read.ok()) return read;
    r.references.push_back(std::move(ref));
  }
  for (size_t i = 0; i < cells->size(); ++i) {
    const Json& j = (*cells)[i];
    if (!j.is_object()) return absl::InvalidArgumentError(absl::StrCat("cells[", i, "]: not an object"));
    study::CellResult c;
    const absl::Status read = RecordFromJson(study::CellFields(), j, absl::StrCat("cells[", i, "]."), &c);
    if (!read.ok()) return read;
    if (!j.contains("reference_floor")) {
      // Written before cells carried their floor: the horizon's reference's.
      for (const auto& ref : r.references) {
        if (ref.horizon == c.horizon) {
          c.reference_floor = ref.floor;
          break;
        }
      }
    }
    r.cells.push_back(std::move(c));
  }
  return r;
}

absl::StatusOr<study::StudyResult> ReadStudyResultFile(const std::string& path) {
  std::filesystem::path file(path);
  if (std::filesystem::is_directory(file)) file /= "results.json";
  std::ifstream in(file);
  if (!in) return absl::NotFoundError(absl::StrCat("cannot open study results '", file.string(), "'"));
  const Json doc = Json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) {
    return absl::InvalidArgumentError(absl::StrCat("'", file.string(), "' is not valid JSON"));
  }
  absl::StatusOr<study::StudyResult> r = StudyResultFromJson(doc);
  if (!r.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("'", file.string(), "': ", r.status().message()));
  }
  return r;
}

}  // namespace totalgrad::io
