// Internal building blocks shared by the exact GP (gp.cc) and its
// hyperparameter training (training.cc): the squared-exponential ARD kernel
// evaluated on length-scale-scaled inputs, and the test that decides whether a
// Cholesky factorisation of a kernel matrix is usable. Not a public API.
//
// Thread safety: pure functions.
#ifndef TOTALGRAD_CORE_GP_SE_KERNEL_H_
#define TOTALGRAD_CORE_GP_SE_KERNEL_H_

#include <Eigen/Cholesky>
#include <limits>

#include "core/common/types.h"
#include "core/common/vector_exp.h"

namespace totalgrad::gp::internal {

// out (P x N, overwritten) = sf2 * exp(-1/2 |a_p - b_n|^2) for rows a_p of `a`
// (P x E) and b_n of `b` (N x E), both already divided by the length-scales.
// a_sq / b_sq are their squared row norms. The exponent is formed as
// a.b - |a|^2/2 - |b|^2/2 so that the only O(P N E) work is one BLAS product;
// its cancellation error is absolute (~eps |a|^2), harmless inside exp, but can
// make it slightly positive, hence the clamp at zero.
inline void SeCrossKernel(const ConstRowMatrixRef& a, const Vector& a_sq,
                          const ConstRowMatrixRef& b, const Vector& b_sq, double sf2,
                          Matrix* out) {
  out->resize(a.rows(), b.rows());
  out->noalias() = a * b.transpose();
  // Column by column, so that |b_n|^2 is a scalar; shift, exponential and
  // scale in one pass (the matrix is L2-sized, so passes cost memory traffic).
  const Eigen::Index rows = out->rows();
  for (Eigen::Index n = 0; n < out->cols(); ++n) {
    double* column = out->data() + n * rows;
    ::totalgrad::SeKernelColumn(column, a_sq.data(), b_sq(n), sf2, column, rows);
  }
}

// The query side of a prediction for one output: zs (P x E, overwritten) =
// z / l, zs_sq = its squared row norms, and kstar (P x N) = SeCrossKernel of
// zs against the support points b (N x E, already divided by l, with squared
// norms b_sq).
inline void ScaledQueryCrossKernel(const ConstRowMatrixRef& z, const Vector& inv_lengthscales,
                                   const ConstRowMatrixRef& b, const Vector& b_sq, double sf2,
                                   RowMatrix* zs, Vector* zs_sq, Matrix* kstar) {
  zs->noalias() = z * inv_lengthscales.asDiagonal();
  zs_sq->noalias() = zs->rowwise().squaredNorm();
  SeCrossKernel(*zs, *zs_sq, b, b_sq, sf2, kstar);
}

// True when `llt` succeeded and K is positive definite beyond round-off: every
// pivot L_ii^2 must exceed N * eps * max_diag. Eigen's LLT only reports a
// non-positive pivot; for exactly duplicated inputs with tiny noise the pivot is
// noise + round-off and can come out positive by chance, which would give a
// K^-1 of size ~1/eps and meaningless predictions. Such a matrix is treated as
// a failed factorisation.
inline bool CholeskyAccepted(const Eigen::LLT<Matrix>& llt, double max_diag) {
  if (llt.info() != Eigen::Success) return false;
  const Eigen::Index n = llt.matrixLLT().rows();
  const double threshold = static_cast<double>(n) * std::numeric_limits<double>::epsilon() *
                           max_diag;
  const auto diag = llt.matrixLLT().diagonal().array();
  return diag.allFinite() && (diag.square() > threshold).all();
}

}  // namespace totalgrad::gp::internal

#endif  // TOTALGRAD_CORE_GP_SE_KERNEL_H_
