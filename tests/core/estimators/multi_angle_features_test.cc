// The angle-feature adapters with several angles (the cart-double-pendulum's,
// double pendulum's and pendubot's features: the non-angle dims, then (sin,
// cos) per angle): the dynamics' Jacobians and the policy's state adjoint
// against finite differences, and a chain rule that drops a term fails.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

#include "core/common/rng.h"
#include "core/diff/gradient_checker.h"
#include "core/estimators/particle_system.h"
#include "core/gp/training.h"
#include "core/gaussian/angle_features.h"

namespace totalgrad::estimators {
namespace multi_angle_features_test {

constexpr int kS = 4;                          // raw state dims
const std::vector<int> kAngles = {1, 3};       // two angles
constexpr int kF = kS + 2;                     // feature dims
constexpr int kE = kS + 1;                     // raw model inputs [x, u]

diff::CheckOptions Tight() {
  diff::CheckOptions options;
  options.relative_tolerance = 1e-5;
  options.absolute_tolerance = 1e-8;
  return options;
}

// A GP on feature inputs [phi(x), u] fitted (initial hyperparameters) to a
// smooth function of random states.
std::unique_ptr<gp::GpModel> FeatureGp() {
  Rng rng(31, Stream::kStudy);
  RowMatrix x(40, kE);
  rng.FillNormal(&x);
  RowMatrix features;
  gaussian::StatesToFeatures(x.leftCols(kS), kAngles, &features);
  RowMatrix inputs(40, kF + 1);
  inputs.leftCols(kF) = features;
  inputs.col(kF) = x.col(kS);
  RowMatrix targets(40, kS);
  for (int a = 0; a < kS; ++a)
    targets.col(a) = (inputs * Vector::LinSpaced(kF + 1, 0.1 * (a + 1), 0.5)).array().sin().matrix();
  auto model = gp::GpModel::Create(inputs, targets, gp::InitialHyperparameters(inputs, targets));
  EXPECT_TRUE(model.ok()) << model.status();
  return std::make_unique<gp::GpModel>(*std::move(model));
}

RowMatrix SomeInputs() {
  RowMatrix z(3, kE);
  z << 0.1, 2.2, -0.3, 1.0, 3.0,  //
      -0.4, 0.7, 0.5, -2.0, -6.0,  //
      0.3, -2.5, 0.0, 0.4, 1.5;
  return z;
}

TEST(MultiAngleFeatures, FeaturesAreTheNonAngleDimsThenSinCosPerAngle) {
  const RowMatrix x = SomeInputs().leftCols(kS);
  RowMatrix f;
  gaussian::StatesToFeatures(x, kAngles, &f);
  ASSERT_EQ(f.cols(), kF);
  for (Eigen::Index i = 0; i < x.rows(); ++i) {
    EXPECT_EQ(f(i, 0), x(i, 0));
    EXPECT_EQ(f(i, 1), x(i, 2));
    EXPECT_EQ(f(i, 2), std::sin(x(i, 1)));
    EXPECT_EQ(f(i, 3), std::cos(x(i, 1)));
    EXPECT_EQ(f(i, 4), std::sin(x(i, 3)));
    EXPECT_EQ(f(i, 5), std::cos(x(i, 3)));
  }
  // One angle: the single-angle features, the same bits.
  RowMatrix one, single;
  gaussian::StatesToFeatures(x, std::vector<int>{1}, &one);
  gaussian::StatesToFeatures(x, 1, &single);
  EXPECT_EQ(one, single);
}

TEST(MultiAngleFeatures, DynamicsJacobiansMatchFiniteDifferences) {
  const auto model = FeatureGp();
  const GpDynamics inner(model.get());
  const AngleFeatureDynamics dynamics(&inner, kAngles);
  ASSERT_EQ(dynamics.state_dim(), kS);
  const RowMatrix z = SomeInputs();
  const Eigen::Index p = z.rows();
  RowMatrix mean, variance, dmean, dvar;
  dynamics.Predict(z, 1.0, &mean, &variance, &dmean, &dvar);
  const diff::VectorFunction f = [&](const Vector& flat, Vector* out) {
    const RowMatrix zz = Eigen::Map<const RowMatrix>(flat.data(), p, kE);
    RowMatrix m, v;
    dynamics.Predict(zz, 1.0, &m, &v, nullptr, nullptr);
    out->resize(2 * p * kS);
    out->head(p * kS) = Eigen::Map<const Vector>(m.data(), p * kS);
    out->tail(p * kS) = Eigen::Map<const Vector>(v.data(), p * kS);
    return out->allFinite();
  };
  auto assemble = [&](const RowMatrix& dm, const RowMatrix& dv) {
    Matrix j = Matrix::Zero(2 * p * kS, p * kE);
    for (Eigen::Index i = 0; i < p; ++i)
      for (int a = 0; a < kS; ++a)
        for (int m = 0; m < kE; ++m) {
          j(i * kS + a, i * kE + m) = dm(i, a * kE + m);
          j(p * kS + i * kS + a, i * kE + m) = dv(i, a * kE + m);
        }
    return j;
  };
  const Vector flat = Eigen::Map<const Vector>(z.data(), z.size());
  const diff::CheckResult r = diff::CheckJacobian(f, flat, assemble(dmean, dvar), Tight());
  EXPECT_TRUE(r.ok) << r.log;
  // The second angle's column carries weight, and dropping its -d/dcos sin
  // term is caught.
  EXPECT_GT(dmean.col(0 * kE + 3).cwiseAbs().maxCoeff(), 1e-4);
  RowMatrix wrong = dmean;
  for (Eigen::Index i = 0; i < p; ++i)
    for (int a = 0; a < kS; ++a) wrong(i, a * kE + 3) *= 0.5;
  EXPECT_FALSE(diff::CheckJacobian(f, flat, assemble(wrong, dvar), Tight()).ok);
}

TEST(MultiAngleFeatures, PolicyStateAdjointMatchesFiniteDifferences) {
  policy::RbfPolicy rbf(5, kF, 10.0);
  Rng rng(9, Stream::kPolicyInit);
  rbf.Initialize(Vector::Zero(kF), Vector::Constant(kF, 0.8), 1.0, &rng);
  Vector theta = rbf.parameters();
  theta.tail(5) *= 6.0;
  rbf.set_parameters(theta);
  const RbfParticlePolicy inner(&rbf);
  const AngleFeaturePolicy policy(&inner, kAngles);
  ASSERT_EQ(policy.state_dim(), kS);
  const RowMatrix x = SomeInputs().leftCols(kS);
  const Eigen::Index p = x.rows();
  Vector forces;
  PolicyCache cache;
  policy.Evaluate(x, &forces, &cache);
  RowMatrix state_bar;
  policy.Backward(cache, Vector::Ones(p), &state_bar, nullptr, nullptr);
  for (Eigen::Index i = 0; i < p; ++i) {
    const diff::VectorFunction f = [&](const Vector& xi, Vector* out) {
      Vector u;
      policy.Evaluate(xi.transpose(), &u, nullptr);
      *out = u;
      return true;
    };
    const diff::CheckResult r = diff::CheckJacobian(f, x.row(i).transpose(), state_bar.row(i), Tight());
    EXPECT_TRUE(r.ok) << "particle " << i << ": " << r.log;
  }
  EXPECT_GT(state_bar.col(3).cwiseAbs().maxCoeff(), 1e-4);
}

}  // namespace multi_angle_features_test
}  // namespace totalgrad::estimators
