#include "core/estimators/gaussian_resampling.h"

#include "core/common/check.h"

namespace totalgrad::estimators {

void GaussianResampler::Resample(Rng* rng, StepRecord* step) const {
  step->pre_resample_state = step->next_state;
  FitGaussian(step->pre_resample_state, 0.0, &step->resample_fit);
  step->resample_noise.resize(step->next_state.rows(), step->next_state.cols());
  rng->FillNormal(&step->resample_noise);
  // x_j = mean + L zeta_j, i.e. rows: zeta_j^T L^T.
  step->next_state.noalias() = step->resample_noise * step->resample_fit.chol.transpose();
  step->next_state.rowwise() += step->resample_fit.mean.transpose();
}

void GaussianResampler::Backward(const StepRecord& step, const RowMatrix& gamma,
                                 RowMatrix* gamma_pre) const {
  const GaussianFit& fit = step.resample_fit;
  TG_CHECK(gamma.rows() == step.resample_noise.rows() && gamma.cols() == step.resample_noise.cols());
  const Vector mean_bar = gamma.colwise().sum().transpose();
  Matrix chol_bar = gamma.transpose() * step.resample_noise;  // S x S: sum_j gamma_j zeta_j^T
  chol_bar.triangularView<Eigen::StrictlyUpper>().setZero();
  const Matrix cov_bar = CholeskyBackward(fit.chol, chol_bar);
  GaussianFitBackward(fit, mean_bar, cov_bar, gamma_pre);
}

}  // namespace totalgrad::estimators
