#include "core/tasks/cost.h"

#include <cmath>
#include <memory>

#include "absl/strings/str_cat.h"
#include "core/common/check.h"

namespace totalgrad::tasks {

absl::StatusOr<pilco::GaussianCost> StateCost::GaussianExpectation() const {
  return absl::InvalidArgumentError(
      absl::StrCat("the cost '", Name(), "' has no closed-form expectation under a Gaussian state"));
}

absl::StatusOr<pilco::GaussianCost> AngleCost::GaussianExpectation() const {
  const Vector target = target_;
  const Matrix q = q_.asDiagonal();
  return pilco::GaussianCost::Angle(target, q);
}

absl::StatusOr<pilco::GaussianCost> TipCost::GaussianExpectation() const {
  return pilco::GaussianCost::Tip(kCartPoleStateDim, /*position_index=*/0, /*angle_index=*/1, length_,
                                  width_, target_position_);
}

double StateCost::Value(const State& x) const {
  RowMatrix batch(1, kCartPoleStateDim);
  batch.row(0) = x.transpose();
  Vector cost;
  Evaluate(batch, &cost, nullptr);
  return cost(0);
}

AngleCost::AngleCost(const State& target, const State& q_diagonal)
    : target_(target), q_(q_diagonal) {}

void AngleCost::Evaluate(const ConstRowMatrixRef& x, Vector* cost, RowMatrix* grad) const {
  TG_CHECK(cost != nullptr);
  TG_CHECK_EQ(x.cols(), kCartPoleStateDim);
  const Eigen::Index p = x.rows();
  cost->resize(p);
  if (grad != nullptr) grad->resize(p, kCartPoleStateDim);
  for (Eigen::Index i = 0; i < p; ++i) {
    const State diff = x.row(i).transpose() - target_;
    const double quad = (q_.array() * diff.array().square()).sum();
    const double e = std::exp(-quad);
    (*cost)(i) = 1.0 - e;
    // dc/dx_m = exp(-quad) * 2 Q_m (x_m - t_m).
    if (grad != nullptr) grad->row(i) = (2.0 * e) * (q_.array() * diff.array()).transpose();
  }
}

TipCost::TipCost(double target_position, double pendulum_length, double width)
    : target_position_(target_position), length_(pendulum_length), width_(width) {}

void TipCost::Evaluate(const ConstRowMatrixRef& x, Vector* cost, RowMatrix* grad) const {
  TG_CHECK(cost != nullptr);
  TG_CHECK_EQ(x.cols(), kCartPoleStateDim);
  const Eigen::Index p = x.rows();
  cost->resize(p);
  if (grad != nullptr) grad->setZero(p, kCartPoleStateDim);
  const double l = length_;
  const double inv_two_w2 = 1.0 / (2.0 * width_ * width_);
  for (Eigen::Index i = 0; i < p; ++i) {
    const double sn = std::sin(x(i, 1));
    const double cs = std::cos(x(i, 1));
    // Horizontal and vertical offsets of the tip, (s + l sin beta, -l cos beta),
    // from the upright tip above the target, (s_target, l).
    const double dx = x(i, 0) - target_position_ + l * sn;
    const double dy = l * (cs + 1.0);
    const double d2 = dx * dx + dy * dy;
    const double e = std::exp(-d2 * inv_two_w2);
    (*cost)(i) = 1.0 - e;
    if (grad != nullptr) {
      // dc/dz = e / (2 w^2) * d(d^2)/dz; only s and beta enter d^2.
      const double scale = e * inv_two_w2;
      (*grad)(i, 0) = scale * 2.0 * dx;
      (*grad)(i, 1) = scale * (2.0 * dx * l * cs - 2.0 * dy * l * sn);
    }
  }
}

absl::StatusOr<std::unique_ptr<StateCost>> MakeCost(const std::string& name,
                                                    const State& target) {
  if (!target.allFinite()) {
    return absl::InvalidArgumentError("cost target: non-finite entry");
  }
  if (name == "angle") {
    State q;
    q << 1.0, 1.0, 0.0, 0.0;
    return std::make_unique<AngleCost>(target, q);
  }
  if (name == "tip") {
    return std::make_unique<TipCost>(target(0));
  }
  return absl::InvalidArgumentError(
      absl::StrCat("cost: unknown cost '", name, "' (expected 'angle' or 'tip')"));
}

}  // namespace totalgrad::tasks
