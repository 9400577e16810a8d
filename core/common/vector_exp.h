// Vectorised exponentials for the element-wise passes of the GP kernel, the
// RBF policy and the batch importance weights.
//
// Thread safety: pure functions.
#ifndef TOTALGRAD_CORE_COMMON_VECTOR_EXP_H_
#define TOTALGRAD_CORE_COMMON_VECTOR_EXP_H_

#include <Eigen/Core>

namespace totalgrad {

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

// One column of gp::internal::SeCrossKernel, fused into a single pass over memory:
// y[i] = sf2 * exp(min((dot[i] - 0.5 a_sq[i]) - 0.5 b_sq, 0)) for i < n, where
// dot holds a_i . b; dot and y may alias. Bitwise equal to the three separate
// passes (shift, ExpNonPositive, scale) on every SIMD path, like ExpNonPositive.
void SeKernelColumn(const double* dot, const double* a_sq, double b_sq, double sf2, double* y,
                    Eigen::Index n);

}  // namespace totalgrad

#endif  // TOTALGRAD_CORE_COMMON_VECTOR_EXP_H_
