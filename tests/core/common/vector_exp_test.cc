#include "core/common/vector_exp.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

namespace totalgrad {
namespace vector_exp_test {

// The GP kernel's exp (core/common/vector_exp.h, used by gp/se_kernel.h):
// accuracy, special values, and bitwise agreement of the SIMD paths.
std::vector<double> ExpTestArguments() {
  std::vector<double> x;
  for (double v = -708.0; v <= 0.0; v += 0.0007137) x.push_back(v);  // odd count on purpose
  for (double v = -1e-3; v <= 0.0; v += 1.37e-7) x.push_back(v);     // near 0
  x.push_back(-0.0);
  x.push_back(0.0);
  return x;
}

TEST(VectorExpTest, ExpIsAccurateToOneUlp) {
  const std::vector<double> x = ExpTestArguments();
  std::vector<double> y(x.size());
  ExpNonPositive(x.data(), y.data(), static_cast<Eigen::Index>(x.size()));
  double worst = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    const double expected = std::exp(x[i]);
    // One ulp of a number in [2^e, 2^(e+1)) is 2^(e-52) <= 2.2e-16 * value;
    // std::exp itself is within one ulp of the exact value: allow two.
    const double ulps = std::abs(y[i] - expected) / (std::numeric_limits<double>::epsilon() * expected);
    worst = std::max(worst, ulps);
    ASSERT_LE(ulps, 2.0) << "x = " << x[i] << " exp " << y[i] << " std::exp " << expected;
  }
  EXPECT_GT(worst, 0.0);  // the comparison really compared two implementations
}

TEST(VectorExpTest, ExpSpecialValues) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const std::vector<double> x = {0.0, 2.5, -708.0, -708.5, -1e4, -inf, nan};
  std::vector<double> y(x.size());
  ExpNonPositive(x.data(), y.data(), static_cast<Eigen::Index>(x.size()));
  EXPECT_EQ(y[0], 1.0);
  EXPECT_EQ(y[1], 1.0);  // the exponent is clamped at 0
  EXPECT_NEAR(y[2], std::exp(-708.0), 2 * std::numeric_limits<double>::epsilon() * y[2]);
  EXPECT_EQ(y[3], 0.0);  // below exp(-708): flushed, never subnormal
  EXPECT_EQ(y[4], 0.0);
  EXPECT_EQ(y[5], 0.0);
  EXPECT_TRUE(std::isnan(y[6]));
  // In place, and every tail length of the SIMD loops.
  for (int n = 1; n <= 9; ++n) {
    std::vector<double> v(n, -0.75);
    ExpNonPositive(v.data(), v.data(), n);
    for (int i = 0; i < n; ++i) EXPECT_NEAR(v[i], std::exp(-0.75), 1e-16) << n << " " << i;
  }
}

TEST(VectorExpTest, SimdPathsAgreeBitwise) {
  const std::vector<double> x = ExpTestArguments();
  const auto n = static_cast<Eigen::Index>(x.size());
  std::vector<double> baseline(x.size()), wide(x.size());
  ExpNonPositiveBaseline(x.data(), baseline.data(), n);
  int paths = 0;
  for (auto* path : {&ExpNonPositiveAvx2, &ExpNonPositiveAvx512}) {
    std::fill(wide.begin(), wide.end(), -1.0);
    if (!path(x.data(), wide.data(), n)) continue;
    ++paths;
    for (size_t i = 0; i < x.size(); ++i) {
      ASSERT_EQ(std::bit_cast<uint64_t>(baseline[i]), std::bit_cast<uint64_t>(wide[i]))
          << "path " << paths << " x = " << x[i];
    }
  }
  if (paths == 0) GTEST_SKIP() << "CPU without AVX2: only the baseline path exists here";
}


// The fused kernel column must give exactly the bits of the three passes it
// replaces (shift, exponential, scale), at every tail length of the SIMD loops
// and with NaN and clamped arguments: fusing the passes changed no kernel value.
TEST(VectorExpTest, FusedColumnEqualsSeparatePassesBitwise) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> args = ExpTestArguments();
  args.resize(std::min<size_t>(args.size(), 4000));
  args.push_back(nan);
  args.push_back(3.0);  // positive exponent: clamped to exp(0)
  for (const double sf2 : {1.0, 0.37, 2.5e3}) {
    for (const double b_sq : {0.0, 0.8, 7.25}) {
      for (Eigen::Index n : {Eigen::Index{1}, Eigen::Index{3}, Eigen::Index{8},
                             Eigen::Index{13}, static_cast<Eigen::Index>(args.size())}) {
        std::vector<double> dot(n), a_sq(n), fused(n), separate(n);
        for (Eigen::Index i = 0; i < n; ++i) {
          a_sq[i] = 0.1 * static_cast<double>(i % 17);
          // Choose dot so that the exponent is args[i] up to rounding.
          dot[i] = args[i] + 0.5 * a_sq[i] + 0.5 * b_sq;
        }
        for (Eigen::Index i = 0; i < n; ++i) separate[i] = (dot[i] - 0.5 * a_sq[i]) - 0.5 * b_sq;
        ExpNonPositiveBaseline(separate.data(), separate.data(), n);
        for (double& v : separate) v *= sf2;
        SeKernelColumn(dot.data(), a_sq.data(), b_sq, sf2, fused.data(), n);
        for (Eigen::Index i = 0; i < n; ++i) {
          ASSERT_EQ(std::bit_cast<uint64_t>(separate[i]), std::bit_cast<uint64_t>(fused[i]))
              << "n = " << n << " i = " << i << " sf2 = " << sf2 << " b_sq = " << b_sq;
        }
        // In place (dot and y alias), as SeCrossKernel calls it.
        SeKernelColumn(dot.data(), a_sq.data(), b_sq, sf2, dot.data(), n);
        for (Eigen::Index i = 0; i < n; ++i) {
          ASSERT_EQ(std::bit_cast<uint64_t>(separate[i]), std::bit_cast<uint64_t>(dot[i]));
        }
      }
    }
  }
}

}  // namespace vector_exp_test
}  // namespace totalgrad
