// A Gaussian fitted to a batch of particles, and the reverse-mode derivatives
// that carry a cotangent on the fit back to the particles (paper section 2.1
// and Murray 2016 for the Cholesky factor). Shared by Gaussian resampling (GR),
// Gaussian shaping (GLR, GTP) and density-estimation LR (DEL).
//
//   mean  = (1/P) sum_i x_i,   d_i = x_i - mean
//   cov   = (1/(P-1)) sum_i d_i d_i^T          (Bessel-corrected; 0 when P = 1)
//   L L^T = cov + jitter I                     (lower Cholesky factor)
//
// Cotangents follow the symmetric convention: for a scalar f(mean, cov),
// cov_bar is the symmetric matrix with df = <cov_bar, dcov> for every
// symmetric perturbation dcov.
//
// Thread safety: functions are re-entrant.
#ifndef TOTALGRAD_CORE_ESTIMATORS_GAUSSIAN_FIT_H_
#define TOTALGRAD_CORE_ESTIMATORS_GAUSSIAN_FIT_H_

#include "core/common/types.h"

namespace totalgrad::estimators {

struct GaussianFit {
  Vector mean;        // S
  RowMatrix centred;  // P x S, d_i = x_i - mean
  Matrix covariance;  // S x S, the sample covariance (without jitter)
  double jitter = 0;  // added to the diagonal before factorising
  Matrix chol;        // S x S lower triangular, L L^T = covariance + jitter I
  int particles() const { return static_cast<int>(centred.rows()); }
};

// Fits a Gaussian to the rows of x (P x S, P >= 1). The jitter is base_jitter
// (>= 0) unless the factorisation fails or a pivot is lost to round-off
// (L_kk^2 <= 1e-12 max diag), as for P <= S or collinear particles; then it is
// raised, x10 at a time, from max(base_jitter, 1e-10 scale), scale = the mean
// diagonal of cov (1 if that is 0), until the factorisation succeeds. The
// jitter is a constant for the derivatives below. Non-finite particles give a
// non-finite fit (no error); callers check the values they produce.
void FitGaussian(const ConstRowMatrixRef& x, double base_jitter, GaussianFit* fit);

// Reverse mode through L = chol(A) (A symmetric positive definite):
//   A_bar = sym(L^-T Phi(L^T L_bar) L^-1),
// Phi = lower triangle with the diagonal halved, sym(B) = (B + B^T)/2. Only the
// lower triangle of chol_bar is read. Returns the symmetric A_bar (S x S).
Matrix CholeskyBackward(const Matrix& chol, const Matrix& chol_bar);

// Particle cotangents (P x S, overwritten) of a scalar that depends on the
// particles through (mean, cov) only:
//   x_bar_i = mean_bar / P + 2/(P-1) cov_bar d_i       (cov_bar symmetric)
// The path through the mean inside cov cancels because sum_i d_i = 0.
void GaussianFitBackward(const GaussianFit& fit, const Vector& mean_bar, const Matrix& cov_bar,
                         RowMatrix* x_bar);

// Solves (cov + jitter I) X = B with the fit's factor. B is S x k.
Matrix SolveWithFit(const GaussianFit& fit, const Matrix& b);

}  // namespace totalgrad::estimators

#endif  // TOTALGRAD_CORE_ESTIMATORS_GAUSSIAN_FIT_H_
