#include "core/pilco/expected_cost.h"

#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "absl/strings/str_cat.h"
#include "core/common/check.h"
#include "core/pilco/trig.h"

namespace totalgrad::pilco {

absl::Status ExpectedSaturatingCost(const Matrix& F, const Vector& z, const Vector& m,
                                    const Matrix& S, bool with_gradient, CostMoments* out) {
  const int n = static_cast<int>(m.size());
  const int r = static_cast<int>(F.rows());
  TG_CHECK(F.cols() == n && z.size() == n && S.rows() == n && S.cols() == n);
  if (!m.allFinite() || !S.allFinite()) {
    return absl::InvalidArgumentError("cost: state mean or covariance not finite");
  }
  const Vector d = m - z;
  const Vector fd = F * d;
  const Matrix fsf = F * S * F.transpose();
  Matrix b1 = fsf;
  b1.diagonal().array() += 1.0;
  Eigen::LLT<Matrix> llt1(b1);
  Matrix b2 = 2.0 * fsf;
  b2.diagonal().array() += 1.0;
  Eigen::LLT<Matrix> llt2(b2);
  if (llt1.info() != Eigen::Success || llt2.info() != Eigen::Success) {
    return absl::FailedPreconditionError(
        "cost: I + F S F^T not positive definite (state covariance not PSD)");
  }
  const Vector g1 = llt1.solve(fd);
  const double logdet1 = 2.0 * llt1.matrixLLT().diagonal().array().log().sum();
  const double l = std::exp(-0.5 * logdet1 - 0.5 * fd.dot(g1));
  const Vector g2 = llt2.solve(fd);
  const double logdet2 = 2.0 * llt2.matrixLLT().diagonal().array().log().sum();
  const double e2 = std::exp(-0.5 * logdet2 - fd.dot(g2));
  out->mean = 1.0 - l;
  out->var = e2 - l * l;
  if (out->var < 1e-12) out->var = 0.0;
  if (with_gradient) {
    // A = F^T (I + F S F^T)^-1 F; dE/dm = L A d; dE/dS = 1/2 L (A - A d d^T A).
    const Vector ad = F.transpose() * g1;
    const Matrix a = F.transpose() * llt1.solve(F);
    out->dmean_dm = l * ad;
    out->dmean_dS = 0.5 * l * (a - ad * ad.transpose());
    out->dmean_dS = 0.5 * (out->dmean_dS + out->dmean_dS.transpose()).eval();
  }
  (void)r;
  return absl::OkStatus();
}

absl::StatusOr<GaussianCost> GaussianCost::Angle(const Vector& target, const Matrix& q) {
  const int d = static_cast<int>(target.size());
  if (q.rows() != d || q.cols() != d) {
    return absl::InvalidArgumentError(absl::StrCat("cost Q must be ", d, " x ", d));
  }
  if (!target.allFinite() || !q.allFinite()) {
    return absl::InvalidArgumentError("cost target or Q not finite");
  }
  if ((q - q.transpose()).cwiseAbs().maxCoeff() > 1e-12 * (1.0 + q.cwiseAbs().maxCoeff())) {
    return absl::InvalidArgumentError("cost Q is not symmetric");
  }
  Eigen::SelfAdjointEigenSolver<Matrix> eig(2.0 * q);
  if (eig.eigenvalues().minCoeff() < -1e-12 * (1.0 + eig.eigenvalues().cwiseAbs().maxCoeff())) {
    return absl::InvalidArgumentError("cost Q is not positive semi-definite");
  }
  GaussianCost c;
  c.state_dim_ = d;
  // 2 Q = V diag(lambda) V^T = F^T F with F = diag(sqrt(lambda)) V^T.
  c.f_ = eig.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal() *
         eig.eigenvectors().transpose();
  c.z_ = target;
  return c;
}

absl::StatusOr<GaussianCost> GaussianCost::Tip(int state_dim, int position_index,
                                               int angle_index, double pendulum_length,
                                               double width, double target_position) {
  if (position_index < 0 || position_index >= state_dim || angle_index < 0 ||
      angle_index >= state_dim || position_index == angle_index) {
    return absl::InvalidArgumentError(absl::StrCat(
        "tip cost: bad position_index ", position_index, " / angle_index ", angle_index,
        " for state dimension ", state_dim));
  }
  if (!(pendulum_length > 0) || !(width > 0) || !std::isfinite(target_position) ||
      !std::isfinite(pendulum_length) || !std::isfinite(width)) {
    return absl::InvalidArgumentError("tip cost: pendulum_length and width must be > 0");
  }
  GaussianCost c;
  c.state_dim_ = state_dim;
  c.angle_index_ = angle_index;
  const int n = state_dim + 2;  // [x; sin x_a; cos x_a]
  c.f_ = Matrix::Zero(2, n);
  c.f_(0, position_index) = 1.0 / width;
  c.f_(0, state_dim) = pendulum_length / width;
  c.f_(1, state_dim + 1) = pendulum_length / width;
  c.z_ = Vector::Zero(n);
  c.z_(position_index) = target_position;
  // The upright target angle pi through sin/cos, as loss_cp: sin(pi) is
  // 1.2246e-16 in double precision, not 0.
  c.z_(state_dim) = std::sin(M_PI);
  c.z_(state_dim + 1) = std::cos(M_PI);
  return c;
}

absl::Status GaussianCost::Evaluate(const Vector& m, const Matrix& S, bool with_gradient,
                                    CostMoments* out) const {
  TG_CHECK(m.size() == state_dim_ && S.rows() == state_dim_ && S.cols() == state_dim_);
  if (angle_index_ < 0) return ExpectedSaturatingCost(f_, z_, m, S, with_gradient, out);
  if (!m.allFinite() || !S.allFinite()) {
    return absl::InvalidArgumentError("cost: state mean or covariance not finite");
  }
  Vector ym;
  Matrix ys;
  AugmentWithTrig(m, S, angle_index_, &ym, &ys);
  CostMoments aug;
  if (absl::Status st = ExpectedSaturatingCost(f_, z_, ym, ys, with_gradient, &aug); !st.ok()) {
    return st;
  }
  out->mean = aug.mean;
  out->var = aug.var;
  if (with_gradient) {
    out->dmean_dm = Vector::Zero(state_dim_);
    out->dmean_dS = Matrix::Zero(state_dim_, state_dim_);
    AugmentWithTrigBackward(m, S, angle_index_, aug.dmean_dm, aug.dmean_dS, &out->dmean_dm,
                            &out->dmean_dS);
    out->dmean_dS = 0.5 * (out->dmean_dS + out->dmean_dS.transpose()).eval();
  }
  return absl::OkStatus();
}

}  // namespace totalgrad::pilco
