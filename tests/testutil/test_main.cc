// main() of every GoogleTest binary of the project (instead of gtest_main).
#include <gtest/gtest.h>

#include "core/common/blas.h"

int main(int argc, char** argv) {
  totalgrad::SelectBlasKernels(argv);  // may re-execute this binary (core/common/blas.h)
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
