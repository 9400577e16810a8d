#include "core/tasks/cost.h"

#include <cmath>
#include <memory>

#include "absl/strings/str_cat.h"
#include "core/common/check.h"

namespace totalgrad::tasks {

absl::StatusOr<gaussian::GaussianCost> StateCost::GaussianExpectation() const {
  return absl::InvalidArgumentError(
      absl::StrCat("the cost '", Name(), "' has no closed-form expectation under a Gaussian state"));
}

absl::StatusOr<gaussian::GaussianCost> AngleCost::GaussianExpectation() const {
  const Vector target = target_;
  const Matrix q = q_.asDiagonal();
  return gaussian::GaussianCost::Angle(target, q);
}

absl::StatusOr<gaussian::GaussianCost> TipCost::GaussianExpectation() const {
  return gaussian::GaussianCost::Tip(kCartPoleStateDim, /*position_index=*/0, /*angle_index=*/1, length_,
                                  width_, target_position_);
}

absl::StatusOr<gaussian::GaussianCost> SaturatingCost::GaussianExpectation() const {
  const int d = static_cast<int>(target_z_.size() - 2 * angle_indices_.size());
  // The angle-list form for every scene: with no angle it is lossSat on x,
  // with one angle it is the one-angle overload bit for bit (that overload
  // forwards here, and Evaluate keeps the one-angle trig block), with several
  // the joint Gaussian approximation of z (PILCO's gTrig pair blocks).
  return gaussian::GaussianCost::Saturating(d, angle_indices_, q_, target_z_, widths_);
}

double StateCost::Value(const Vector& x) const {
  RowMatrix batch(1, x.size());
  batch.row(0) = x.transpose();
  Vector cost;
  Evaluate(batch, &cost, nullptr);
  return cost(0);
}

AngleCost::AngleCost(const Vector& target, const Vector& q_diagonal)
    : target_(target), q_(q_diagonal) {
  TG_CHECK_EQ(target.size(), q_diagonal.size());
}

void AngleCost::Evaluate(const ConstRowMatrixRef& x, Vector* cost, RowMatrix* grad) const {
  TG_CHECK(cost != nullptr);
  TG_CHECK_EQ(x.cols(), target_.size());
  const Eigen::Index p = x.rows();
  cost->resize(p);
  if (grad != nullptr) grad->resize(p, target_.size());
  for (Eigen::Index i = 0; i < p; ++i) {
    const Vector diff = x.row(i).transpose() - target_;
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

SaturatingCost::SaturatingCost(const Vector& target, std::vector<int> angle_indices, const Matrix& q,
                               std::vector<double> widths)
    : angle_indices_(std::move(angle_indices)), q_(q), widths_(std::move(widths)) {
  const Eigen::Index d = target.size();
  const Eigen::Index z = d + 2 * static_cast<Eigen::Index>(angle_indices_.size());
  TG_CHECK(q.rows() == z && q.cols() == z && !widths_.empty());
  target_z_.resize(z);
  target_z_.head(d) = target;
  for (size_t a = 0; a < angle_indices_.size(); ++a) {
    TG_CHECK(angle_indices_[a] >= 0 && angle_indices_[a] < d);
    target_z_(d + 2 * a) = std::sin(target(angle_indices_[a]));
    target_z_(d + 2 * a + 1) = std::cos(target(angle_indices_[a]));
  }
}

void SaturatingCost::Evaluate(const ConstRowMatrixRef& x, Vector* cost, RowMatrix* grad) const {
  TG_CHECK(cost != nullptr);
  const Eigen::Index d = target_z_.size() - 2 * static_cast<Eigen::Index>(angle_indices_.size());
  TG_CHECK_EQ(x.cols(), d);
  const Eigen::Index p = x.rows();
  cost->resize(p);
  if (grad != nullptr) grad->resize(p, d);
  const double n_widths = static_cast<double>(widths_.size());
  Vector z(target_z_.size()), dz(target_z_.size()), qdz(target_z_.size()), dc_dz(target_z_.size());
  for (Eigen::Index i = 0; i < p; ++i) {
    z.head(d) = x.row(i).transpose();
    for (size_t a = 0; a < angle_indices_.size(); ++a) {
      z(d + 2 * a) = std::sin(x(i, angle_indices_[a]));
      z(d + 2 * a + 1) = std::cos(x(i, angle_indices_[a]));
    }
    dz = z - target_z_;
    qdz.noalias() = q_ * dz;
    const double quad = dz.dot(qdz);
    double c = 0, slope = 0;  // slope: sum_w exp(-quad / (2 w^2)) / w^2
    for (double w : widths_) {
      const double e = std::exp(-quad / (2.0 * w * w));
      c += 1.0 - e;
      slope += e / (w * w);
    }
    (*cost)(i) = c / n_widths;
    if (grad == nullptr) continue;
    // dc/dz = mean_w exp(-quad / (2 w^2)) Q dz / w^2, then the chain rule
    // through sin and cos of each angle.
    dc_dz = (slope / n_widths) * qdz;
    grad->row(i) = dc_dz.head(d).transpose();
    for (size_t a = 0; a < angle_indices_.size(); ++a) {
      const int m = angle_indices_[a];
      (*grad)(i, m) += dc_dz(d + 2 * a) * z(d + 2 * a + 1) - dc_dz(d + 2 * a + 1) * z(d + 2 * a);
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
