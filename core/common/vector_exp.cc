#include "core/common/vector_exp.h"

#include <algorithm>

#include <bit>
#include <cstdint>

#if defined(__x86_64__) && defined(__SSE2__)
#include <immintrin.h>
#define TOTALGRAD_X86_VECTOR_EXP 1
// GCC 12's avx512fintrin.h passes _mm512_undefined_pd() as the unused merge
// operand of unmasked intrinsics, which -Wmaybe-uninitialized reports inside
// target("avx512f") functions (GCC bug 105593); the values are never read.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
#endif

namespace totalgrad {
namespace {

// exp(x) = 2^k exp(r), k = round(x / ln 2), r = x - k ln 2 in [-ln2/2, ln2/2],
// with ln 2 split in two (Cody-Waite; ln2_hi has enough trailing zero bits for
// k ln2_hi to be exact for |k| < 2^11) and exp(r) by its Taylor polynomial of
// degree 13 (truncation < 5e-18 relative) in Horner form. k is rounded by the
// 1.5 * 2^52 trick, which also leaves k in the low bits of t, and 2^k is
// applied by adding k to the exponent field; x >= -708 keeps 2^k exp(r)
// normal, so the integer add is exact.
constexpr double kLog2e = 1.4426950408889634074;
constexpr double kLn2Hi = 6.93147180369123816490e-01;
constexpr double kLn2Lo = 1.90821492927058770002e-10;
constexpr double kRoundMagic = 6755399441055744.0;  // 1.5 * 2^52
constexpr double kMinArgument = -708.0;
constexpr int kDegree = 13;
// 1/13!, 1/12!, ..., 1/1!, 1/0!
constexpr double kTaylor[kDegree + 1] = {
    1.0 / 6227020800.0, 1.0 / 479001600.0, 1.0 / 39916800.0, 1.0 / 3628800.0,
    1.0 / 362880.0,     1.0 / 40320.0,     1.0 / 5040.0,     1.0 / 720.0,
    1.0 / 120.0,        1.0 / 24.0,        1.0 / 6.0,        0.5,
    1.0,                1.0};

// Portable path: the same operations on one lane.
[[maybe_unused]] double ExpScalar(double x) {
  const double xc = std::max(std::min(x, 0.0), kMinArgument);  // NaN handled below
  const double t = xc * kLog2e + kRoundMagic;
  const double k = t - kRoundMagic;
  const double r = (xc - k * kLn2Hi) - k * kLn2Lo;
  double p = kTaylor[0];
  for (int i = 1; i <= kDegree; ++i) p = p * r + kTaylor[i];
  const uint64_t k_bits = std::bit_cast<uint64_t>(t) - std::bit_cast<uint64_t>(kRoundMagic);
  const double scaled = std::bit_cast<double>(std::bit_cast<uint64_t>(p) + (k_bits << 52));
  if (x != x) return x;
  return x < kMinArgument ? 0.0 : scaled;
}

#ifdef TOTALGRAD_X86_VECTOR_EXP
// Each function below performs exactly this sequence of IEEE operations per
// lane, in this order; only the register width differs.
inline __m128d ExpPacket2(__m128d x) {
  const __m128d xc = _mm_max_pd(_mm_min_pd(x, _mm_setzero_pd()), _mm_set1_pd(kMinArgument));
  const __m128d t = _mm_add_pd(_mm_mul_pd(xc, _mm_set1_pd(kLog2e)), _mm_set1_pd(kRoundMagic));
  const __m128d k = _mm_sub_pd(t, _mm_set1_pd(kRoundMagic));
  const __m128d r = _mm_sub_pd(_mm_sub_pd(xc, _mm_mul_pd(k, _mm_set1_pd(kLn2Hi))),
                               _mm_mul_pd(k, _mm_set1_pd(kLn2Lo)));
  __m128d p = _mm_set1_pd(kTaylor[0]);
  for (int i = 1; i <= kDegree; ++i) p = _mm_add_pd(_mm_mul_pd(p, r), _mm_set1_pd(kTaylor[i]));
  const __m128i k_bits =
      _mm_sub_epi64(_mm_castpd_si128(t), _mm_castpd_si128(_mm_set1_pd(kRoundMagic)));
  const __m128d scaled =
      _mm_castsi128_pd(_mm_add_epi64(_mm_castpd_si128(p), _mm_slli_epi64(k_bits, 52)));
  // x < -708 -> 0 (min/max above would give exp(-708)); NaN -> x. Ordered
  // comparisons are false for NaN, so `below` is clear there.
  const __m128d below = _mm_cmplt_pd(x, _mm_set1_pd(kMinArgument));
  const __m128d nan = _mm_cmpunord_pd(x, x);
  return _mm_or_pd(_mm_andnot_pd(_mm_or_pd(below, nan), scaled), _mm_and_pd(nan, x));
}

__attribute__((target("avx2"))) inline __m256d ExpPacket4(__m256d x) {
  const __m256d xc =
      _mm256_max_pd(_mm256_min_pd(x, _mm256_setzero_pd()), _mm256_set1_pd(kMinArgument));
  const __m256d t =
      _mm256_add_pd(_mm256_mul_pd(xc, _mm256_set1_pd(kLog2e)), _mm256_set1_pd(kRoundMagic));
  const __m256d k = _mm256_sub_pd(t, _mm256_set1_pd(kRoundMagic));
  const __m256d r = _mm256_sub_pd(_mm256_sub_pd(xc, _mm256_mul_pd(k, _mm256_set1_pd(kLn2Hi))),
                                  _mm256_mul_pd(k, _mm256_set1_pd(kLn2Lo)));
  __m256d p = _mm256_set1_pd(kTaylor[0]);
  for (int i = 1; i <= kDegree; ++i) {
    p = _mm256_add_pd(_mm256_mul_pd(p, r), _mm256_set1_pd(kTaylor[i]));
  }
  const __m256i k_bits = _mm256_sub_epi64(_mm256_castpd_si256(t),
                                          _mm256_castpd_si256(_mm256_set1_pd(kRoundMagic)));
  const __m256d scaled = _mm256_castsi256_pd(
      _mm256_add_epi64(_mm256_castpd_si256(p), _mm256_slli_epi64(k_bits, 52)));
  const __m256d below = _mm256_cmp_pd(x, _mm256_set1_pd(kMinArgument), _CMP_LT_OQ);
  const __m256d nan = _mm256_cmp_pd(x, x, _CMP_UNORD_Q);
  return _mm256_or_pd(_mm256_andnot_pd(_mm256_or_pd(below, nan), scaled),
                      _mm256_and_pd(nan, x));
}

__attribute__((target("avx512f"))) inline __m512d ExpPacket8(__m512d x) {
  const __m512d xc =
      _mm512_max_pd(_mm512_min_pd(x, _mm512_setzero_pd()), _mm512_set1_pd(kMinArgument));
  const __m512d t =
      _mm512_add_pd(_mm512_mul_pd(xc, _mm512_set1_pd(kLog2e)), _mm512_set1_pd(kRoundMagic));
  const __m512d k = _mm512_sub_pd(t, _mm512_set1_pd(kRoundMagic));
  const __m512d r = _mm512_sub_pd(_mm512_sub_pd(xc, _mm512_mul_pd(k, _mm512_set1_pd(kLn2Hi))),
                                  _mm512_mul_pd(k, _mm512_set1_pd(kLn2Lo)));
  __m512d p = _mm512_set1_pd(kTaylor[0]);
  for (int i = 1; i <= kDegree; ++i) {
    p = _mm512_add_pd(_mm512_mul_pd(p, r), _mm512_set1_pd(kTaylor[i]));
  }
  const __m512i k_bits = _mm512_sub_epi64(_mm512_castpd_si512(t),
                                          _mm512_castpd_si512(_mm512_set1_pd(kRoundMagic)));
  const __m512d scaled = _mm512_castsi512_pd(
      _mm512_add_epi64(_mm512_castpd_si512(p), _mm512_slli_epi64(k_bits, 52)));
  const __mmask8 below = _mm512_cmp_pd_mask(x, _mm512_set1_pd(kMinArgument), _CMP_LT_OQ);
  const __mmask8 nan = _mm512_cmp_pd_mask(x, x, _CMP_UNORD_Q);
  const __m512d flushed = _mm512_mask_blend_pd(below, scaled, _mm512_setzero_pd());
  return _mm512_mask_blend_pd(nan, flushed, x);
}

// The last odd element goes through a padded packet: same operations.
void ExpTail(const double* x, double* y, Eigen::Index n) {
  for (Eigen::Index i = 0; i < n; ++i) {
    alignas(16) double in[2] = {x[i], 0.0};
    alignas(16) double out[2];
    _mm_store_pd(out, ExpPacket2(_mm_load_pd(in)));
    y[i] = out[0];
  }
}

__attribute__((target("avx2"))) void ExpAvx2Body(const double* x, double* y,
                                                 Eigen::Index n) {
  Eigen::Index i = 0;
  for (; i + 4 <= n; i += 4) _mm256_storeu_pd(y + i, ExpPacket4(_mm256_loadu_pd(x + i)));
  for (; i + 2 <= n; i += 2) _mm_storeu_pd(y + i, ExpPacket2(_mm_loadu_pd(x + i)));
  ExpTail(x + i, y + i, n - i);
}

__attribute__((target("avx512f"))) void ExpAvx512Body(const double* x, double* y,
                                                      Eigen::Index n) {
  Eigen::Index i = 0;
  for (; i + 8 <= n; i += 8) _mm512_storeu_pd(y + i, ExpPacket8(_mm512_loadu_pd(x + i)));
  for (; i + 2 <= n; i += 2) _mm_storeu_pd(y + i, ExpPacket2(_mm_loadu_pd(x + i)));
  ExpTail(x + i, y + i, n - i);
}

// Fused kernel column: y[i] = sf2 * exp(min((dot[i] - 0.5 a_sq[i]) - half_b_sq, 0)),
// the same IEEE operations, in the same order, as the three separate passes it
// replaces (shift, exp, scale), so its result is bitwise theirs.
void SeColumnTail(const double* dot, const double* a_sq, double half_b_sq, double sf2,
                  double* y, Eigen::Index n) {
  for (Eigen::Index i = 0; i < n; ++i) {
    const double x = (dot[i] - 0.5 * a_sq[i]) - half_b_sq;
    alignas(16) double in[2] = {x, 0.0};
    alignas(16) double out[2];
    _mm_store_pd(out, ExpPacket2(_mm_load_pd(in)));
    y[i] = out[0] * sf2;
  }
}

void SeColumnBaselineBody(const double* dot, const double* a_sq, double half_b_sq, double sf2,
                          double* y, Eigen::Index n) {
  const __m128d half = _mm_set1_pd(0.5);
  const __m128d shift = _mm_set1_pd(half_b_sq);
  const __m128d scale = _mm_set1_pd(sf2);
  Eigen::Index i = 0;
  for (; i + 2 <= n; i += 2) {
    const __m128d x = _mm_sub_pd(
        _mm_sub_pd(_mm_loadu_pd(dot + i), _mm_mul_pd(half, _mm_loadu_pd(a_sq + i))), shift);
    _mm_storeu_pd(y + i, _mm_mul_pd(ExpPacket2(x), scale));
  }
  SeColumnTail(dot + i, a_sq + i, half_b_sq, sf2, y + i, n - i);
}

__attribute__((target("avx2"))) void SeColumnAvx2Body(const double* dot, const double* a_sq,
                                                      double half_b_sq, double sf2, double* y,
                                                      Eigen::Index n) {
  const __m256d half = _mm256_set1_pd(0.5);
  const __m256d shift = _mm256_set1_pd(half_b_sq);
  const __m256d scale = _mm256_set1_pd(sf2);
  Eigen::Index i = 0;
  for (; i + 4 <= n; i += 4) {
    const __m256d x = _mm256_sub_pd(
        _mm256_sub_pd(_mm256_loadu_pd(dot + i), _mm256_mul_pd(half, _mm256_loadu_pd(a_sq + i))),
        shift);
    _mm256_storeu_pd(y + i, _mm256_mul_pd(ExpPacket4(x), scale));
  }
  SeColumnBaselineBody(dot + i, a_sq + i, half_b_sq, sf2, y + i, n - i);
}

__attribute__((target("avx512f"))) void SeColumnAvx512Body(const double* dot, const double* a_sq,
                                                          double half_b_sq, double sf2,
                                                          double* y, Eigen::Index n) {
  const __m512d half = _mm512_set1_pd(0.5);
  const __m512d shift = _mm512_set1_pd(half_b_sq);
  const __m512d scale = _mm512_set1_pd(sf2);
  Eigen::Index i = 0;
  for (; i + 8 <= n; i += 8) {
    const __m512d x = _mm512_sub_pd(
        _mm512_sub_pd(_mm512_loadu_pd(dot + i), _mm512_mul_pd(half, _mm512_loadu_pd(a_sq + i))),
        shift);
    _mm512_storeu_pd(y + i, _mm512_mul_pd(ExpPacket8(x), scale));
  }
  SeColumnBaselineBody(dot + i, a_sq + i, half_b_sq, sf2, y + i, n - i);
}

bool CpuHasAvx512() {
  static const bool has = __builtin_cpu_supports("avx512f");
  return has;
}

bool CpuHasAvx2() {
  static const bool has = __builtin_cpu_supports("avx2");
  return has;
}

#endif  // TOTALGRAD_X86_VECTOR_EXP

}  // namespace

void ExpNonPositiveBaseline(const double* x, double* y, Eigen::Index n) {
#ifdef TOTALGRAD_X86_VECTOR_EXP
  Eigen::Index i = 0;
  for (; i + 2 <= n; i += 2) _mm_storeu_pd(y + i, ExpPacket2(_mm_loadu_pd(x + i)));
  ExpTail(x + i, y + i, n - i);
#else
  for (Eigen::Index i = 0; i < n; ++i) y[i] = ExpScalar(x[i]);
#endif
}

bool ExpNonPositiveAvx2(const double* x, double* y, Eigen::Index n) {
#ifdef TOTALGRAD_X86_VECTOR_EXP
  if (!CpuHasAvx2()) return false;
  ExpAvx2Body(x, y, n);
  return true;
#else
  return false;
#endif
}

bool ExpNonPositiveAvx512(const double* x, double* y, Eigen::Index n) {
#ifdef TOTALGRAD_X86_VECTOR_EXP
  if (!CpuHasAvx512()) return false;
  ExpAvx512Body(x, y, n);
  return true;
#else
  return false;
#endif
}

void ExpNonPositive(const double* x, double* y, Eigen::Index n) {
  if (ExpNonPositiveAvx512(x, y, n)) return;
  if (ExpNonPositiveAvx2(x, y, n)) return;
  ExpNonPositiveBaseline(x, y, n);
}

void SeKernelColumn(const double* dot, const double* a_sq, double b_sq, double sf2, double* y,
                    Eigen::Index n) {
  const double half_b_sq = 0.5 * b_sq;
#ifdef TOTALGRAD_X86_VECTOR_EXP
  if (CpuHasAvx512()) {
    SeColumnAvx512Body(dot, a_sq, half_b_sq, sf2, y, n);
  } else if (CpuHasAvx2()) {
    SeColumnAvx2Body(dot, a_sq, half_b_sq, sf2, y, n);
  } else {
    SeColumnBaselineBody(dot, a_sq, half_b_sq, sf2, y, n);
  }
#else
  for (Eigen::Index i = 0; i < n; ++i) {
    y[i] = ExpScalar((dot[i] - 0.5 * a_sq[i]) - half_b_sq) * sf2;
  }
#endif
}

}  // namespace totalgrad
