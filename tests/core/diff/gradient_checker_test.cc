#include "core/diff/gradient_checker.h"

#include <cmath>

#include <gtest/gtest.h>

namespace totalgrad::diff {
namespace gradient_checker_test {

// f(x) = [x0^2 x1, sin(x1) + x0]
bool F(const Vector& x, Vector* v) {
  v->resize(2);
  (*v)(0) = x(0) * x(0) * x(1);
  (*v)(1) = std::sin(x(1)) + x(0);
  return true;
}

Matrix TrueJacobian(const Vector& x) {
  Matrix j(2, 2);
  j << 2 * x(0) * x(1), x(0) * x(0), 1.0, std::cos(x(1));
  return j;
}

TEST(GradientChecker, AcceptsCorrectJacobian) {
  Vector x(2);
  x << 0.7, -1.3;
  const CheckResult r = CheckJacobian(F, x, TrueJacobian(x));
  EXPECT_TRUE(r.ok) << r.log;
  EXPECT_LT(r.max_relative_error, 1e-8);
}

TEST(GradientChecker, RejectsWrongJacobian) {
  Vector x(2);
  x << 0.7, -1.3;
  Matrix wrong = TrueJacobian(x);
  wrong(1, 1) *= 1.001;  // a 0.1% error in one entry must be caught
  const CheckResult r = CheckJacobian(F, x, wrong);
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.worst_row, 1);
  EXPECT_EQ(r.worst_col, 1);
}

TEST(GradientChecker, RejectsNonFiniteAnalytic) {
  Vector x(2);
  x << 0.7, -1.3;
  Matrix wrong = TrueJacobian(x);
  wrong(0, 0) = std::nan("");
  EXPECT_FALSE(CheckJacobian(F, x, wrong).ok);
}

TEST(GradientChecker, ReportsFailingFunction) {
  const VectorFunction failing = [](const Vector&, Vector*) { return false; };
  Vector x = Vector::Zero(2);
  const CheckResult r = CheckJacobian(failing, x, Matrix::Zero(2, 2));
  EXPECT_FALSE(r.ok);
  EXPECT_FALSE(r.log.empty());
}

}  // namespace gradient_checker_test
}  // namespace totalgrad::diff
