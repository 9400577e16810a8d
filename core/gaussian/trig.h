// Moments of (sin theta, cos theta) for a Gaussian angle (PILCO's gTrig,
// pilco-spec.md 3.1), and the joint Gaussian of a state with the sin/cos of
// one of its entries appended.
//
// Every function here is exact (no sampling). Derivatives are explicit
// Jacobians (Sophus-style Dx_ functions) for the scalar block and
// vector-Jacobian products ("Backward") for the augmentation, which is what
// reverse-mode accumulation over a horizon needs.
//
// Thread safety: free functions, no shared state.
#ifndef TOTALGRAD_CORE_GAUSSIAN_TRIG_H_
#define TOTALGRAD_CORE_GAUSSIAN_TRIG_H_

#include <vector>

#include <Eigen/Core>

#include "core/common/types.h"

namespace totalgrad::gaussian {

// Moments of (sin t, cos t) for t ~ N(mean, var), var >= 0.
struct TrigMoments {
  double e_sin = 0;    // E[sin t] = exp(-var/2) sin(mean)
  double e_cos = 0;    // E[cos t] = exp(-var/2) cos(mean)
  double var_sin = 0;  // Var[sin t]
  double var_cos = 0;  // Var[cos t]
  double cov_sc = 0;   // Cov[sin t, cos t]
  // The five numbers above in this order.
  Eigen::Matrix<double, 5, 1> AsVector() const;
};

// Computed in a form without cancellation for small var (expm1), so a nearly
// deterministic angle gives variances with full relative precision.
TrigMoments GTrig(double mean, double var);

// 5 x 2 Jacobian of GTrig(mean, var).AsVector() with respect to (mean, var),
// row-major in the sense J(r, c) = d out_r / d in_c.
Eigen::Matrix<double, 5, 2> Dx_GTrig(double mean, double var);

// The joint Gaussian of y = [x; sin x_a; cos x_a] for x ~ N(m, S) (D-dim),
// with the moments of (sin, cos) from GTrig and the cross-covariances by
// Stein's lemma: Cov(x, sin x_a) = S(:, a) E[cos x_a],
// Cov(x, cos x_a) = -S(:, a) E[sin x_a]. angle_index in [0, D).
// *y_mean (D + 2) and *y_cov ((D + 2) x (D + 2), symmetric) are resized.
void AugmentWithTrig(const Vector& m, const Matrix& S, int angle_index, Vector* y_mean,
                     Matrix* y_cov);

// Reverse mode of AugmentWithTrig: given the adjoints of y_mean and y_cov
// (y_cov_bar need not be symmetric: every entry of y_cov is treated as its own
// output), ADDS the adjoints of m and S to *m_bar (D) and *S_bar (D x D),
// which must be sized.
void AugmentWithTrigBackward(const Vector& m, const Matrix& S, int angle_index,
                             const Vector& y_mean_bar, const Matrix& y_cov_bar, Vector* m_bar,
                             Matrix* S_bar);

// Several angles (the cart-double-pendulum's, the pendubot's): the joint
// Gaussian of y = [x; sin x_a1; cos x_a1; sin x_a2; cos x_a2; ...] (D + 2A,
// angle_indices strictly increasing in [0, D), A >= 1). Each angle's own block
// is GTrig's; the blocks of two angles k != l follow from the product
// formulas, e.g. E[sin x_k sin x_l] = (E cos(x_k - x_l) - E cos(x_k + x_l)) / 2
// with x_k +- x_l ~ N(m_k +- m_l, S_kk + S_ll +- (S_kl + S_lk)); x's blocks by
// Stein's lemma as above. One angle is the function above, bit for bit.
void AugmentWithTrig(const Vector& m, const Matrix& S, const std::vector<int>& angle_indices,
                     Vector* y_mean, Matrix* y_cov);

// Its reverse mode, with the contract of the one-angle AugmentWithTrigBackward.
void AugmentWithTrigBackward(const Vector& m, const Matrix& S, const std::vector<int>& angle_indices,
                             const Vector& y_mean_bar, const Matrix& y_cov_bar, Vector* m_bar,
                             Matrix* S_bar);

}  // namespace totalgrad::gaussian

#endif  // TOTALGRAD_CORE_GAUSSIAN_TRIG_H_
