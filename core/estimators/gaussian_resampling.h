// GR: Gaussian resampling (PIPPS; pipps-spec.md 5.2). After every transition
// the particles x'_{t+1} are replaced by P fresh draws from the Gaussian
// fitted to them,
//   x_{t+1}^j = mean + L zeta_j,   zeta_j ~ N(0, I),   L L^T = cov + jitter I,
// and the cost and the next step use the new particles. The backward pass is
// the exact pathwise derivative of that computation with eps and zeta held
// fixed (the jitter is a constant):
//   mean_bar = sum_j gamma_j,  L_bar = tril(sum_j gamma_j zeta_j^T),
//   cov_bar = CholeskyBackward(L, L_bar),
//   gamma'_i = mean_bar / P + 2/(P-1) cov_bar d_i.
// The jitter is 0 unless the sample covariance cannot be factorised (P <= S,
// collinear particles), see FitGaussian.
//
// Thread safety: a GaussianResampler is stateless and thread-safe.
#ifndef TOTALGRAD_CORE_ESTIMATORS_GAUSSIAN_RESAMPLING_H_
#define TOTALGRAD_CORE_ESTIMATORS_GAUSSIAN_RESAMPLING_H_

#include "core/estimators/rollout.h"

namespace totalgrad::estimators {

class GaussianResampler final : public StepResampler {
 public:
  // Draws P x S standard normals from *rng (row by row).
  void Resample(Rng* rng, StepRecord* step) const override;
  void Backward(const StepRecord& step, const RowMatrix& gamma, RowMatrix* gamma_pre) const override;
};

}  // namespace totalgrad::estimators

#endif  // TOTALGRAD_CORE_ESTIMATORS_GAUSSIAN_RESAMPLING_H_
