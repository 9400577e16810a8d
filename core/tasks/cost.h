// Per-step state costs of the scenes (values in [0, 1]).
//
//  * AngleCost: c(x) = 1 - exp(-(x - t)^T Q (x - t)), Q diagonal (the paper's
//    "Angle Cost", Q = diag(1, 1, 0, 0) on the cart-pole, t the target state;
//    any D).
//  * SaturatingCost: PILCO's lossSat on z = [x, sin x_a1, cos x_a1, ...], the
//    mean over widths w of 1 - exp(-(z - z_t)^T (Q / w^2) (z - z_t) / 2), z_t
//    the augmented target (any scene; tasks/scene_catalog.h).
//  * TipCost: PILCO's saturating tip-distance cost,
//    c(x) = 1 - exp(-d^2 / (2 width^2)), with d the distance between the pole
//    tip and the tip of the upright pole above the target cart position:
//    d^2 = (s - s_target + l sin beta)^2 + l^2 (cos beta + 1)^2, l = 0.5 m,
//    width = 0.25 m (pilco-spec.md 3.4, in our angle convention).
//
// Batched evaluation: x is P x D (one state per row), cost is P, the optional
// gradient is P x D with grad(i, m) = dc(x_i)/dx_im.
//
// Each cost also states its expectation under a Gaussian state in closed form
// (GaussianExpectation(): PILCO's lossSat form, core/gaussian/expected_cost.h),
// which PILCO's moment matching and the exact Gaussian-shaping derivatives
// use: the closed form lives with the cost it belongs to.
//
// Thread safety: const methods are thread-safe.
#ifndef TOTALGRAD_CORE_TASKS_COST_H_
#define TOTALGRAD_CORE_TASKS_COST_H_

#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "core/common/types.h"
#include "core/gaussian/expected_cost.h"
#include "core/tasks/cartpole.h"

namespace totalgrad::tasks {

class StateCost {
 public:
  virtual ~StateCost() = default;
  // cost must be non-null; grad may be null (then no gradient is computed).
  // Output sizes are set by the call.
  virtual void Evaluate(const ConstRowMatrixRef& x, Vector* cost, RowMatrix* grad) const = 0;
  virtual std::string Name() const = 0;
  // E[c(x)], Var[c(x)] and their gradients for x ~ N(m, S) in closed form.
  // InvalidArgument naming the cost when it has none (the default).
  virtual absl::StatusOr<gaussian::GaussianCost> GaussianExpectation() const;
  // Convenience for one state.
  double Value(const Vector& x) const;
};

class AngleCost final : public StateCost {
 public:
  // target and q_diagonal: D each.
  AngleCost(const Vector& target, const Vector& q_diagonal);
  void Evaluate(const ConstRowMatrixRef& x, Vector* cost, RowMatrix* grad) const override;
  std::string Name() const override { return "angle"; }
  // W = 2 Q on the raw state (gaussian::GaussianCost::Angle).
  absl::StatusOr<gaussian::GaussianCost> GaussianExpectation() const override;
  const Vector& target() const { return target_; }
  const Vector& q_diagonal() const { return q_; }

 private:
  Vector target_;
  Vector q_;
};

class TipCost final : public StateCost {
 public:
  TipCost(double target_position, double pendulum_length = 0.5, double width = 0.25);
  void Evaluate(const ConstRowMatrixRef& x, Vector* cost, RowMatrix* grad) const override;
  std::string Name() const override { return "tip"; }
  // On the Gaussian approximation of [x; sin beta; cos beta], as PILCO's
  // loss_cp (gaussian::GaussianCost::Tip with position index 0, angle index 1).
  absl::StatusOr<gaussian::GaussianCost> GaussianExpectation() const override;
  double target_position() const { return target_position_; }
  double pendulum_length() const { return length_; }
  double width() const { return width_; }

 private:
  double target_position_;
  double length_;
  double width_;
};

class SaturatingCost final : public StateCost {
 public:
  // target: D; angle_indices: strictly increasing state indices; q: Z x Z
  // symmetric PSD (Z = D + 2 A); widths: > 0 (at least one).
  SaturatingCost(const Vector& target, std::vector<int> angle_indices, const Matrix& q,
                 std::vector<double> widths);
  void Evaluate(const ConstRowMatrixRef& x, Vector* cost, RowMatrix* grad) const override;
  std::string Name() const override { return "saturating"; }
  // PILCO's lossSat on the Gaussian approximation of z for any number of
  // angles and widths (gaussian::GaussianCost::Saturating with the angle list:
  // the mean over the widths, the variance the mean of theirs, gradients
  // with respect to the state's mean and covariance). No angle or one angle
  // gives the same bits as the one-angle form; several angles use z's joint
  // moments (PILCO's gTrig). The constructor's checks leave no error but a
  // Q that is not PSD (InvalidArgument from the factorisation).
  absl::StatusOr<gaussian::GaussianCost> GaussianExpectation() const override;

 private:
  Vector target_z_;
  std::vector<int> angle_indices_;
  Matrix q_;
  std::vector<double> widths_;
};

// "angle" or "tip", with target state `target` (the upright state for both
// scenes). InvalidArgument names an unknown cost.
absl::StatusOr<std::unique_ptr<StateCost>> MakeCost(const std::string& name, const State& target);

}  // namespace totalgrad::tasks

#endif  // TOTALGRAD_CORE_TASKS_COST_H_
