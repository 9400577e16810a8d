// PILCO's linear policy with saturation (conCat(@conlin, @gSat), the
// unicycle's controller) under a Gaussian state:
//
//   a = W x + b,   u_j = max_u_j (9 sin a_j + sin 3 a_j) / 8,   x ~ N(m, S),
//
// W F x D, b F. a is Gaussian: N(W m + b, W S W^T), Cov(x, a) = S W^T, so
// the moments of u are GSatJoint's (saturation.h) and, by Stein's lemma
// (u_j depends on a_j only), Cov(x, u) = S W^T diag(c), c_j = E[du_j/da_j].
// All exact for the Gaussian input (no moment matching is needed before the
// saturation; the saturation's own moments are exact too).
//
// Thread safety: free functions.
#ifndef TOTALGRAD_CORE_PILCO_LINEAR_POLICY_H_
#define TOTALGRAD_CORE_PILCO_LINEAR_POLICY_H_

#include "core/common/types.h"

namespace totalgrad::pilco {

struct LinearPolicy {
  Matrix w;      // F x D
  Vector b;      // F
  Vector max_u;  // F, > 0
};

struct LinearPolicyMoments {
  Vector mean;   // F, E[u]
  Matrix cov;    // F x F, Cov[u]
  Matrix cross;  // D x F, Cov(x, u)
  // D x F, S^-1 Cov(x, u) = W^T diag(c): the form the moment-matching
  // propagation carries (pilco::MultiPolicyMoments::u_cross), exact and
  // without S^-1.
  Matrix u_cross;
};

// m D, s D x D symmetric PSD.
void LinearPolicyForward(const LinearPolicy& policy, const Vector& m, const Matrix& s,
                         LinearPolicyMoments* out);

// Reverse mode: from the adjoints of out.mean, out.cov and out.cross (every
// entry its own output), and of out.u_cross when u_cross_bar is given, ADDS
// the adjoints of m (D), s (D x D, every entry its own input), w (F x D) and
// b (F), which must be sized; any of them may be null when not wanted.
void LinearPolicyBackward(const LinearPolicy& policy, const Vector& m, const Matrix& s,
                          const Vector& mean_bar, const Matrix& cov_bar, const Matrix& cross_bar,
                          Vector* m_bar, Matrix* s_bar, Matrix* w_bar, Vector* b_bar,
                          const Matrix* u_cross_bar = nullptr);

}  // namespace totalgrad::pilco

#endif  // TOTALGRAD_CORE_PILCO_LINEAR_POLICY_H_
