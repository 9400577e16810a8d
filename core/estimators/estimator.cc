#include "core/estimators/estimator.h"

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "core/estimators/rp.h"

namespace totalgrad::estimators {

std::vector<std::string> ParticleMethods() { return {"RP"}; }

absl::StatusOr<std::unique_ptr<Estimator>> MakeEstimator(const std::string& name,
                                                         const EstimatorOptions& options) {
  if (name == "RP") return std::unique_ptr<Estimator>(new RpEstimator());
  return absl::InvalidArgumentError(absl::StrCat("unknown method '", name, "'; known: ",
                                                 absl::StrJoin(ParticleMethods(), ", ")));
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
