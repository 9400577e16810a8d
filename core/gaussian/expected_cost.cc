#include "core/gaussian/expected_cost.h"

#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "absl/strings/str_cat.h"
#include "core/common/check.h"
#include "core/gaussian/trig.h"

namespace totalgrad::gaussian {

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

namespace {

// F with F^T F = w, for w symmetric PSD: w = V diag(lambda) V^T, F =
// diag(sqrt(lambda)) V^T (tiny negative eigenvalues of rounding clipped).
// InvalidArgument naming `what` when w is not finite, symmetric or PSD.
absl::StatusOr<Matrix> PsdFactor(const Matrix& w, const char* what) {
  if (!w.allFinite()) return absl::InvalidArgumentError(absl::StrCat(what, " not finite"));
  if ((w - w.transpose()).cwiseAbs().maxCoeff() > 1e-12 * (1.0 + w.cwiseAbs().maxCoeff())) {
    return absl::InvalidArgumentError(absl::StrCat(what, " is not symmetric"));
  }
  Eigen::SelfAdjointEigenSolver<Matrix> eig(w);
  if (eig.eigenvalues().minCoeff() < -1e-12 * (1.0 + eig.eigenvalues().cwiseAbs().maxCoeff())) {
    return absl::InvalidArgumentError(absl::StrCat(what, " is not positive semi-definite"));
  }
  return Matrix(eig.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal() *
                eig.eigenvectors().transpose());
}

}  // namespace

absl::StatusOr<GaussianCost> GaussianCost::Angle(const Vector& target, const Matrix& q) {
  const int d = static_cast<int>(target.size());
  if (q.rows() != d || q.cols() != d) {
    return absl::InvalidArgumentError(absl::StrCat("cost Q must be ", d, " x ", d));
  }
  if (!target.allFinite()) return absl::InvalidArgumentError("cost target or Q not finite");
  absl::StatusOr<Matrix> f = PsdFactor(2.0 * q, "cost Q");
  if (!f.ok()) return f.status();
  GaussianCost c;
  c.state_dim_ = d;
  c.fs_ = {*std::move(f)};  // 2 Q = F^T F
  c.z_ = target;
  return c;
}

absl::StatusOr<GaussianCost> GaussianCost::Saturating(int state_dim, int angle_index,
                                                      const Matrix& q_z, const Vector& target_z,
                                                      const std::vector<double>& widths) {
  if (state_dim <= 0 || angle_index >= state_dim) {
    return absl::InvalidArgumentError(absl::StrCat("saturating cost: angle index ", angle_index,
                                                   " outside the state of dimension ", state_dim));
  }
  return Saturating(state_dim, angle_index >= 0 ? std::vector<int>{angle_index} : std::vector<int>{},
                    q_z, target_z, widths);
}

absl::StatusOr<GaussianCost> GaussianCost::Saturating(int state_dim,
                                                      const std::vector<int>& angle_indices,
                                                      const Matrix& q_z, const Vector& target_z,
                                                      const std::vector<double>& widths) {
  if (state_dim <= 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("saturating cost: state dimension ", state_dim, " must be >= 1"));
  }
  for (size_t k = 0; k < angle_indices.size(); ++k) {
    const int a = angle_indices[k];
    if (a < 0 || a >= state_dim || (k > 0 && a <= angle_indices[k - 1])) {
      return absl::InvalidArgumentError(absl::StrCat(
          "saturating cost: angle indices must be strictly increasing in [0, ", state_dim,
          "); entry ", k, " is ", a));
    }
  }
  const int n = state_dim + 2 * static_cast<int>(angle_indices.size());
  if (q_z.rows() != n || q_z.cols() != n || target_z.size() != n) {
    return absl::InvalidArgumentError(absl::StrCat(
        "saturating cost: Q must be ", n, " x ", n, " and the target ", n, " long (z = [x",
        angle_indices.empty() ? "" : ", (sin, cos) per angle", "])"));
  }
  if (!target_z.allFinite()) return absl::InvalidArgumentError("saturating cost: target not finite");
  if (widths.empty()) return absl::InvalidArgumentError("saturating cost: no width");
  GaussianCost c;
  c.state_dim_ = state_dim;
  c.angles_ = angle_indices;
  c.z_ = target_z;
  for (double width : widths) {
    if (!(width > 0) || !std::isfinite(width)) {
      return absl::InvalidArgumentError(
          absl::StrCat("saturating cost: width ", width, " is not a positive number"));
    }
    absl::StatusOr<Matrix> f = PsdFactor(q_z / (width * width), "saturating cost Q");
    if (!f.ok()) return f.status();
    c.fs_.push_back(*std::move(f));  // Q / w^2 = F^T F
  }
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
  c.angles_ = {angle_index};
  const int n = state_dim + 2;  // [x; sin x_a; cos x_a]
  Matrix f = Matrix::Zero(2, n);
  f(0, position_index) = 1.0 / width;
  f(0, state_dim) = pendulum_length / width;
  f(1, state_dim + 1) = pendulum_length / width;
  c.fs_ = {std::move(f)};
  c.z_ = Vector::Zero(n);
  c.z_(position_index) = target_position;
  // The upright target angle pi through sin/cos, as loss_cp: sin(pi) is
  // 1.2246e-16 in double precision, not 0.
  c.z_(state_dim) = std::sin(M_PI);
  c.z_(state_dim + 1) = std::cos(M_PI);
  return c;
}

absl::StatusOr<GaussianCost> GaussianCost::OfLinearMap(const Matrix& input_map,
                                                       GaussianCost cost_of_y) {
  if (input_map.rows() != cost_of_y.state_dim() || input_map.cols() == 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "cost of a linear map: the map is ", input_map.rows(), " x ", input_map.cols(),
        " but the cost sees ", cost_of_y.state_dim(), " entries"));
  }
  if (!input_map.allFinite()) return absl::InvalidArgumentError("cost of a linear map: map not finite");
  if (cost_of_y.input_map_.size() > 0) {
    cost_of_y.input_map_ = cost_of_y.input_map_ * input_map;
  } else {
    cost_of_y.input_map_ = input_map;
  }
  cost_of_y.state_dim_ = static_cast<int>(input_map.cols());
  return cost_of_y;
}

absl::Status GaussianCost::Evaluate(const Vector& m, const Matrix& S, bool with_gradient,
                                    CostMoments* out) const {
  TG_CHECK(m.size() == state_dim_ && S.rows() == state_dim_ && S.cols() == state_dim_);
  if (!m.allFinite() || !S.allFinite()) {
    return absl::InvalidArgumentError("cost: state mean or covariance not finite");
  }
  if (input_map_.size() == 0) return EvaluateWithoutMap(m, S, with_gradient, out);
  const Matrix& p = input_map_;
  const Matrix sy = p * S * p.transpose();
  if (absl::Status st = EvaluateWithoutMap(p * m, 0.5 * (sy + sy.transpose()), with_gradient, out);
      !st.ok()) {
    return st;
  }
  if (!with_gradient) return absl::OkStatus();
  out->dmean_dm = p.transpose() * out->dmean_dm;
  out->dmean_dS = p.transpose() * out->dmean_dS * p;
  return absl::OkStatus();
}

absl::Status GaussianCost::EvaluateWithoutMap(const Vector& m, const Matrix& S,
                                              bool with_gradient, CostMoments* out) const {
  Vector ym = m;
  Matrix ys = S;
  // One angle through the one-angle block (its own bits, as before several
  // angles existed); several through the joint block with the pair moments.
  if (angles_.size() == 1) {
    AugmentWithTrig(m, S, angles_[0], &ym, &ys);
  } else if (!angles_.empty()) {
    AugmentWithTrig(m, S, angles_, &ym, &ys);
  }
  // Several widths: the mean of their costs, and (as PILCO's lossSat, S2 / n)
  // the mean of their variances.
  const double share = 1.0 / static_cast<double>(fs_.size());
  CostMoments sum;
  for (const Matrix& f : fs_) {
    CostMoments one;
    if (absl::Status st = ExpectedSaturatingCost(f, z_, ym, ys, with_gradient, &one); !st.ok()) {
      return st;
    }
    sum.mean += share * one.mean;
    sum.var += share * one.var;
    if (!with_gradient) continue;
    if (sum.dmean_dm.size() == 0) {
      sum.dmean_dm = share * one.dmean_dm;
      sum.dmean_dS = share * one.dmean_dS;
    } else {
      sum.dmean_dm += share * one.dmean_dm;
      sum.dmean_dS += share * one.dmean_dS;
    }
  }
  out->mean = sum.mean;
  out->var = sum.var;
  if (!with_gradient) return absl::OkStatus();
  if (angles_.empty()) {
    out->dmean_dm = std::move(sum.dmean_dm);
    out->dmean_dS = std::move(sum.dmean_dS);
    return absl::OkStatus();
  }
  out->dmean_dm = Vector::Zero(m.size());
  out->dmean_dS = Matrix::Zero(m.size(), m.size());
  if (angles_.size() == 1) {
    AugmentWithTrigBackward(m, S, angles_[0], sum.dmean_dm, sum.dmean_dS, &out->dmean_dm,
                            &out->dmean_dS);
  } else {
    AugmentWithTrigBackward(m, S, angles_, sum.dmean_dm, sum.dmean_dS, &out->dmean_dm,
                            &out->dmean_dS);
  }
  out->dmean_dS = 0.5 * (out->dmean_dS + out->dmean_dS.transpose()).eval();
  return absl::OkStatus();
}

}  // namespace totalgrad::gaussian
