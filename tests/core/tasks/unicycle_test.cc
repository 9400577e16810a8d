// The unicycle's plant (core/tasks/unicycle.h): the planar case against the
// wheel-and-pendulum equations derived here, the energy's rate as the power
// of the two torques, energy conserved over seconds without them, the mirror
// image, the upright equilibrium, and the adaptive integrator against a
// tighter one over an episode (PILCO's 0.15 s steps) until the unicycle falls.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <numbers>
#include <random>

#include "core/gaussian/trig.h"
#include "core/tasks/unicycle.h"
#include "tests/testutil/plant_energy.h"

namespace totalgrad::tasks {
namespace unicycle_test {

using U = Unicycle;

Unicycle MakeUnicycle(double tolerance = 1e-10) {
  ode::IntegratorOptions integrator;
  integrator.relative_tolerance = tolerance;
  integrator.absolute_tolerance = tolerance;
  return Unicycle(UnicycleParams(), 0.15, integrator);
}

Vector RandomState(std::mt19937_64& rng, double rate_scale, double angle_scale) {
  std::normal_distribution<double> normal;
  Vector x(12);
  for (int i = 0; i < 5; ++i) x(i) = rate_scale * normal(rng);
  for (int i = 5; i < 12; ++i) x(i) = angle_scale * normal(rng);
  return x;
}

Vector Torques(double turntable, double wheel) { return Eigen::Vector2d(turntable, wheel); }

using ::totalgrad::testing::EnergyRate;

TEST(UnicycleTest, PlanarMotionIsAWheelWithAPendulumOnItsAxle) {
  // No roll, yaw or turntable motion: the wheel (angle w) and the frame with
  // the turntable (pitch p) as a pendulum on the rolling axle. Lagrange with
  // T = (Cw + M rw^2) w'^2 / 2 + rw L cos(p) w' p' + Ip p'^2 / 2 and
  // V = g (M rw + L cos p), the wheel torque U doing work U (w' - p'):
  //   (Cw + M rw^2) w'' + rw L cos(p) p'' - rw L sin(p) p'^2 = U
  //   rw L cos(p) w'' + Ip p'' - g L sin(p) = -U,
  // with the pitch inertia Ip = Cw + At + mf rf^2 + mt r^2 of the published
  // equations (unicycle.h).
  const Unicycle plant = MakeUnicycle();
  const UnicycleParams p;
  const double mass = p.wheel_mass + p.frame_mass + p.turntable_mass, rw = p.wheel_radius;
  const double r = p.frame_centre_to_wheel + p.frame_centre_to_turntable;
  const double moment = p.frame_mass * p.frame_centre_to_wheel + p.turntable_mass * r;
  const double pitch_inertia = p.wheel_axial_inertia + p.turntable_diametral_inertia +
                               p.frame_mass * std::pow(p.frame_centre_to_wheel, 2) +
                               p.turntable_mass * r * r;
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal;
  for (int trial = 0; trial < 20; ++trial) {
    Vector x = Vector::Zero(12);
    x(U::kWheelRate) = 3 * normal(rng);
    x(U::kPitchRate) = normal(rng);
    x(U::kPitch) = 0.5 * normal(rng);
    x(U::kYaw) = normal(rng);
    const double torque = 5 * normal(rng);
    Vector f;
    plant.Derivative(x, Torques(0.0, torque), &f);
    const double cp = std::cos(x(U::kPitch)), sp = std::sin(x(U::kPitch));
    const double dp = x(U::kPitchRate);
    Eigen::Matrix2d mass_matrix;
    mass_matrix << p.wheel_axial_inertia + mass * rw * rw, rw * moment * cp, rw * moment * cp,
        pitch_inertia;
    const Eigen::Vector2d forces(torque + rw * moment * sp * dp * dp,
                                 -torque + p.gravity * moment * sp);
    const Eigen::Vector2d expected = mass_matrix.lu().solve(forces);
    EXPECT_NEAR(f(U::kWheelRate), expected(0), 1e-10 * (1 + std::abs(expected(0))));
    EXPECT_NEAR(f(U::kPitchRate), expected(1), 1e-10 * (1 + std::abs(expected(1))));
    // It stays planar, and the contact point rolls along the heading.
    EXPECT_NEAR(f(U::kRollRate), 0.0, 1e-12);
    EXPECT_NEAR(f(U::kYawRate), 0.0, 1e-12);
    EXPECT_NEAR(f(U::kTurntableRate), 0.0, 1e-12);
    EXPECT_DOUBLE_EQ(f(U::kX), rw * std::cos(x(U::kYaw)) * x(U::kWheelRate));
    EXPECT_DOUBLE_EQ(f(U::kY), rw * std::sin(x(U::kYaw)) * x(U::kWheelRate));
  }
}

TEST(UnicycleTest, EnergyRateIsThePowerOfTheTwoTorques) {
  // Each torque acts between its body and the frame: the turntable's V at
  // the relative rate dpsit, the wheel's U at dpsiw - dpsif.
  const Unicycle plant = MakeUnicycle();
  std::mt19937_64 rng(11);
  std::normal_distribution<double> normal;
  for (int trial = 0; trial < 50; ++trial) {
    const Vector x = RandomState(rng, 1.0, 0.4);
    const double v = 5 * normal(rng), u = 5 * normal(rng);
    const double power = v * x(U::kTurntableRate) + u * (x(U::kWheelRate) - x(U::kPitchRate));
    const double rate = EnergyRate(plant, x, Torques(v, u));
    EXPECT_NEAR(rate, power, 1e-6 * (1 + std::abs(power))) << "trial " << trial;
  }
  // Without torques nothing changes the energy.
  const Vector x = RandomState(rng, 1.0, 0.4);
  EXPECT_NEAR(EnergyRate(plant, x, Torques(0, 0)), 0.0, 1e-6);
}

TEST(UnicycleTest, AWrongInertiaFailsTheEnergyRateCheck) {
  // The check above can fail: the same energy with another mass for the
  // frame than the dynamics use does not match the power of the torques.
  UnicycleParams heavier;
  heavier.frame_mass *= 1.01;
  const Unicycle plant = MakeUnicycle();
  const Unicycle other(heavier, 0.15, ode::IntegratorOptions());
  std::mt19937_64 rng(13);
  const Vector x = RandomState(rng, 1.0, 0.4);
  Vector f;
  plant.Derivative(x, Torques(0, 0), &f);
  const double h = 1e-6;
  const double rate = (other.Energy(x + h * f) - other.Energy(x - h * f)) / (2 * h);
  EXPECT_GT(std::abs(rate), 1e-3);
}

TEST(UnicycleTest, EnergyIsConservedOverSecondsWithoutTorques) {
  const Unicycle plant = MakeUnicycle();
  std::mt19937_64 rng(17);
  Vector x = RandomState(rng, 1.0, 0.3);
  const double start = plant.Energy(x);
  for (int step = 0; step < 20; ++step) {  // 3 s
    Vector next;
    ASSERT_TRUE(plant.Step(x, Torques(0, 0), &next).ok()) << "step " << step;
    x = next;
  }
  // Tolerances of 1e-10 per accepted step: the energy within 1e-8 relative.
  EXPECT_NEAR(plant.Energy(x), start, 1e-8 * std::abs(start));
  std::cout.precision(12);
  std::cout << "energy " << start << " J, after 3 s " << plant.Energy(x) << " J\n";
}

TEST(UnicycleTest, TheMirrorImageMovesAsTheMirrorImage) {
  // Reflection in the vertical plane of the heading: roll, yaw, y and the
  // turntable change sign (with their rates and the turntable's torque);
  // the wheel, the pitch and x do not.
  const Unicycle plant = MakeUnicycle();
  Vector mirror(12);
  mirror << -1, -1, 1, 1, -1, 1, -1, -1, -1, 1, 1, -1;
  std::mt19937_64 rng(19);
  for (int trial = 0; trial < 20; ++trial) {
    const Vector x = RandomState(rng, 1.0, 0.5);
    Vector f, g;
    plant.Derivative(x, Torques(1.5, -0.5), &f);
    plant.Derivative(mirror.cwiseProduct(x), Torques(-1.5, -0.5), &g);
    EXPECT_LT((mirror.cwiseProduct(f) - g).cwiseAbs().maxCoeff(), 1e-12) << "trial " << trial;
  }
}

TEST(UnicycleTest, UprightAtRestIsAnUnstableEquilibrium) {
  const Unicycle plant = MakeUnicycle();
  Vector f;
  plant.Derivative(Vector::Zero(12), Torques(0, 0), &f);
  EXPECT_EQ(f.cwiseAbs().maxCoeff(), 0.0);
  // Tilted sideways or forwards it falls further that way.
  Vector rolled = Vector::Zero(12), pitched = Vector::Zero(12);
  rolled(U::kRoll) = 0.01;
  pitched(U::kPitch) = 0.01;
  plant.Derivative(rolled, Torques(0, 0), &f);
  EXPECT_GT(f(U::kRollRate), 0.0);
  plant.Derivative(pitched, Torques(0, 0), &f);
  EXPECT_GT(f(U::kPitchRate), 0.0);
}

TEST(UnicycleTest, AgreesWithATighterIntegratorUntilItFalls) {
  // An episode of PILCO's protocol (dt = 0.15 s, H = 67) from its start
  // distribution (S0 of the scenario) with random torques within maxU / 5:
  // the adaptive steps at the scenes' tolerance (1e-10) against 1e-13, to
  // 1e-7 absolute, for as long as |roll| and |pitch| stay below pi / 2.
  const Unicycle plant = MakeUnicycle(1e-10), reference = MakeUnicycle(1e-13);
  const double start_std[12] = {0.02, 0.02, 0.02, 0.02, 0.02, 0.1, 0.1,
                                0.02, 0.02, 0.02, 0.02, 0.02};
  std::mt19937_64 rng(23);
  std::normal_distribution<double> normal;
  int steps_compared = 0;
  double largest = 0;
  for (int episode = 0; episode < 3; ++episode) {
    Vector x(12);
    for (int i = 0; i < 12; ++i) x(i) = start_std[i] * normal(rng);
    Vector y = x;
    std::uniform_real_distribution<double> turntable(-2.0, 2.0), wheel(-10.0, 10.0);
    for (int step = 0; step < 67; ++step) {
      if (std::abs(x(U::kRoll)) > std::numbers::pi / 2 ||
          std::abs(x(U::kPitch)) > std::numbers::pi / 2) {
        break;
      }
      const Vector u = Torques(turntable(rng), wheel(rng));
      Vector next_x, next_y;
      ASSERT_TRUE(plant.Step(x, u, &next_x).ok());
      ASSERT_TRUE(reference.Step(y, u, &next_y).ok());
      x = next_x;
      y = next_y;
      EXPECT_LT((x - y).cwiseAbs().maxCoeff(), 1e-7) << "episode " << episode << " step " << step;
      largest = std::max(largest, (x - y).cwiseAbs().maxCoeff());
      ++steps_compared;
    }
  }
  EXPECT_GT(steps_compared, 10);
  std::cout << steps_compared << " steps compared before the falls; largest difference "
            << largest << "\n";
}

// ---- the augmented state ----

TEST(UnicycleAugmentTest, TheContactPointsVelocitiesAreTheTimeDerivatives) {
  // Along the ODE, (x, y) moves at (dx, dy) and the goal's coordinates in
  // the unicycle's frame (xc, yc) at (dxc, dyc): central differences in time.
  const Unicycle plant = MakeUnicycle();
  const double rw = UnicycleParams().wheel_radius;
  std::mt19937_64 rng(41);
  for (int trial = 0; trial < 20; ++trial) {
    const Vector x = RandomState(rng, 1.0, 0.8);
    Vector f;
    plant.Derivative(x, Torques(0.5, 1.0), &f);
    const Vector a = UnicycleAugmentedEntries(x, rw);
    EXPECT_NEAR(a(0), f(U::kX), 1e-15);
    EXPECT_NEAR(a(1), f(U::kY), 1e-15);
    const double h = 1e-6;
    const Vector ahead = UnicycleAugmentedEntries(x + h * f, rw);
    const Vector behind = UnicycleAugmentedEntries(x - h * f, rw);
    EXPECT_NEAR(a(2), (ahead(4) - behind(4)) / (2 * h), 1e-7) << "trial " << trial;
    EXPECT_NEAR(a(3), (ahead(5) - behind(5)) / (2 * h), 1e-7) << "trial " << trial;
  }
}

TEST(UnicycleAugmentTest, HandComputedCasesAndTheGpState) {
  // Facing phi = 0 at (1, 2): the goal (the origin) is 1 m behind and 2 m to
  // the right, (xc, yc) = (-1, -2); facing phi = pi / 2 it is (-2, 1).
  Vector x = Vector::Zero(12);
  x(U::kX) = 1;
  x(U::kY) = 2;
  Vector a = UnicycleAugmentedEntries(x, 0.225);
  EXPECT_DOUBLE_EQ(a(4), -1);
  EXPECT_DOUBLE_EQ(a(5), -2);
  x(U::kYaw) = std::numbers::pi / 2;
  a = UnicycleAugmentedEntries(x, 0.225);
  EXPECT_NEAR(a(4), -2, 1e-15);
  EXPECT_NEAR(a(5), 1, 1e-15);
  // The GP state in PILCO's dyno order, and upright over the goal costs 0.
  for (int i = 0; i < 5; ++i) x(i) = i + 1;
  x(U::kRoll) = 0.1;
  x(U::kPitch) = 0.2;
  const Vector s = UnicycleGpState(x, 0.225);
  ASSERT_EQ(s.size(), kUnicycleCostStateDim);
  for (int i = 0; i < 5; ++i) EXPECT_EQ(s(i), i + 1);
  EXPECT_NEAR(s(5), -2, 1e-15);
  EXPECT_NEAR(s(6), 1, 1e-15);
  EXPECT_EQ(s(7), 0.1);
  EXPECT_EQ(s(8), std::numbers::pi / 2);
  EXPECT_EQ(s(9), 0.2);
  EXPECT_EQ(UnicycleCostValue({}, UnicycleGpState(Vector::Zero(12), 0.225)), 0.0);
}

// ---- the cost (loss_unicycle) ----

// A mean near upright and a covariance with correlations: s = [rates (5),
// xc, yc, theta, phi, psif].
void CostTestMoments(std::mt19937_64& rng, double scale, Vector* m, Matrix* s) {
  std::normal_distribution<double> normal;
  *m = Vector(10);
  for (int i = 0; i < 10; ++i) (*m)(i) = 0.3 * normal(rng);
  Matrix root(10, 10);
  for (int i = 0; i < 10; ++i) {
    for (int j = 0; j < 10; ++j) root(i, j) = scale * normal(rng) / std::sqrt(10.0);
  }
  *s = root * root.transpose();
}

// d^2 from z = [s, theta - psif, theta + psif, (sin, cos) of theta, psif,
// theta - psif, theta + psif] as unicycle.h writes it (indices 12.. are the
// sines and cosines in that order).
double CostOfZ(const Vector& z) {
  const double rw = 0.22, r = 0.81;
  const double height = rw * z(13) + r / 2 * z(17) + r / 2 * z(19) - rw - r;
  const double forward = z(5) - r * z(14), sideways = z(6) - (r + rw) * z(12);
  const double yaw = z(8) / (4 * std::numbers::pi);
  return 1 - std::exp(-(8 * height * height + 0.5 * forward * forward +
                        0.5 * sideways * sideways + yaw * yaw) / 2);
}

Matrix CostInputMap() {
  Matrix p = Matrix::Zero(12, 10);
  p.topRows(10).setIdentity();
  p(10, 7) = 1;
  p(10, 9) = -1;
  p(11, 7) = 1;
  p(11, 9) = 1;
  return p;
}

TEST(UnicycleCostTest, AtAPointTheClosedFormIsTheCost) {
  const absl::StatusOr<gaussian::GaussianCost> cost = UnicycleCost();
  ASSERT_TRUE(cost.ok()) << cost.status();
  EXPECT_EQ(cost->state_dim(), kUnicycleCostStateDim);
  std::mt19937_64 rng(29);
  std::normal_distribution<double> normal;
  for (int trial = 0; trial < 20; ++trial) {
    Vector s(10);
    for (int i = 0; i < 10; ++i) s(i) = 0.7 * normal(rng);
    gaussian::CostMoments moments;
    ASSERT_TRUE(cost->Evaluate(s, Matrix::Zero(10, 10), false, &moments).ok());
    EXPECT_NEAR(moments.mean, UnicycleCostValue({}, s), 1e-12);
    EXPECT_NEAR(moments.var, 0.0, 1e-12);
  }
  // Upright over the origin, facing 0: no cost. Fallen sideways (theta =
  // pi / 2): the top is rw + r = 1.03 m lower and (r + rw) to the side, so
  // d^2 = 8 (1.03)^2 + (1.03)^2 / 2.
  EXPECT_EQ(UnicycleCostValue({}, Vector::Zero(10)), 0.0);
  Vector fallen = Vector::Zero(10);
  fallen(7) = std::numbers::pi / 2;
  EXPECT_NEAR(UnicycleCostValue({}, fallen), 1 - std::exp(-8.5 * 1.03 * 1.03 / 2), 1e-12);
}

TEST(UnicycleCostTest, GaussianExpectationMatchesMonteCarlo) {
  // z's Gaussian (the trig moments are exact in mean and covariance) against
  // samples of z(s), then E[c] and Var[c] of the closed form against
  // lossSat on samples of that Gaussian: 10^6 samples, 5 standard errors.
  const absl::StatusOr<gaussian::GaussianCost> cost = UnicycleCost();
  ASSERT_TRUE(cost.ok());
  std::mt19937_64 rng(31);
  Vector m;
  Matrix s;
  CostTestMoments(rng, 0.25, &m, &s);
  const Matrix p = CostInputMap();
  Vector mz;
  Matrix sz;
  gaussian::AugmentWithTrig(p * m, p * s * p.transpose(), std::vector<int>{7, 9, 10, 11}, &mz,
                            &sz);
  const int samples = 1000000;
  std::normal_distribution<double> normal;
  const Matrix ls = s.llt().matrixL();
  const Matrix lz = (sz + 1e-12 * Matrix::Identity(20, 20)).llt().matrixL();
  Vector z_sum = Vector::Zero(20);
  Matrix z_outer = Matrix::Zero(20, 20);
  double c_sum = 0, c_sq = 0;
  Vector e10(10), e20(20);
  for (int k = 0; k < samples; ++k) {
    for (int i = 0; i < 10; ++i) e10(i) = normal(rng);
    const Vector y = p * (m + ls * e10);
    Vector z(20);
    z.head(12) = y;
    const int angles[4] = {7, 9, 10, 11};
    for (int a = 0; a < 4; ++a) {
      z(12 + 2 * a) = std::sin(y(angles[a]));
      z(13 + 2 * a) = std::cos(y(angles[a]));
    }
    z_sum += z;
    z_outer.noalias() += (z - mz) * (z - mz).transpose();
    for (int i = 0; i < 20; ++i) e20(i) = normal(rng);
    const double c = CostOfZ(mz + lz * e20);
    c_sum += c;
    c_sq += c * c;
  }
  const Vector z_mean = z_sum / samples;
  const Matrix z_cov = z_outer / samples - (z_mean - mz) * (z_mean - mz).transpose();
  for (int i = 0; i < 20; ++i) {
    EXPECT_NEAR(z_mean(i), mz(i), 5 * std::sqrt(sz(i, i) / samples) + 1e-12) << "z " << i;
    for (int j = 0; j < 20; ++j) {
      const double se = std::sqrt((sz(i, i) * sz(j, j) + sz(i, j) * sz(i, j)) / samples);
      EXPECT_NEAR(z_cov(i, j), sz(i, j), 5 * se + 1e-12) << "cov " << i << "," << j;
    }
  }
  gaussian::CostMoments moments;
  ASSERT_TRUE(cost->Evaluate(m, s, false, &moments).ok());
  const double mean = c_sum / samples, var = c_sq / samples - mean * mean;
  EXPECT_NEAR(moments.mean, mean, 5 * std::sqrt(var / samples));
  EXPECT_NEAR(moments.var, var, 0.01 * var);
  std::cout << "E[c] " << moments.mean << " (Monte Carlo " << mean << "), Var[c] "
            << moments.var << " (" << var << ")\n";
}

TEST(UnicycleCostTest, GradientsMatchCentralDifferences) {
  const absl::StatusOr<gaussian::GaussianCost> cost = UnicycleCost();
  ASSERT_TRUE(cost.ok());
  std::mt19937_64 rng(37);
  Vector m;
  Matrix s;
  CostTestMoments(rng, 0.3, &m, &s);
  gaussian::CostMoments moments;
  ASSERT_TRUE(cost->Evaluate(m, s, true, &moments).ok());
  auto mean_at = [&](const Vector& mm, const Matrix& ss) {
    gaussian::CostMoments out;
    EXPECT_TRUE(cost->Evaluate(mm, ss, false, &out).ok());
    return out.mean;
  };
  const double h = 1e-6;
  for (int i = 0; i < 10; ++i) {
    Vector up = m, down = m;
    up(i) += h;
    down(i) -= h;
    EXPECT_NEAR(moments.dmean_dm(i), (mean_at(up, s) - mean_at(down, s)) / (2 * h), 1e-7)
        << "dm " << i;
    for (int j = 0; j <= i; ++j) {
      // A symmetric perturbation of S(i, j) and S(j, i) together.
      Matrix su = s, sd = s;
      su(i, j) += h;
      sd(i, j) -= h;
      if (i != j) {
        su(j, i) += h;
        sd(j, i) -= h;
      }
      const double fd = (mean_at(m, su) - mean_at(m, sd)) / (2 * h);
      const double analytic =
          i == j ? moments.dmean_dS(i, i) : moments.dmean_dS(i, j) + moments.dmean_dS(j, i);
      EXPECT_NEAR(analytic, fd, 1e-7) << "dS " << i << "," << j;
    }
  }
}

// The trial's per-step cost: values are UnicycleCostValue's (two widths,
// so the mean over widths is exercised), the batch gradient matches central
// differences of the value, the distance is sqrt(d^2), and its Gaussian form
// is the closed form above.
TEST(UnicycleCostTest, StateCostGradientMatchesCentralDifferences) {
  UnicycleCostParams params;
  params.widths = {0.5, 1.5};
  const UnicycleStateCost cost(params);
  std::mt19937_64 rng(41);
  std::normal_distribution<double> normal;
  RowMatrix x(6, 10);
  for (int r = 0; r < 6; ++r)
    for (int i = 0; i < 10; ++i) x(r, i) = 0.6 * normal(rng);
  Vector values;
  RowMatrix grad;
  cost.Evaluate(x, &values, &grad);
  ASSERT_EQ(grad.rows(), 6);
  ASSERT_EQ(grad.cols(), 10);
  const double h = 1e-6;
  for (int r = 0; r < 6; ++r) {
    const Vector s = x.row(r).transpose();
    EXPECT_EQ(values(r), UnicycleCostValue(params, s));
    for (int i = 0; i < 10; ++i) {
      Vector up = s, down = s;
      up(i) += h;
      down(i) -= h;
      const double fd = (UnicycleCostValue(params, up) - UnicycleCostValue(params, down)) / (2 * h);
      EXPECT_NEAR(grad(r, i), fd, 1e-8) << "row " << r << " entry " << i;
    }
  }
  // Fallen sideways: d = 1.03 sqrt(8.5) (the hand-computed case above).
  Vector fallen = Vector::Zero(10);
  fallen(7) = std::numbers::pi / 2;
  EXPECT_NEAR(UnicycleUprightDistance({}, fallen), 1.03 * std::sqrt(8.5), 1e-12);
  EXPECT_EQ(UnicycleUprightDistance({}, Vector::Zero(10)), 0.0);
  const absl::StatusOr<gaussian::GaussianCost> gaussian = cost.GaussianExpectation();
  ASSERT_TRUE(gaussian.ok());
  gaussian::CostMoments moments;
  ASSERT_TRUE(gaussian->Evaluate(x.row(0).transpose(), Matrix::Zero(10, 10), false, &moments).ok());
  EXPECT_NEAR(moments.mean, values(0), 1e-12);
}

TEST(UnicycleCostTest, AMapOfTheWrongShapeIsRefused) {
  const absl::StatusOr<gaussian::GaussianCost> of_y =
      gaussian::GaussianCost::Saturating(3, std::vector<int>{}, Matrix::Identity(3, 3),
                                         Vector::Zero(3), {1.0});
  ASSERT_TRUE(of_y.ok());
  const absl::StatusOr<gaussian::GaussianCost> wrong =
      gaussian::GaussianCost::OfLinearMap(Matrix::Identity(2, 4), *of_y);
  EXPECT_EQ(wrong.status().code(), absl::StatusCode::kInvalidArgument);
  Matrix nan_map = Matrix::Identity(3, 2);
  nan_map(0, 0) = std::nan("");
  EXPECT_EQ(gaussian::GaussianCost::OfLinearMap(nan_map, *of_y).status().code(),
            absl::StatusCode::kInvalidArgument);
}

}  // namespace unicycle_test
}  // namespace totalgrad::tasks
