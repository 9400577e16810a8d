// Fixed-width vectors of doubles for hand-vectorised loops, in GCC's vector
// extensions: the same source compiles to one AVX-512 instruction, two AVX2
// ones or four SSE2 ones per operation, with identical lane arithmetic, so a
// loop written with them gives the same bits on every CPU (with
// -ffp-contract=off, which the build sets: no FMA contraction).
//
// TG_VECTOR_CLONES on a function makes the compiler emit one copy per
// instruction set (AVX-512F, AVX2, baseline) and pick one at load time.
//
// Usage rules that keep results reproducible: every lane is an independent
// sequence of IEEE operations; lanes are combined (CombineLanes) in lane
// order; a loop's assignment of elements to lanes depends only on the data
// sizes, never on a thread count.
#ifndef TOTALGRAD_CORE_COMMON_SIMD_H_
#define TOTALGRAD_CORE_COMMON_SIMD_H_

#include <cstdint>
#include <cstring>

// The helpers below take and return 64-byte vectors; GCC warns that their
// calling convention differs between instruction sets, which cannot matter:
// they are inline and never cross a translation unit.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"

namespace totalgrad::simd {

constexpr int kLanes = 8;
typedef double Doubles __attribute__((vector_size(kLanes * sizeof(double))));
typedef int64_t Mask __attribute__((vector_size(kLanes * sizeof(int64_t))));

inline Doubles Load(const double* p) {
  Doubles v;
  std::memcpy(&v, p, sizeof(v));
  return v;
}
inline void Store(double* p, Doubles v) { std::memcpy(p, &v, sizeof(v)); }
inline Doubles Broadcast(double x) { return Doubles{} + x; }
// where(mask, a, b): lane l is a[l] where mask[l] is set (all ones), else b[l].
inline Doubles Select(Mask mask, Doubles a, Doubles b) { return mask ? a : b; }
// Sum of the lanes, in lane order.
inline double CombineLanes(Doubles v) {
  double total = 0;
  for (int l = 0; l < kLanes; ++l) total += v[l];
  return total;
}

}  // namespace totalgrad::simd

#pragma GCC diagnostic pop

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define TG_VECTOR_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define TG_VECTOR_CLONES
#endif

#endif  // TOTALGRAD_CORE_COMMON_SIMD_H_
