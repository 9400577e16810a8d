#include "core/estimators/estimator.h"

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "core/estimators/rp.h"
#include "core/estimators/total_propagation.h"

namespace totalgrad::estimators {

std::vector<std::string> ParticleMethods() {
  return {"RP", "GR", "LR", "TP", "GLR", "GTP", "GTP+sn", "DEL"};
}

absl::StatusOr<std::unique_ptr<Estimator>> MakeEstimator(const std::string& name,
                                                         const EstimatorOptions& options) {
  // RP keeps its dedicated pass: the reference the composed passes are tested against.
  if (name == "RP") return std::unique_ptr<Estimator>(new RpEstimator());
  for (const std::string& method : ParticleMethods()) {
    if (method != name) continue;
    absl::StatusOr<MethodRecipe> recipe = RecipeFor(name, options);
    if (!recipe.ok()) return recipe.status();
    return std::unique_ptr<Estimator>(new ParticleEstimator(name, *std::move(recipe)));
  }
  return absl::InvalidArgumentError(absl::StrCat("unknown method '", name, "'; known: ",
                                                 absl::StrJoin(ParticleMethods(), ", ")));
}

std::string LrWeightsName(LrWeights w) {
  return w == LrWeights::kBatchImportance ? "biw" : "plain";
}

std::string LrBaselineName(LrBaseline b) {
  switch (b) {
    case LrBaseline::kBatchImportance: return "biw";
    case LrBaseline::kBatchImportancePair: return "biw_pair";
    case LrBaseline::kLeaveOneOut: return "loo";
    case LrBaseline::kNone: return "none";
  }
  return "";
}

std::string GsDerivativeName(GsDerivative d) {
  return d == GsDerivative::kSampled ? "sampled" : "exact";
}

absl::Status ParseLrWeights(const std::string& text, LrWeights* out) {
  if (text == "biw") *out = LrWeights::kBatchImportance;
  else if (text == "plain") *out = LrWeights::kPlain;
  else return absl::InvalidArgumentError(absl::StrCat("LR weights '", text, "' is not one of biw, plain"));
  return absl::OkStatus();
}

absl::Status ParseLrBaseline(const std::string& text, LrBaseline* out) {
  if (text == "biw") *out = LrBaseline::kBatchImportance;
  else if (text == "biw_pair") *out = LrBaseline::kBatchImportancePair;
  else if (text == "loo") *out = LrBaseline::kLeaveOneOut;
  else if (text == "none") *out = LrBaseline::kNone;
  else return absl::InvalidArgumentError(absl::StrCat("LR baseline '", text, "' is not one of biw, biw_pair, loo, none"));
  return absl::OkStatus();
}

absl::Status ParseGsDerivative(const std::string& text, GsDerivative* out) {
  if (text == "sampled") *out = GsDerivative::kSampled;
  else if (text == "exact") *out = GsDerivative::kExact;
  else return absl::InvalidArgumentError(absl::StrCat("shaping derivative '", text, "' is not one of sampled, exact"));
  return absl::OkStatus();
}

Vector ColumnSampleVariance(const RowMatrix& per_particle) {
  const Eigen::Index p = per_particle.rows();
  if (p < 2) return Vector::Zero(per_particle.cols());
  const Eigen::RowVectorXd mean = per_particle.colwise().mean();
  return ((per_particle.rowwise() - mean).array().square().colwise().sum() /
          static_cast<double>(p - 1))
      .transpose();
}

}  // namespace totalgrad::estimators
