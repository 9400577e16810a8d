#include "core/estimators/gaussian_shaping.h"

#include "core/common/check.h"

namespace totalgrad::estimators {

void SampledExpectedCostGradient(const tasks::StateCost& cost, const GaussianFit& fit,
                                 int samples, Rng* rng, ExpectedCostGradient* out) {
  TG_CHECK(samples >= 1);
  const Eigen::Index s = fit.mean.size();
  RowMatrix zeta(samples, s);
  rng->FillNormal(&zeta);
  RowMatrix x = zeta * fit.chol.transpose();
  x.rowwise() += fit.mean.transpose();
  Vector c;
  RowMatrix grad;
  cost.Evaluate(x, &c, &grad);
  const double inv_k = 1.0 / static_cast<double>(samples);
  out->value = c.mean();
  out->dmean = inv_k * grad.colwise().sum().transpose();
  Matrix chol_bar = inv_k * (grad.transpose() * zeta);  // S x S
  chol_bar.triangularView<Eigen::StrictlyUpper>().setZero();
  out->dcov = CholeskyBackward(fit.chol, chol_bar);
}

absl::Status ExactExpectedCostGradient(const gaussian::GaussianCost& cost, const GaussianFit& fit,
                                       ExpectedCostGradient* out) {
  Matrix cov = fit.covariance;
  cov.diagonal().array() += fit.jitter;
  gaussian::CostMoments moments;
  absl::Status status = cost.Evaluate(fit.mean, cov, /*with_gradient=*/true, &moments);
  if (!status.ok()) return status;
  out->value = moments.mean;
  out->dmean = moments.dmean_dm;
  out->dcov = moments.dmean_dS;
  return absl::OkStatus();
}

void ShapedValues(const GaussianFit& fit, const ExpectedCostGradient& e, Vector* g) {
  const Eigen::Index p = fit.centred.rows();
  const double correction = (static_cast<double>(p - 1) / static_cast<double>(p)) *
                            (e.dcov.cwiseProduct(fit.covariance)).sum();  // tr(e_cov cov)
  const RowMatrix de = fit.centred * e.dcov;  // row i: d_i^T e_cov
  *g = fit.centred * e.dmean;
  g->array() += de.cwiseProduct(fit.centred).rowwise().sum().array() - correction;
}

}  // namespace totalgrad::estimators
