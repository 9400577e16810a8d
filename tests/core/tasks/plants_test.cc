// The plants of the scene catalog against their published equations
// (core/tasks/*.h, from PILCO a0b48b7's dynamics_*.m, shared/docs/
// scenes-notes.md): the right-hand side solves the published A a = r (built
// here independently), the energy changes exactly by the power of the
// controls and the friction, is conserved without them over seconds of
// integration, and the adaptive step agrees with a fine fixed-step RK4.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <numbers>

#include "core/ode/integrator.h"
#include "core/tasks/scene_catalog.h"
#include "tests/testutil/testutil.h"
#include "tests/testutil/plant_energy.h"

namespace totalgrad::tasks {
namespace plants_test {

constexpr double kPi = std::numbers::pi;

Vector Of(std::initializer_list<double> values) {
  Vector v(static_cast<Eigen::Index>(values.size()));
  Eigen::Index i = 0;
  for (double x : values) v(i++) = x;
  return v;
}

std::unique_ptr<Plant> PlantOf(const std::string& scene) {
  const SceneDefinition* d = FindSceneDefinition(scene);
  EXPECT_NE(d, nullptr) << scene;
  return MakePlant(*d);
}

using ::totalgrad::testing::EnergyRate;

TEST(PendulumTest, PublishedRightHandSide) {
  const auto plant = PlantOf("pendulum");  // m = l = 1, b = 0.01, g = 9.82
  Vector f;
  // Hanging at rest, u = 1 N m: ddtheta = 1 / (1/3).
  plant->Derivative(Of({0.0, 0.0}), Of({1.0}), &f);
  EXPECT_NEAR(f(0), 3.0, 1e-14);
  EXPECT_EQ(f(1), 0.0);
  // Horizontal, moving: ddtheta = (0.5 - 0.01 * 2 - 9.82 / 2) * 3.
  plant->Derivative(Of({2.0, kPi / 2}), Of({0.5}), &f);
  EXPECT_NEAR(f(0), (0.5 - 0.02 - 4.91) * 3.0, 1e-12);
  EXPECT_EQ(f(1), 2.0);
}

// A [dd_1, dd_2] = r of the double pendulum as published, with tau = B u.
void ExpectDoublePendulumEquations(const Plant& plant, const Matrix& input_map, const Vector& x,
                                   const Vector& u) {
  const double m1 = 0.5, m2 = 0.5, l1 = 0.5, l2 = 0.5, g = 9.82;
  const double i1 = m1 * l1 * l1 / 12, i2 = m2 * l2 * l2 / 12;
  const double dth1 = x(0), dth2 = x(1), th1 = x(2), th2 = x(3);
  const Vector tau = input_map * u;
  Matrix a(2, 2);
  a << l1 * l1 * (m1 / 4 + m2) + i1, m2 * l1 * l2 * std::cos(th1 - th2) / 2,
      m2 * l1 * l2 * std::cos(th1 - th2) / 2, l2 * l2 * m2 / 4 + i2;
  Vector r(2);
  r << g * l1 * std::sin(th1) * (m1 / 2 + m2) - m2 * l1 * l2 * dth2 * dth2 * std::sin(th1 - th2) / 2 + tau(0),
      m2 * l2 * (l1 * dth1 * dth1 * std::sin(th1 - th2) + g * std::sin(th2)) / 2 + tau(1);
  Vector f;
  plant.Derivative(x, u, &f);
  EXPECT_TRUE(testing::MatricesNear(a * f.head(2), r, 1e-12, 1e-12));
  EXPECT_EQ(f(2), dth1);
  EXPECT_EQ(f(3), dth2);
}

TEST(DoublePendulumTest, PublishedRightHandSide) {
  const auto dp = PlantOf("double-pendulum");
  ASSERT_EQ(dp->control_dim(), 2);
  for (const Vector& x : {Of({0.3, -1.2, 0.4, 2.9}), Of({2.0, 0.5, kPi, 0.1}), Of({0, 0, 1.0, -2.0})}) {
    ExpectDoublePendulumEquations(*dp, Matrix::Identity(2, 2), x, Of({0.7, -1.3}));
  }
  // The pendubot is the same plant with the torque at the first joint only.
  const auto pendubot = PlantOf("pendubot");
  ASSERT_EQ(pendubot->control_dim(), 1);
  Matrix first_joint(2, 1);
  first_joint << 1.0, 0.0;
  ExpectDoublePendulumEquations(*pendubot, first_joint, Of({0.3, -1.2, 0.4, 2.9}), Of({1.5}));
}

TEST(CartDoublePendulumTest, PublishedRightHandSide) {
  const auto plant = PlantOf("cart-double-pendulum");
  const double m1 = 0.5, m2 = 0.5, m3 = 0.5, l2 = 0.6, l3 = 0.6, b = 0.1, g = 9.82;
  for (const Vector& x : {Of({0.1, 0.4, -1.0, 2.0, 0.3, -2.5}), Of({0, 0, 0, 0, kPi, kPi})}) {
    const double u = 3.0;
    const double dx = x(1), dth1 = x(2), dth2 = x(3), th1 = x(4), th2 = x(5);
    Matrix a(3, 3);
    a << 2 * (m1 + m2 + m3), -(m2 + 2 * m3) * l2 * std::cos(th1), -m3 * l3 * std::cos(th2),
        -(3 * m2 + 6 * m3) * std::cos(th1), (2 * m2 + 6 * m3) * l2, 3 * m3 * l3 * std::cos(th1 - th2),
        -3 * std::cos(th2), 3 * l2 * std::cos(th1 - th2), 2 * l3;
    Vector r(3);
    r << 2 * u - 2 * b * dx - (m2 + 2 * m3) * l2 * dth1 * dth1 * std::sin(th1) -
             m3 * l3 * dth2 * dth2 * std::sin(th2),
        (3 * m2 + 6 * m3) * g * std::sin(th1) - 3 * m3 * l3 * dth2 * dth2 * std::sin(th1 - th2),
        3 * l2 * dth1 * dth1 * std::sin(th1 - th2) + 3 * g * std::sin(th2);
    Vector f;
    plant->Derivative(x, Of({u}), &f);
    EXPECT_TRUE(testing::MatricesNear(a * f.segment(1, 3), r, 1e-12, 1e-12));
    EXPECT_EQ(f(0), dx);
    EXPECT_EQ(f(4), dth1);
    EXPECT_EQ(f(5), dth2);
  }
}

// dE/dt is the controls' power minus the friction's: the energies (and hence
// the equations' inertia terms) belong to one Lagrangian.
TEST(PlantEnergyTest, RateIsThePowerOfControlsAndFriction) {
  {
    const auto p = PlantOf("pendulum");
    const Vector x = Of({1.3, 0.8}), u = Of({0.6});
    EXPECT_NEAR(EnergyRate(*p, x, u), (0.6 - 0.01 * 1.3) * 1.3, 1e-7);
  }
  {
    const auto p = PlantOf("double-pendulum");
    const Vector x = Of({1.3, -0.7, 0.8, 2.2}), u = Of({0.6, -0.4});
    EXPECT_NEAR(EnergyRate(*p, x, u), 0.6 * 1.3 + -0.4 * -0.7, 1e-7);
  }
  {
    const auto p = PlantOf("pendubot");
    const Vector x = Of({1.3, -0.7, 0.8, 2.2}), u = Of({0.6});
    EXPECT_NEAR(EnergyRate(*p, x, u), 0.6 * 1.3, 1e-7);
  }
  {
    const auto p = PlantOf("cart-double-pendulum");
    const Vector x = Of({0.2, 0.9, 1.3, -0.7, 0.8, 2.2}), u = Of({2.5});
    EXPECT_NEAR(EnergyRate(*p, x, u), (2.5 - 0.1 * 0.9) * 0.9, 1e-6);
  }
}

// A wrong energy (here: the double pendulum's without the rods' own inertia)
// fails the rate check: the test has power.
TEST(PlantEnergyTest, AWrongEnergyFailsTheRateCheck) {
  class WrongEnergy final : public Plant {
   public:
    explicit WrongEnergy(std::unique_ptr<Plant> inner) : Plant(0.1, {}), inner_(std::move(inner)) {}
    int state_dim() const override { return 4; }
    int control_dim() const override { return 2; }
    void Derivative(const Vector& x, const Vector& u, Vector* f) const override { inner_->Derivative(x, u, f); }
    double Energy(const Vector& x) const override {
      const double i = 0.5 * 0.25 / 12;
      return inner_->Energy(x) - i * (x(0) * x(0) + x(1) * x(1)) / 2;
    }
   private:
    std::unique_ptr<Plant> inner_;
  };
  const WrongEnergy wrong(PlantOf("double-pendulum"));
  const Vector x = Of({1.3, -0.7, 0.8, 2.2}), u = Of({0.6, -0.4});
  EXPECT_GT(std::abs(EnergyRate(wrong, x, u) - (0.6 * 1.3 + -0.4 * -0.7)), 1e-3);
}

// Without friction and controls the energy stays constant over 3 s of
// chaotic motion (adaptive steps at the plants' 1e-10 tolerances).
TEST(PlantEnergyTest, ConservedWithoutFrictionAndControls) {
  struct Case {
    std::string scene;
    Vector start;
  };
  for (const Case& c : {Case{"pendulum", Of({0.0, 2.5})},
                        Case{"double-pendulum", Of({0.0, 0.0, 2.0, 2.5})},
                        Case{"pendubot", Of({1.0, -1.0, 0.5, 3.0})},
                        Case{"cart-double-pendulum", Of({0.0, 0.0, 0.0, 0.0, 2.0, 2.5})}}) {
    SceneDefinition d = *FindSceneDefinition(c.scene);
    d.pendulum.friction = 0.0;
    d.cart_double_pendulum.friction = 0.0;
    const auto plant = MakePlant(d);
    const Vector u = Vector::Zero(plant->control_dim());
    Vector x = c.start;
    const double e0 = plant->Energy(x);
    double worst = 0;
    for (int k = 0; k < static_cast<int>(3.0 / d.dt); ++k) {
      Vector next;
      ASSERT_TRUE(plant->Step(x, u, &next).ok()) << c.scene << " step " << k;
      x = next;
      worst = std::max(worst, std::abs(plant->Energy(x) - e0));
    }
    EXPECT_LT(worst, 1e-7 * (1 + std::abs(e0))) << c.scene;
    EXPECT_GT((x - c.start).norm(), 0.1) << c.scene << ": the state must have moved";
  }
}

// One control period against a fine fixed-step RK4 reference.
TEST(PlantStepTest, MatchesFineRk4) {
  struct Case {
    std::string scene;
    Vector start, u;
  };
  for (const Case& c : {Case{"pendulum", Of({0.5, 1.0}), Of({2.0})},
                        Case{"double-pendulum", Of({0.5, -0.5, 2.5, 3.5}), Of({1.0, -2.0})},
                        Case{"pendubot", Of({0.5, -0.5, 2.5, 3.5}), Of({3.0})},
                        Case{"cart-double-pendulum", Of({0.1, 0.2, 0.5, -0.5, 2.5, 3.5}), Of({15.0})}}) {
    const auto plant = PlantOf(c.scene);
    Vector next;
    ASSERT_TRUE(plant->Step(c.start, c.u, &next).ok()) << c.scene;
    Vector reference = c.start;
    const ode::Rhs rhs = [&](const Vector& z, Vector* dz) { plant->Derivative(z, c.u, dz); };
    ode::IntegrateRk4(rhs, plant->dt(), 4000, &reference);
    EXPECT_TRUE(testing::MatricesNear(next, reference, 1e-9, 1e-9)) << c.scene;
  }
}

TEST(PlantStepTest, WrongSizesAndNonFiniteInputsAreRefused) {
  const auto plant = PlantOf("double-pendulum");
  Vector next = Vector::Constant(4, 7.0);
  EXPECT_EQ(plant->Step(Of({0, 0, 0}), Of({0, 0}), &next).code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(plant->Step(Of({0, 0, 0, 0}), Of({0}), &next).code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(plant->Step(Of({0, NAN, 0, 0}), Of({0, 0}), &next).code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(next, Vector::Constant(4, 7.0));
}

// The cart-pole through the Plant interface is the cart-pole, bit for bit.
TEST(PlantStepTest, CartPoleThroughThePlantInterfaceIsTheSame) {
  const CartPole cartpole;
  const Plant& plant = cartpole;
  State x;
  x << 0.1, 2.0, -0.3, 1.5;
  State next;
  ASSERT_TRUE(cartpole.Step(x, 4.0, &next).ok());
  Vector generic;
  ASSERT_TRUE(plant.Step(Vector(x), Of({4.0}), &generic).ok());
  EXPECT_EQ(Vector(next), generic);
}

}  // namespace plants_test
}  // namespace totalgrad::tasks
