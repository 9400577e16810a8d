#include "core/estimators/gaussian_fit.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>

#include "core/common/check.h"

namespace totalgrad::estimators {
namespace {

// True when L is a usable factor: every pivot finite and not lost to round-off.
bool UsableFactor(const Matrix& l, double max_diag) {
  for (Eigen::Index k = 0; k < l.rows(); ++k) {
    const double pivot = l(k, k);
    if (!std::isfinite(pivot) || !(pivot * pivot > 1e-12 * max_diag)) return false;
  }
  return true;
}

}  // namespace

void FitGaussian(const ConstRowMatrixRef& x, double base_jitter, GaussianFit* fit) {
  TG_CHECK(x.rows() >= 1 && base_jitter >= 0);
  const Eigen::Index p = x.rows(), s = x.cols();
  fit->mean = x.colwise().mean().transpose();
  fit->centred = x.rowwise() - fit->mean.transpose();
  fit->covariance = fit->centred.transpose() * fit->centred;
  fit->covariance /= static_cast<double>(std::max<Eigen::Index>(p - 1, 1));
  // Exactly symmetric, so that LLT and the shaped values see the same matrix.
  fit->covariance = (0.5 * (fit->covariance + fit->covariance.transpose())).eval();

  const double mean_diag = fit->covariance.diagonal().mean();
  const double scale = (std::isfinite(mean_diag) && mean_diag > 0) ? mean_diag : 1.0;
  double jitter = base_jitter;
  double next = base_jitter >= 1e-10 * scale ? 10.0 * base_jitter : 1e-10 * scale;
  for (int attempt = 0;; ++attempt) {
    Matrix a = fit->covariance;
    a.diagonal().array() += jitter;
    Eigen::LLT<Matrix> llt(a);
    const double max_diag = a.diagonal().maxCoeff();
    if (llt.info() == Eigen::Success) {
      fit->chol = llt.matrixL();
      if (UsableFactor(fit->chol, max_diag) || !std::isfinite(max_diag)) break;
    } else if (!std::isfinite(max_diag)) {
      fit->chol = Matrix::Constant(s, s, std::nan(""));
      break;
    }
    // 1e-10 scale x 10^12 = 100 scale always succeeds for a finite matrix;
    // the bound only stops a loop on values no jitter can repair.
    if (attempt > 14) {
      fit->chol = Matrix::Constant(s, s, std::nan(""));
      break;
    }
    jitter = next;
    next *= 10.0;
  }
  fit->jitter = jitter;
}

Matrix CholeskyBackward(const Matrix& chol, const Matrix& chol_bar) {
  const Eigen::Index s = chol.rows();
  TG_CHECK(chol.cols() == s && chol_bar.rows() == s && chol_bar.cols() == s);
  const auto l = chol.triangularView<Eigen::Lower>();
  Matrix phi = chol.transpose() * chol_bar.triangularView<Eigen::Lower>().toDenseMatrix();
  phi.triangularView<Eigen::StrictlyUpper>().setZero();
  phi.diagonal() *= 0.5;
  // S = L^-T phi L^-1: solve L^T Y = phi, then L^T S^T = Y^T.
  const Matrix y = l.transpose().solve(phi);
  const Matrix st = l.transpose().solve(y.transpose());
  return 0.5 * (st + st.transpose());
}

void GaussianFitBackward(const GaussianFit& fit, const Vector& mean_bar, const Matrix& cov_bar,
                         RowMatrix* x_bar) {
  const Eigen::Index p = fit.centred.rows();
  const double inv_p = 1.0 / static_cast<double>(p);
  const double two_over = 2.0 / static_cast<double>(std::max<Eigen::Index>(p - 1, 1));
  // cov uses 1/max(P-1, 1); with P = 1 the centred particle is 0, so the
  // covariance term vanishes as the covariance itself does.
  *x_bar = two_over * (fit.centred * cov_bar);  // cov_bar symmetric: (C d_i)^T = d_i^T C
  x_bar->rowwise() += inv_p * mean_bar.transpose();
}

Matrix SolveWithFit(const GaussianFit& fit, const Matrix& b) {
  const auto l = fit.chol.triangularView<Eigen::Lower>();
  return l.transpose().solve(l.solve(b));
}

}  // namespace totalgrad::estimators
