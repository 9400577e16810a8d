#include "client/core_commands/study_format.h"

#include <cmath>
#include <map>
#include <sstream>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "core/common/blas.h"
#include "io/record_format.h"
#include "io/study_results.h"

namespace totalgrad::cli {
namespace {

using io::StudySpec;

using OrderedJson = nlohmann::ordered_json;

std::string Num(double v, const char* format = "%.3g") {
  return std::isfinite(v) ? absl::StrFormat(format, v) : std::string("-");
}

}  // namespace

const study::ReferenceGradient* ReferenceFor(const study::StudyResult& r, int horizon) {
  for (const auto& ref : r.references) {
    if (ref.horizon == horizon) return &ref;
  }
  return nullptr;
}

std::string StudyTableText(const study::StudyResult& r) {
  std::ostringstream os;
  os << "problem: " << r.source << (r.scene.empty() ? "" : "; scene " + r.scene) << "; "
     << r.num_parameters << " policy parameters; study "
     << Num(r.seconds, "%.1f") << " s\n\n";
  os << "reference gradients (pooled; floor = 1.96 |SE| / |g*|):\n";
  os << absl::StrFormat("%5s %10s %9s %8s %9s %-28s %8s %8s %5s  %s\n", "H", "|g*|", "rel_SE",
                        "floor", "J", "estimators (replicates)", "max|z|", "mean_z2", "agree", "note");
  for (const auto& ref : r.references) {
    std::vector<std::string> used;
    for (size_t k = 0; k < ref.used.size(); ++k) {
      used.push_back(absl::StrCat(ref.used[k], " (", ref.replicates[k], ")"));
    }
    os << absl::StrFormat("%5d %10s %9s %8s %9s %-28s %8s %8s %5s  %s\n", ref.horizon,
                          Num(ref.norm, "%.4g"), Num(ref.relative_error), Num(ref.floor),
                          Num(ref.objective, "%.4g"), absl::StrJoin(used, ", "),
                          Num(ref.agreement_max_z), Num(ref.agreement_mean_z2),
                          ref.agree ? "yes" : "NO", ref.note);
  }
  os << "\n";
  os << absl::StrFormat("%-14s %5s %4s %5s %10s %9s %9s %9s %7s %7s %7s %6s %5s  %s\n", "estimator",
                        "P", "H", "reps", "t_min_ms", "rel_rmse", "rel_bias", "bias_noise", "cos",
                        "ess", "k_lr", "nonfin", "err", "note");
  std::vector<std::string> omissions;
  for (const auto& c : r.cells) {
    os << absl::StrFormat("%-14s %5s %4d %5d %10s %9s %9s %9s %7s %7s %7s %6d %5d  %s\n", c.estimator,
                          c.particles > 0 ? std::to_string(c.particles) : "-", c.horizon,
                          c.replicates, Num(c.time_min_s * 1e3, "%.4g"), Num(c.rel_rmse),
                          Num(c.rel_bias), Num(c.rel_bias_noise), Num(c.cos_mean, "%.3f"),
                          Num(c.ess_mean, "%.3f"), Num(c.k_lr_mean, "%.3f"), c.nonfinite, c.errors,
                          study::CellNote(c));
    if (c.omitted || !c.reference_agrees || c.nonfinite > 0 || c.errors > 0) {
      omissions.push_back(absl::StrCat(c.estimator, " P=", c.particles, " H=", c.horizon, ": ",
                                       c.omitted ? c.omission_reason
                                                 : absl::StrCat(c.nonfinite, " non-finite, ",
                                                                c.errors, " errors"),
                                       c.reference_agrees ? "" : " (reference disagrees: not plotted)"));
    }
  }
  if (!omissions.empty()) {
    os << "\nomissions and failures:\n";
    for (const auto& line : omissions) os << "  " << line << "\n";
  }
  return os.str();
}

// Both CSVs are their records' CSV (io/record_format.h), the format every
// other writer of these records uses.
std::string StudyTableCsv(const study::StudyResult& r) {
  std::string out = io::CsvLine(io::RecordCsvColumns(study::CellFields())) + "\n";
  for (const auto& c : r.cells) {
    out += io::CsvLine(io::RecordCsvCells(study::CellFields(), c)) + "\n";
  }
  return out;
}

std::string StudyReferenceCsv(const study::StudyResult& r) {
  std::string out = io::CsvLine(io::RecordCsvColumns(study::ReferenceFields())) + "\n";
  for (const auto& ref : r.references) {
    out += io::CsvLine(io::RecordCsvCells(study::ReferenceFields(), ref)) + "\n";
  }
  return out;
}

OrderedJson StudyToJson(const study::StudyResult& r, const StudySpec& spec) {
  return io::StudyResultToJson(r, spec);
}

}  // namespace totalgrad::cli
