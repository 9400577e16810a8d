// Deterministic random numbers with independent, named substreams.
//
// A trial is seeded once; every consumer (initial states, observation noise,
// exploration actions, policy initialisation, particle noise of each policy
// optimisation step, ...) draws from its own substream, derived from
// (seed, stream id, index) by SplitMix64 hashing. Adding a consumer therefore
// never shifts the numbers of another one, and the same seed and build always
// give the same numbers.
//
// Thread safety: an Rng object is not thread-safe; make one per thread.
#ifndef TOTALGRAD_CORE_COMMON_RNG_H_
#define TOTALGRAD_CORE_COMMON_RNG_H_

#include <cstdint>
#include <random>

#include "core/common/types.h"

namespace totalgrad {

// Substream identifiers. Values are part of the reproducibility contract:
// never renumber an existing entry.
enum class Stream : uint64_t {
  kInitialState = 1,
  kObservationNoise = 2,
  kExplorationAction = 3,
  kPolicyInit = 4,
  kParticleNoise = 5,
  kEvaluation = 6,
  kGpInit = 7,
  kResampling = 8,
  kStudy = 9,
};

// Mixes 64 bits (SplitMix64 finaliser). Pure function.
uint64_t MixBits(uint64_t x);

class Rng {
 public:
  // A generator for substream `stream`, sub-index `index` of `seed`.
  Rng(uint64_t seed, Stream stream, uint64_t index = 0);

  double Normal() { return normal_(engine_); }
  // Uniform on [lo, hi).
  double Uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(engine_); }
  uint64_t Bits() { return engine_(); }

  // Fills `out` with independent standard normals (row by row).
  void FillNormal(RowMatrix* out);
  void FillNormal(Vector* out);

 private:
  std::mt19937_64 engine_;
  std::normal_distribution<double> normal_;
};

}  // namespace totalgrad

#endif  // TOTALGRAD_CORE_COMMON_RNG_H_
