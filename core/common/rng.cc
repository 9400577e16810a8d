#include "core/common/rng.h"

namespace totalgrad {

uint64_t MixBits(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

Rng::Rng(uint64_t seed, Stream stream, uint64_t index)
    : engine_(MixBits(MixBits(MixBits(seed) ^ static_cast<uint64_t>(stream)) ^ index)) {}

void Rng::FillNormal(RowMatrix* out) {
  for (Eigen::Index r = 0; r < out->rows(); ++r)
    for (Eigen::Index c = 0; c < out->cols(); ++c) (*out)(r, c) = Normal();
}

void Rng::FillNormal(Vector* out) {
  for (Eigen::Index i = 0; i < out->size(); ++i) (*out)(i) = Normal();
}

}  // namespace totalgrad
