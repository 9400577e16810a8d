// Expected saturating costs under a Gaussian state (PILCO's lossSat and
// loss_cp, pilco-spec.md 3.3-3.4), with gradients.
//
// Generic form: c(y) = 1 - exp(-1/2 |F (y - z)|^2) with F (r x n), for
// y ~ N(m, S):
//   E[c]      = 1 - det(I + F S F^T)^-1/2 exp(-1/2 d^T F^T (I + F S F^T)^-1 F d),
//   E[(1-c)^2] likewise with 2 F^T F; Var[c] = E[(1-c)^2] - (1 - E[c])^2,
//   set to 0 when below 1e-12 (as lossSat).
// Writing W = F^T F, this is lossSat with weight W; the factor form keeps
// I + F S F^T symmetric positive definite for any PSD S and singular W.
//
// GaussianCost builds the cart-pole costs and the scenes' saturating cost:
//  * Angle: c(x) = 1 - exp(-(x - t)^T Q (x - t)) (tasks::AngleCost), i.e.
//    W = 2 Q on the raw state.
//  * Tip: c(x) = 1 - exp(-d^2 / (2 width^2)), d^2 = (x_p - target + l sin x_a)^2
//    + l^2 (cos x_a + 1)^2 (tasks::TipCost; upright at x_a = pi), evaluated, as
//    loss_cp does, on the Gaussian approximation of [x; sin x_a; cos x_a]
//    (AugmentWithTrig).
//
// Thread safety: const methods are thread-safe.
#ifndef TOTALGRAD_CORE_GAUSSIAN_EXPECTED_COST_H_
#define TOTALGRAD_CORE_GAUSSIAN_EXPECTED_COST_H_

#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/common/types.h"

namespace totalgrad::gaussian {

struct CostMoments {
  double mean = 0;   // E[c]
  double var = 0;    // Var[c] (>= 0)
  Vector dmean_dm;   // n, filled when gradients are asked for
  Matrix dmean_dS;   // n x n, symmetric
};

// F r x n, z and m n, S n x n. Errors: InvalidArgument for non-finite input,
// FailedPrecondition if I + F S F^T cannot be factorised (S not PSD).
absl::Status ExpectedSaturatingCost(const Matrix& F, const Vector& z, const Vector& m,
                                    const Matrix& S, bool with_gradient, CostMoments* out);

class GaussianCost {
 public:
  // Q: D x D symmetric positive semi-definite; target: D.
  static absl::StatusOr<GaussianCost> Angle(const Vector& target, const Matrix& q);
  // PILCO's lossSat on z = [x] (angle_index -1) or z = [x, sin x_a, cos x_a]
  // (the Gaussian approximation of z, as for Tip): for each width w,
  // E[1 - exp(-1/2 (z - z_t)^T (Q / w^2) (z - z_t))]; the cost is the mean
  // over the widths and its variance the mean of their variances (PILCO's
  // S2 / n). q_z: Z x Z symmetric PSD and target_z: Z (Z = D or D + 2);
  // widths: > 0, at least one. InvalidArgument naming what is wrong.
  static absl::StatusOr<GaussianCost> Saturating(int state_dim, int angle_index,
                                                 const Matrix& q_z, const Vector& target_z,
                                                 const std::vector<double>& widths);
  // The same on z = [x, sin x_a1, cos x_a1, sin x_a2, cos x_a2, ...] for any
  // number A >= 0 of angles (angle_indices strictly increasing in [0, D)):
  // z's Gaussian approximation is AugmentWithTrig's joint one (trig.h, the
  // pair blocks of PILCO's gTrig), Z = D + 2A. Gradients with respect to
  // (m, S) go back through AugmentWithTrigBackward. One angle is the
  // overload above, bit for bit. InvalidArgument naming what is wrong
  // (angle indices, shapes, widths, Q not finite / symmetric / PSD).
  static absl::StatusOr<GaussianCost> Saturating(int state_dim,
                                                 const std::vector<int>& angle_indices,
                                                 const Matrix& q_z, const Vector& target_z,
                                                 const std::vector<double>& widths);
  // `cost_of_y` applied to y = P x (P = input_map, Y x D, finite; Y =
  // cost_of_y.state_dim()): y ~ N(P m, P S P^T), the gradients taken back
  // through P. PILCO's unicycle cost sees angle differences and sums this
  // way (tasks::UnicycleCost). InvalidArgument on a shape or a non-finite P.
  static absl::StatusOr<GaussianCost> OfLinearMap(const Matrix& input_map,
                                                  GaussianCost cost_of_y);
  // Indices into the D-dim state; length > 0, width > 0.
  static absl::StatusOr<GaussianCost> Tip(int state_dim, int position_index, int angle_index,
                                          double pendulum_length, double width,
                                          double target_position = 0.0);

  int state_dim() const { return state_dim_; }

  // Moments of the cost of x ~ N(m, S) (D-dim); gradients with respect to m
  // and S (symmetric) when with_gradient. Errors as ExpectedSaturatingCost.
  absl::Status Evaluate(const Vector& m, const Matrix& S, bool with_gradient,
                        CostMoments* out) const;

 private:
  GaussianCost() = default;
  // Moments of the cost of the state the factors see (before input_map_).
  absl::Status EvaluateWithoutMap(const Vector& m, const Matrix& S, bool with_gradient,
                                  CostMoments* out) const;
  int state_dim_ = 0;
  Matrix input_map_;  // empty: none (the cost sees x itself)
  // Non-empty: the cost sees [x; sin x_a1; cos x_a1; ...] (one angle: the
  // one-angle AugmentWithTrig, so Tip and one-angle Saturating keep their bits).
  std::vector<int> angles_;
  std::vector<Matrix> fs_;  // one factor per width (Angle, Tip: one)
  Vector z_;
};

}  // namespace totalgrad::gaussian

#endif  // TOTALGRAD_CORE_GAUSSIAN_EXPECTED_COST_H_
