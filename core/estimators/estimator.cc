#include "core/estimators/estimator.h"

#include <cmath>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "core/estimators/rp.h"
#include "core/estimators/total_propagation.h"

namespace totalgrad::estimators {

absl::StatusOr<std::unique_ptr<Estimator>> MakeEstimator(Method method,
                                                         const EstimatorOptions& options) {
  if (absl::Status st = options.Validate(); !st.ok()) return st;
  if (!IsNamedEnum(MethodNames(), method))
    return absl::InvalidArgumentError("MakeEstimator: a method value outside the enum");
  if (!IsParticleMethod(method))
    return absl::InvalidArgumentError(absl::StrCat(
        MethodName(method), " is not a particle method (it runs in core/pilco); particle methods: ",
        absl::StrJoin(ParticleMethods(), ", ", [](std::string* out, Method m) {
          out->append(MethodName(m));
        })));
  // RP keeps its dedicated pass: the reference the composed passes are tested against.
  if (method == Method::kRp) return std::unique_ptr<Estimator>(new RpEstimator());
  absl::StatusOr<MethodRecipe> recipe = RecipeFor(method, options);
  if (!recipe.ok()) return recipe.status();
  return std::unique_ptr<Estimator>(new ParticleEstimator(method, *std::move(recipe)));
}

const EnumNames<LrWeights>& LrWeightsNames() {
  static const EnumNames<LrWeights>* names =
      new EnumNames<LrWeights>{{LrWeights::kBatchImportance, "biw"}, {LrWeights::kPlain, "plain"}};
  return *names;
}

const EnumNames<LrBaseline>& LrBaselineNames() {
  static const EnumNames<LrBaseline>* names = new EnumNames<LrBaseline>{
      {LrBaseline::kBatchImportance, "biw"},
      {LrBaseline::kBatchImportancePair, "biw_pair"},
      {LrBaseline::kLeaveOneOut, "loo"},
      {LrBaseline::kNone, "none"}};
  return *names;
}

const EnumNames<GsDerivative>& GsDerivativeNames() {
  static const EnumNames<GsDerivative>* names = new EnumNames<GsDerivative>{
      {GsDerivative::kSampled, "sampled"}, {GsDerivative::kExact, "exact"}};
  return *names;
}

std::string LrWeightsName(LrWeights w) { return EnumName(LrWeightsNames(), w); }
std::string LrBaselineName(LrBaseline b) { return EnumName(LrBaselineNames(), b); }
std::string GsDerivativeName(GsDerivative d) { return EnumName(GsDerivativeNames(), d); }

absl::Status ParseLrWeights(const std::string& text, LrWeights* out) {
  return ParseEnum("lr_weights", text, LrWeightsNames(), out);
}
absl::Status ParseLrBaseline(const std::string& text, LrBaseline* out) {
  return ParseEnum("lr_baseline", text, LrBaselineNames(), out);
}
absl::Status ParseGsDerivative(const std::string& text, GsDerivative* out) {
  return ParseEnum("gs_derivative", text, GsDerivativeNames(), out);
}

const OptionTable<EstimatorOptions>& EstimatorOptions::Table() {
  static const OptionTable<EstimatorOptions>* table = [] {
    auto* t = new OptionTable<EstimatorOptions>();
    t->Enum("lr_weights", &EstimatorOptions::lr_weights, LrWeightsNames())
        .Enum("lr_baseline", &EstimatorOptions::lr_baseline, LrBaselineNames())
        .Enum("gs_derivative", &EstimatorOptions::gs_derivative, GsDerivativeNames())
        .Double("sn_noise_multiplier", &EstimatorOptions::sn_noise_multiplier)
        .Double("forced_k_lr", &EstimatorOptions::forced_k_lr);
    return t;
  }();
  return *table;
}

absl::Status EstimatorOptions::Validate() const {
  if (!IsNamedEnum(LrWeightsNames(), lr_weights)) return InvalidOption("lr_weights", "is not a known value");
  if (!IsNamedEnum(LrBaselineNames(), lr_baseline)) return InvalidOption("lr_baseline", "is not a known value");
  if (!IsNamedEnum(GsDerivativeNames(), gs_derivative))
    return InvalidOption("gs_derivative", "is not a known value");
  if (!(sn_noise_multiplier >= 0) || !std::isfinite(sn_noise_multiplier))
    return InvalidOption("sn_noise_multiplier", "must be finite and >= 0");
  if (!std::isfinite(forced_k_lr)) return InvalidOption("forced_k_lr", "must be finite");
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
