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

namespace totalgrad::gp::internal {

// y[i] = exp(min(x[i], 0)) for i < n, the kernel's exponential; x and y may be
// the same array. Results are within 1 ulp of the correctly rounded value;
// exp(x) for x < -708 (below 3.3e-308, irrelevant next to any kernel value
// that matters) is returned as exactly 0 instead of a subnormal; NaN stays
// NaN. The same IEEE operations (no FMA) run in every SIMD width, so the
// result is bitwise the same whether the AVX-512 or AVX2 path (chosen at run
// time, widest first) or the baseline path runs: a trial's numbers do not
// depend on the worker's CPU through this function. With -march=x86-64-v2,
// Eigen's own exp is 2-wide SSE and costs more than the P x N x N product at
// N <= 120; this one runs 8- or 4-wide where it can.
void ExpNonPositive(const double* x, double* y, Eigen::Index n);
// The paths, for tests: baseline (SSE2 on x86-64, scalar elsewhere), AVX2 and
// AVX-512F; the latter two return false (and do nothing) when the CPU lacks
// the instructions.
void ExpNonPositiveBaseline(const double* x, double* y, Eigen::Index n);
bool ExpNonPositiveAvx2(const double* x, double* y, Eigen::Index n);
bool ExpNonPositiveAvx512(const double* x, double* y, Eigen::Index n);

// One column of SeCrossKernel, fused into a single pass over memory:
// y[i] = sf2 * exp(min((dot[i] - 0.5 a_sq[i]) - 0.5 b_sq, 0)) for i < n, where
// dot holds a_i . b; dot and y may alias. Bitwise equal to the three separate
// passes (shift, ExpNonPositive, scale) on every SIMD path, like ExpNonPositive.
void SeKernelColumn(const double* dot, const double* a_sq, double b_sq, double sf2, double* y,
                    Eigen::Index n);

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
    SeKernelColumn(column, a_sq.data(), b_sq(n), sf2, column, rows);
  }
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
