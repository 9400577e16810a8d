// InputSubsetDynamics (particle_system.h): a model that sees a subset of the
// state (PILCO's dyni) as a model on the whole state. Its mean and variance
// are the inner model's on the subset, bit for bit; its Jacobians with
// respect to z = [x, u] against central differences, zero in the columns of
// the state dims it does not see.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "core/estimators/particle_system.h"
#include "core/gp/gp.h"
#include "core/gp/training.h"

namespace totalgrad::estimators {
namespace input_subset_test {

// A GP on 30 random transitions of a 4-dim state with one control, which
// sees the state dims {0, 1, 3} (not 2) and the control.
struct Fixture {
  gp::GpModel model;
  std::vector<int> inputs = {0, 1, 3};
};

Fixture MakeFixture() {
  std::mt19937_64 rng(17);
  std::normal_distribution<double> normal;
  const int n = 30, s = 4;
  RowMatrix x(n, 4), y(n, s);  // x: [x0, x1, x3, u]
  for (int i = 0; i < n; ++i) {
    for (int m = 0; m < 4; ++m) x(i, m) = normal(rng);
    for (int a = 0; a < s; ++a) {
      y(i, a) = std::sin((a + 1) * 0.6 * x(i, 0) + 0.4 * x(i, 2)) + 0.3 * x(i, 3) * x(i, 1) +
                0.02 * normal(rng);
    }
  }
  absl::StatusOr<gp::GpModel> model =
      gp::GpModel::Create(x, y, gp::InitialHyperparameters(x, y));
  EXPECT_TRUE(model.ok()) << model.status();
  return Fixture{*std::move(model)};
}

TEST(InputSubsetDynamics, PredictsTheInnerModelOnTheSubset) {
  const Fixture f = MakeFixture();
  const GpDynamics inner(&f.model);
  const InputSubsetDynamics subset(&inner, f.inputs);
  ASSERT_EQ(subset.state_dim(), 4);
  ASSERT_EQ(subset.input_dim(), 5);  // [x (4), u]
  std::mt19937_64 rng(18);
  std::normal_distribution<double> normal;
  RowMatrix z(6, 5);
  for (Eigen::Index i = 0; i < z.size(); ++i) z.data()[i] = normal(rng);
  RowMatrix zq(6, 4);
  zq << z.col(0), z.col(1), z.col(3), z.col(4);
  RowMatrix mean, var, inner_mean, inner_var;
  subset.Predict(z, 1.0, &mean, &var, nullptr, nullptr);
  inner.Predict(zq, 1.0, &inner_mean, &inner_var, nullptr, nullptr);
  EXPECT_EQ(mean, inner_mean);
  EXPECT_EQ(var, inner_var);
  // The unseen dim changes nothing.
  RowMatrix moved = z;
  moved.col(2).array() += 3.0;
  RowMatrix mean2, var2;
  subset.Predict(moved, 1.0, &mean2, &var2, nullptr, nullptr);
  EXPECT_EQ(mean2, mean);
  EXPECT_EQ(var2, var);
}

TEST(InputSubsetDynamics, JacobiansMatchCentralDifferences) {
  const Fixture f = MakeFixture();
  const GpDynamics inner(&f.model);
  const InputSubsetDynamics subset(&inner, f.inputs);
  const int s = 4, e = 5, p = 3;
  std::mt19937_64 rng(19);
  std::normal_distribution<double> normal;
  RowMatrix z(p, e);
  for (Eigen::Index i = 0; i < z.size(); ++i) z.data()[i] = 0.7 * normal(rng);
  RowMatrix mean, var, dmean, dvar;
  subset.Predict(z, 2.0, &mean, &var, &dmean, &dvar);
  ASSERT_EQ(dmean.rows(), p);
  ASSERT_EQ(dmean.cols(), s * e);
  ASSERT_EQ(dvar.cols(), s * e);
  const double h = 1e-6;
  double largest = 0;
  for (int i = 0; i < p; ++i) {
    for (int m = 0; m < e; ++m) {
      RowMatrix plus = z, minus = z;
      plus(i, m) += h;
      minus(i, m) -= h;
      RowMatrix mp, vp, mm, vm;
      subset.Predict(plus, 2.0, &mp, &vp, nullptr, nullptr);
      subset.Predict(minus, 2.0, &mm, &vm, nullptr, nullptr);
      for (int a = 0; a < s; ++a) {
        const double dm = (mp(i, a) - mm(i, a)) / (2 * h);
        const double dv = (vp(i, a) - vm(i, a)) / (2 * h);
        EXPECT_NEAR(dmean(i, a * e + m), dm, 1e-7 + 1e-6 * std::abs(dm)) << i << " " << a << " " << m;
        EXPECT_NEAR(dvar(i, a * e + m), dv, 1e-7 + 1e-6 * std::abs(dv)) << i << " " << a << " " << m;
        if (m == 2) {
          EXPECT_EQ(dmean(i, a * e + m), 0.0);
          EXPECT_EQ(dvar(i, a * e + m), 0.0);
        }
        largest = std::max(largest, std::abs(dm));
      }
    }
  }
  EXPECT_GT(largest, 1e-2) << "the check should see real slopes";
}

}  // namespace input_subset_test
}  // namespace totalgrad::estimators
