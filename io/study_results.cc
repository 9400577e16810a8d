#include "io/study_results.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include "absl/strings/str_cat.h"
#include "core/common/blas.h"

namespace totalgrad::io {
namespace {

using Json = nlohmann::json;
using OrderedJson = nlohmann::ordered_json;

OrderedJson JsonNumber(double v) { return std::isfinite(v) ? OrderedJson(v) : OrderedJson(nullptr); }

OrderedJson VectorJson(const Vector& v) {
  OrderedJson a = OrderedJson::array();
  for (Eigen::Index i = 0; i < v.size(); ++i) a.push_back(JsonNumber(v(i)));
  return a;
}

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Field readers: a missing field keeps the default; a mistyped one is an
// error naming `where` and the key.
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
  void Bool(const char* key, bool* out) {
    const Json* v = Find(key);
    if (v == nullptr) return;
    if (v->is_boolean()) *out = v->get<bool>();
    else Fail(key, "not true or false");
  }
  void Text(const char* key, std::string* out) {
    const Json* v = Find(key);
    if (v == nullptr) return;
    if (v->is_string()) *out = v->get<std::string>();
    else Fail(key, "not a string");
  }
  void Numbers(const char* key, std::vector<double>* out) {
    const Json* v = Find(key);
    if (v == nullptr) return;
    if (!v->is_array()) return Fail(key, "not an array");
    out->clear();
    for (const Json& x : *v) {
      if (x.is_null()) out->push_back(kNaN);
      else if (x.is_number()) out->push_back(x.get<double>());
      else return Fail(key, "holds an entry that is not a number or null");
    }
  }
  void Vec(const char* key, Vector* out) {
    std::vector<double> values;
    Numbers(key, &values);
    *out = Eigen::Map<const Vector>(values.data(), static_cast<Eigen::Index>(values.size()));
  }
  void Ints(const char* key, std::vector<int>* out) {
    const Json* v = Find(key);
    if (v == nullptr) return;
    if (!v->is_array()) return Fail(key, "not an array");
    out->clear();
    for (const Json& x : *v) {
      if (!x.is_number_integer()) return Fail(key, "holds an entry that is not an integer");
      out->push_back(x.get<int>());
    }
  }
  void Texts(const char* key, std::vector<std::string>* out) {
    const Json* v = Find(key);
    if (v == nullptr) return;
    if (!v->is_array()) return Fail(key, "not an array");
    out->clear();
    for (const Json& x : *v) {
      if (!x.is_string()) return Fail(key, "holds an entry that is not a string");
      out->push_back(x.get<std::string>());
    }
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
  for (const auto& ref : r.references) {
    refs.push_back({{"horizon", ref.horizon},
                    {"norm", JsonNumber(ref.norm)},
                    {"relative_error", JsonNumber(ref.relative_error)},
                    {"floor", JsonNumber(ref.floor)},
                    {"objective", JsonNumber(ref.objective)},
                    {"used", ref.used},
                    {"replicates", ref.replicates},
                    {"agreement_max_z", JsonNumber(ref.agreement_max_z)},
                    {"agreement_mean_z2", JsonNumber(ref.agreement_mean_z2)},
                    {"agreement_resolution", JsonNumber(ref.agreement_resolution)},
                    {"agree", ref.agree},
                    {"note", ref.note},
                    {"seconds", ref.seconds},
                    {"gradient", VectorJson(ref.gradient)},
                    {"standard_error", VectorJson(ref.standard_error)}});
  }
  j["references"] = refs;
  OrderedJson cells = OrderedJson::array();
  for (const auto& c : r.cells) {
    OrderedJson k_lr = OrderedJson::array();
    for (double v : c.k_lr_per_step) k_lr.push_back(JsonNumber(v));
    cells.push_back({{"estimator", c.estimator},
                     {"method", c.method},
                     {"particles", c.particles},
                     {"horizon", c.horizon},
                     {"replicates", c.replicates},
                     {"nonfinite", c.nonfinite},
                     {"errors", c.errors},
                     {"error", c.error},
                     {"budget_hit", c.budget_hit},
                     {"omitted", c.omitted},
                     {"omission_reason", c.omission_reason},
                     {"time_min_s", JsonNumber(c.time_min_s)},
                     {"time_median_s", JsonNumber(c.time_median_s)},
                     {"rel_rmse", JsonNumber(c.rel_rmse)},
                     {"rel_bias", JsonNumber(c.rel_bias)},
                     {"rel_bias_noise", JsonNumber(c.rel_bias_noise)},
                     {"total_variance", JsonNumber(c.total_variance)},
                     {"cos_mean", JsonNumber(c.cos_mean)},
                     {"objective_mean", JsonNumber(c.objective_mean)},
                     {"ess_mean", JsonNumber(c.ess_mean)},
                     {"ess_min", JsonNumber(c.ess_min)},
                     {"k_lr_mean", JsonNumber(c.k_lr_mean)},
                     {"k_lr_per_step", k_lr},
                     {"reference_agrees", c.reference_agrees}});
  }
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
    const Json& j = (*refs)[i];
    if (!j.is_object()) return absl::InvalidArgumentError(absl::StrCat("references[", i, "]: not an object"));
    study::ReferenceGradient ref;
    FieldReader f(j, absl::StrCat("references[", i, "].", ""));
    f.Int("horizon", &ref.horizon);
    f.Number("norm", &ref.norm);
    f.Number("relative_error", &ref.relative_error);
    f.Number("floor", &ref.floor);
    f.Number("objective", &ref.objective);
    f.Texts("used", &ref.used);
    f.Ints("replicates", &ref.replicates);
    f.Number("agreement_max_z", &ref.agreement_max_z);
    f.Number("agreement_mean_z2", &ref.agreement_mean_z2);
    f.Number("agreement_resolution", &ref.agreement_resolution);  // absent before 2026-11-24
    f.Bool("agree", &ref.agree);
    f.Text("note", &ref.note);
    f.Number("seconds", &ref.seconds);
    f.Vec("gradient", &ref.gradient);
    f.Vec("standard_error", &ref.standard_error);
    if (!f.status().ok()) return f.status();
    r.references.push_back(std::move(ref));
  }
  for (size_t i = 0; i < cells->size(); ++i) {
    const Json& j = (*cells)[i];
    if (!j.is_object()) return absl::InvalidArgumentError(absl::StrCat("cells[", i, "]: not an object"));
    study::CellResult c;
    FieldReader f(j, absl::StrCat("cells[", i, "]."));
    f.Text("estimator", &c.estimator);
    f.Text("method", &c.method);
    f.Int("particles", &c.particles);
    f.Int("horizon", &c.horizon);
    f.Int("replicates", &c.replicates);
    f.Int("nonfinite", &c.nonfinite);
    f.Int("errors", &c.errors);
    f.Text("error", &c.error);
    f.Bool("budget_hit", &c.budget_hit);
    f.Bool("omitted", &c.omitted);
    f.Text("omission_reason", &c.omission_reason);
    f.Number("time_min_s", &c.time_min_s);
    f.Number("time_median_s", &c.time_median_s);
    f.Number("rel_rmse", &c.rel_rmse);
    f.Number("rel_bias", &c.rel_bias);
    f.Number("rel_bias_noise", &c.rel_bias_noise);
    f.Number("total_variance", &c.total_variance);
    f.Number("cos_mean", &c.cos_mean);
    f.Number("objective_mean", &c.objective_mean);
    f.Number("ess_mean", &c.ess_mean);
    f.Number("ess_min", &c.ess_min);
    f.Number("k_lr_mean", &c.k_lr_mean);
    f.Numbers("k_lr_per_step", &c.k_lr_per_step);
    f.Bool("reference_agrees", &c.reference_agrees);
    if (!f.status().ok()) return f.status();
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
