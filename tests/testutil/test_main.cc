// main() of every GoogleTest binary of the project (instead of gtest_main).
#include <gtest/gtest.h>

#include "core/common/blas.h"

int main(int argc, char** argv) {
  totalgrad::SelectBlasKernels(argv);  // may re-execute this binary (core/common/blas.h)
  // One BLAS thread, as every trial and study runs: ctest runs the binaries
  // side by side (-j2), and OpenBLAS's own threads on a busy machine wait for
  // each other at every call (measured beside a build: 6 minutes of wall time
  // for 11 CPU seconds of EstimatorExtremes.OneAndTwoParticlesAreUnbiased).
  totalgrad::SetBlasThreads(1);
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
