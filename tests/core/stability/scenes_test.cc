// Stability suite, the scenes beyond the cart-pole (docs/stability.md):
//  * the frictionless double pendulum and pendubot at high energy: the
//    adaptive integrator meets its tolerance (a step matches a converged
//    fine RK4 reference; energy is conserved over many steps, the drift
//    stated), or reports that it cannot (step budget named, state untouched);
//  * the cart-double-pendulum with tiny link masses, lengths or cart mass
//    (stiff): the same contract;
//  * several angles at variance 1e3 in what exists for them today: the
//    particle methods' (sin, cos) feature adapters with two angles (RP's
//    gradient against finite differences, every particle method finite),
//    PILCO's one-angle trig block (exact for independent angles only) and
//    its joint several-angle block (the pair moments exact);
//  * a scene with no angle at all: no (sin, cos) adapter, RP's gradient
//    against finite differences.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include <Eigen/Eigenvalues>

#include "core/common/rng.h"
#include "core/diff/gradient_checker.h"
#include "core/estimators/estimator.h"
#include "core/estimators/particle_system.h"
#include "core/learner/trial.h"
#include "core/ode/integrator.h"
#include "core/pilco/saturation.h"
#include "core/gaussian/trig.h"
#include "core/study/frozen_problem.h"
#include "core/tasks/scene.h"
#include "core/tasks/scene_catalog.h"
#include "tests/testutil/testutil.h"

namespace totalgrad {
namespace scenes_test {

const tasks::SceneDefinition& Definition(const std::string& name) {
  const tasks::SceneDefinition* d = tasks::FindSceneDefinition(name);
  TG_CHECK(d != nullptr);
  return *d;
}

// RK4 over one control period of `plant` with `substeps` equal steps.
Vector Rk4Reference(const tasks::Plant& plant, const Vector& x, const Vector& u, int substeps) {
  const ode::Rhs rhs = [&](const Vector& z, Vector* dzdt) { plant.Derivative(z, u, dzdt); };
  Vector z = x;
  ode::IntegrateRk4(rhs, plant.dt(), substeps, &z);
  return z;
}

// One step of `plant` against a converged RK4 reference (n and 2n substeps
// agree to 1e-11 first). Returns |adaptive - reference|_inf / (1 + |x|_inf).
double StepErrorAgainstReference(const tasks::Plant& plant, const Vector& x, const Vector& u,
                                 int substeps, ode::IntegrationReport* report) {
  Vector next;
  const absl::Status st = plant.Step(x, u, &next, report);
  EXPECT_TRUE(st.ok()) << st;
  if (!st.ok()) return INFINITY;
  const Vector fine = Rk4Reference(plant, x, u, substeps);
  const Vector finer = Rk4Reference(plant, x, u, 2 * substeps);
  const double scale = 1.0 + finer.lpNorm<Eigen::Infinity>();
  EXPECT_LT((fine - finer).lpNorm<Eigen::Infinity>(), 1e-11 * scale)
      << "the reference itself is not converged";
  return (next - finer).lpNorm<Eigen::Infinity>() / scale;
}

// The relative energy drift max_t |E(t) - E(0)| / |E(0)| over `steps` control
// periods with zero controls.
double EnergyDrift(const tasks::Plant& plant, Vector x, int steps, int* total_steps) {
  const Vector u = Vector::Zero(plant.control_dim());
  const double e0 = plant.Energy(x);
  double drift = 0;
  *total_steps = 0;
  for (int t = 0; t < steps; ++t) {
    Vector next;
    ode::IntegrationReport report;
    const absl::Status st = plant.Step(x, u, &next, &report);
    EXPECT_TRUE(st.ok()) << "step " << t << ": " << st;
    if (!st.ok()) return INFINITY;
    *total_steps += report.accepted_steps;
    x = next;
    drift = std::max(drift, std::abs(plant.Energy(x) - e0) / std::abs(e0));
  }
  return drift;
}

// Central differences of J with step h = 1e-6 max(1, |theta_j|) carry a
// round-off error of about eps |J| / h; entries are compared to a relative
// 1e-5 with an absolute floor of ten times that round-off.
diff::CheckOptions FiniteDifferenceCheck(double objective) {
  diff::CheckOptions check;
  check.relative_step = 1e-6;
  check.relative_tolerance = 1e-5;
  check.absolute_tolerance =
      10.0 * std::numeric_limits<double>::epsilon() * std::max(1.0, std::abs(objective)) /
      check.relative_step;
  return check;
}

// ------------------------------------------------- high-energy double pendulums

struct HighEnergyCase {
  const char* scene;
  Vector start;  // [dtheta1, dtheta2, theta1, theta2]
};

Vector Vec4(double a, double b, double c, double d) {
  Vector v(4);
  v << a, b, c, d;
  return v;
}

// The frictionless double pendulum and pendubot (zero torque) at 20-30 rad/s
// joint speeds (energy 5-12 x the potential energy's range of ~10 J): one
// control period matches a converged fine RK4 reference to 1e-8 (tolerance
// 1e-10 per step, errors accumulate over a few hundred steps), and over 10 s
// of chaotic motion the energy drifts by less than 1e-7 of itself.
TEST(SceneStiffPlant, FrictionlessDoublePendulumsAtHighEnergyMeetTolerance) {
  for (const HighEnergyCase& c :
       {HighEnergyCase{"double-pendulum", Vec4(20.0, -25.0, 0.3, 2.0)},
        HighEnergyCase{"pendubot", Vec4(-30.0, 22.0, 2.5, -1.0)}}) {
    const std::unique_ptr<tasks::Plant> plant = tasks::MakePlant(Definition(c.scene));
    const Vector u = Vector::Zero(plant->control_dim());
    ode::IntegrationReport report;
    const double err = StepErrorAgainstReference(*plant, c.start, u, 20000, &report);
    EXPECT_LT(err, 1e-8) << c.scene;
    const int steps = static_cast<int>(std::lround(10.0 / plant->dt()));
    int total = 0;
    const double drift = EnergyDrift(*plant, c.start, steps, &total);
    EXPECT_LT(drift, 1e-7) << c.scene;
    std::printf("  %s: E0 %.4g J; one step: %d accepted, %d rejected, |adaptive - rk4| %.2g; "
                "10 s (%d periods, %d steps): energy drift %.2g\n",
                c.scene, plant->Energy(c.start), report.accepted_steps, report.rejected_steps, err,
                steps, total, drift);
  }
}

// At 1e4 rad/s one period needs thousands of steps; with a budget of 100
// steps the integrator cannot meet its tolerance and says so: ResourceExhausted
// naming the budget, the caller's state untouched.
TEST(SceneStiffPlant, DoublePendulumBeyondTheStepBudgetReportsIt) {
  for (const char* scene : {"double-pendulum", "pendubot"}) {
    ode::IntegratorOptions integrator;
    integrator.max_steps = 100;
    const std::unique_ptr<tasks::Plant> plant = tasks::MakePlant(Definition(scene), integrator);
    const Vector sentinel = Vec4(7, 7, 7, 7);
    Vector next = sentinel;
    ode::IntegrationReport report;
    const absl::Status st = plant->Step(Vec4(1e4, -1e4, 0.3, 2.0),
                                        Vector::Zero(plant->control_dim()), &next, &report);
    EXPECT_EQ(st.code(), absl::StatusCode::kResourceExhausted) << scene << ": " << st;
    EXPECT_NE(st.message().find("step budget"), std::string::npos) << st;
    EXPECT_EQ(next, sentinel) << scene;
    EXPECT_EQ(report.accepted_steps + report.rejected_steps, 100) << scene;
  }
}

// ------------------------------------------- stiff cart-double-pendulums

struct CdpCase {
  const char* name;
  tasks::CartDoublePendulumParams params;
};

std::vector<CdpCase> TinyCartDoublePendulums() {
  std::vector<CdpCase> cases(4);
  cases[0].name = "link masses 1e-4 kg";
  cases[0].params.mass1 = cases[0].params.mass2 = 1e-4;
  cases[1].name = "link lengths 1e-3 m";
  cases[1].params.length1 = cases[1].params.length2 = 1e-3;
  cases[2].name = "cart mass 1e-4 kg";
  cases[2].params.cart_mass = 1e-4;
  cases[3].name = "outer link 1e-4 kg, 1e-3 m";
  cases[3].params.mass2 = 1e-4;
  cases[3].params.length2 = 1e-3;
  return cases;
}

// Tiny masses or lengths make the cart-double-pendulum fast (1 mm links
// swing at ~sqrt(g / l) ~ 100 rad/s and faster in the coupled modes): each
// step still meets the tolerance and matches the converged reference, and
// whole episodes under bang-bang force stay finite.
TEST(SceneStiffPlant, CartDoublePendulumWithTinyMassesOrLengthsMeetsTolerance) {
  Vector x(6);
  x << 0.1, -0.5, 2.0, -3.0, 2.8, 3.4;
  for (const CdpCase& c : TinyCartDoublePendulums()) {
    tasks::SceneDefinition definition = Definition("cart-double-pendulum");
    definition.cart_double_pendulum = c.params;
    const std::unique_ptr<tasks::Plant> plant = tasks::MakePlant(definition);
    ode::IntegrationReport report;
    const double err =
        StepErrorAgainstReference(*plant, x, Vector::Constant(1, 15.0), 40000, &report);
    EXPECT_LT(err, 1e-8) << c.name;
    // 40 periods (2 s) of bang-bang force: finite states throughout.
    Vector z = x;
    int total = 0;
    for (int t = 0; t < 40; ++t) {
      Vector next;
      ode::IntegrationReport r;
      const absl::Status st = plant->Step(z, Vector::Constant(1, t % 2 == 0 ? 20.0 : -20.0), &next, &r);
      ASSERT_TRUE(st.ok()) << c.name << " period " << t << ": " << st;
      ASSERT_TRUE(next.allFinite()) << c.name;
      total += r.accepted_steps;
      z = next;
    }
    std::printf("  %s: one step %d accepted, %d rejected, smallest %.2g s, |adaptive - rk4| %.2g; "
                "40 bang-bang periods: %d steps\n",
                c.name, report.accepted_steps, report.rejected_steps, report.smallest_step, err,
                total);
  }
}

// --------------------------------------- several angles at variance 1e3

// Particles of the pendubot spread with angle variance 1e3 (std 31.6 rad)
// through the two-angle (sin, cos) adapters: every particle method gives a
// finite estimate, and RP's gradient (random numbers held fixed) matches
// central differences of the same objective.
TEST(SceneFeatureExtremes, TwoAnglesAtVariance1e3) {
  estimators::SyntheticProblemOptions synthetic;
  synthetic.scene = "pendubot";
  // PILCO's saturating cost sees the angles through sin/cos: with the angles
  // spread over many turns some particles pass near the target, so the cost
  // is not saturated at 1 (the angle cost would be, with a zero gradient).
  synthetic.cost = "saturating";
  synthetic.data = 60;
  synthetic.basis_functions = 6;
  absl::StatusOr<std::unique_ptr<study::FrozenProblem>> frozen =
      study::FrozenProblemFromSynthetic(synthetic);
  TG_ASSERT_OK(frozen.status());
  ASSERT_EQ((*frozen)->angle_indices, (std::vector<int>{2, 3}));
  estimators::Problem problem = (*frozen)->problem;
  problem.horizon = 5;
  problem.initial_std(2) = problem.initial_std(3) = std::sqrt(1e3);
  estimators::EstimateOptions eo;
  eo.particles = 30;
  for (estimators::Method method : estimators::ParticleMethods()) {
    absl::StatusOr<std::unique_ptr<estimators::Estimator>> e = estimators::MakeEstimator(method, {});
    TG_ASSERT_OK(e.status());
    Rng rng(3, Stream::kStudy, 11);
    estimators::GradientEstimate g;
    const absl::Status st = (*e)->Estimate(problem, eo, &rng, &g);
    ASSERT_TRUE(st.ok()) << estimators::MethodName(method) << ": " << st;
    EXPECT_TRUE(g.finite && g.gradient.allFinite()) << estimators::MethodName(method);
  }
  absl::StatusOr<std::unique_ptr<estimators::Estimator>> rp =
      estimators::MakeEstimator(estimators::Method::kRp, {});
  TG_ASSERT_OK(rp.status());
  // The policy is shared with the problem's adapter: set its parameters for
  // every probe and restore them afterwards.
  policy::RbfPolicy* policy = &(*frozen)->owned_policy->rbf();
  const Vector theta0 = policy->parameters();
  estimators::GradientEstimate at;
  Rng rng0(3, Stream::kStudy, 12);
  TG_ASSERT_OK((*rp)->Estimate(problem, eo, &rng0, &at));
  const diff::VectorFunction objective = [&](const Vector& theta, Vector* out) {
    policy->set_parameters(theta);
    Rng rng(3, Stream::kStudy, 12);
    estimators::GradientEstimate g;
    const bool ok = (*rp)->Estimate(problem, eo, &rng, &g).ok();
    *out = Vector::Constant(1, g.objective);
    return ok;
  };
  const diff::CheckOptions check = FiniteDifferenceCheck(at.objective);
  const diff::CheckResult r = diff::CheckJacobian(objective, theta0, at.gradient.transpose(), check);
  policy->set_parameters(theta0);
  EXPECT_TRUE(r.ok) << r.log;
  EXPECT_GT(at.gradient.norm(), 1e-6) << "the cost is saturated: the check would be empty";
  std::printf("  pendubot, angle variance 1e3: J %.4g, |dJ| %.3g, |dJ|_inf %.2g; FD max rel error "
              "%.2g, max abs error %.2g (absolute floor %.2g); %s\n",
              at.objective, at.gradient.norm(), at.gradient.lpNorm<Eigen::Infinity>(),
              r.max_relative_error, r.max_abs_error, check.absolute_tolerance, r.log.c_str());
}

// The one-angle trig block of PILCO's moment matching (gaussian::AugmentWithTrig)
// applied to each of two angles in turn, at variance 1e3: for independent
// angles the result is the exact joint Gaussian moments of
// [x, sin a1, cos a1, sin a2, cos a2] (checked against the closed form:
// E sin = 0, E cos = e^-500, Var = 1/2, cross-covariances 0), finite,
// symmetric and PSD. For correlated angles the sin/cos cross-covariances
// need the joint moments (e.g. Cov(sin a1, sin a2) = (E cos(a1 - a2) -
// E cos(a1 + a2)) / 2), which the one-angle block does not form: the test
// prints the gap; PILCO's moment matching with several angles uses the
// joint block (next test), not this one.
TEST(SceneFeatureExtremes, OneAngleTrigBlockOnTwoAnglesAtVariance1e3) {
  Vector m(4);
  m << 0.1, -0.2, 0.5, 3.0;
  Matrix s = 0.01 * Matrix::Identity(4, 4);
  s(2, 2) = s(3, 3) = 1e3;
  Vector y1, y2;
  Matrix c1, c2;
  gaussian::AugmentWithTrig(m, s, 2, &y1, &c1);
  gaussian::AugmentWithTrig(y1, c1, 3, &y2, &c2);
  ASSERT_EQ(y2.size(), 8);
  EXPECT_TRUE(y2.allFinite() && c2.allFinite());
  EXPECT_EQ((c2 - c2.transpose()).cwiseAbs().maxCoeff(), 0.0);
  const Eigen::SelfAdjointEigenSolver<Matrix> eig(c2);
  EXPECT_GE(eig.eigenvalues().minCoeff(), -1e-12 * eig.eigenvalues().maxCoeff());
  const double e500 = std::exp(-500.0);
  EXPECT_NEAR(y2(4), e500 * std::sin(0.5), 1e-230);
  EXPECT_NEAR(y2(5), e500 * std::cos(0.5), 1e-230);
  EXPECT_NEAR(y2(6), e500 * std::sin(3.0), 1e-230);
  EXPECT_NEAR(y2(7), e500 * std::cos(3.0), 1e-230);
  for (int k = 4; k < 8; ++k) EXPECT_NEAR(c2(k, k), 0.5, 1e-12) << k;
  // Independent angles: every cross-covariance between the two angles'
  // sin/cos is 0 (exactly, up to e^-500 terms).
  EXPECT_LT(c2.block(4, 6, 2, 2).cwiseAbs().maxCoeff(), 1e-200);
  EXPECT_LT(c2.block(0, 4, 4, 4).cwiseAbs().maxCoeff(), 1e-200);

  // Correlated (rho = 0.9999): the joint moment the one-angle block cannot give.
  s(2, 3) = s(3, 2) = 0.9999e3;
  gaussian::AugmentWithTrig(m, s, 2, &y1, &c1);
  gaussian::AugmentWithTrig(y1, c1, 3, &y2, &c2);
  const double var_diff = s(2, 2) + s(3, 3) - 2 * s(2, 3);
  const double var_sum = s(2, 2) + s(3, 3) + 2 * s(2, 3);
  const double exact_ss = 0.5 * (std::exp(-var_diff / 2) * std::cos(m(2) - m(3)) -
                                 std::exp(-var_sum / 2) * std::cos(m(2) + m(3)));
  EXPECT_TRUE(c2.allFinite());
  std::printf("  correlated angles (rho 0.9999, variance 1e3): Cov(sin a1, sin a2) exact %.4f, "
              "one-angle block in turn %.2g\n",
              exact_ss, c2(4, 6));
}

// PILCO's joint block for several angles (the cart-double-pendulum's and the
// pendubot's) at variance 1e3, correlation 0.9999: finite, symmetric, PSD,
// and the cross moment the one-angle block in turn cannot give is exact:
// Cov(sin a1, sin a2) = (E cos(a1 - a2) - E cos(a1 + a2)) / 2 (E sin a_k is
// e^-500 sin m_k, nothing).
TEST(SceneFeatureExtremes, SeveralAnglesJointBlockAtVariance1e3) {
  Vector m(4);
  m << 0.1, -0.2, 0.5, 3.0;
  Matrix s = 0.01 * Matrix::Identity(4, 4);
  s(2, 2) = s(3, 3) = 1e3;
  s(2, 3) = s(3, 2) = 0.9999e3;
  Vector y;
  Matrix c;
  gaussian::AugmentWithTrig(m, s, std::vector<int>{2, 3}, &y, &c);
  ASSERT_EQ(y.size(), 8);
  EXPECT_TRUE(y.allFinite() && c.allFinite());
  EXPECT_LE((c - c.transpose()).cwiseAbs().maxCoeff(), 1e-15);
  const Eigen::SelfAdjointEigenSolver<Matrix> eig(0.5 * (c + c.transpose()));
  EXPECT_GE(eig.eigenvalues().minCoeff(), -1e-12 * eig.eigenvalues().maxCoeff());
  const double var_diff = s(2, 2) + s(3, 3) - 2 * s(2, 3);
  const double var_sum = s(2, 2) + s(3, 3) + 2 * s(2, 3);
  const double d = m(2) - m(3), t = m(2) + m(3);
  const double e_cos_diff = std::exp(-var_diff / 2) * std::cos(d);
  const double e_cos_sum = std::exp(-var_sum / 2) * std::cos(t);
  EXPECT_NEAR(c(4, 6), 0.5 * (e_cos_diff - e_cos_sum), 1e-12);  // sin a1, sin a2
  EXPECT_NEAR(c(5, 7), 0.5 * (e_cos_diff + e_cos_sum), 1e-12);  // cos a1, cos a2
  for (int k = 4; k < 8; ++k) EXPECT_NEAR(c(k, k), 0.5, 1e-12) << k;
  std::printf("  joint block, rho 0.9999, variance 1e3: Cov(sin a1, sin a2) %.4f (exact %.4f)\n",
              c(4, 6), 0.5 * (e_cos_diff - e_cos_sum));
}

// Several controls saturated at once (the double pendulum's two torques) at
// input variance 1e3, correlation 0.9999: finite, symmetric, PSD, and the
// moments the huge variance makes exact: E[u] = 0, Var[u_j] = max_j^2 41/64
// (sin^2 averages 1/2, sin a sin 3a averages 0), Cov(u1, u2) from the only
// terms that survive, those of a1 - a2 (variance 0.2) and 3 (a1 - a2).
TEST(SceneFeatureExtremes, SeveralControlsSaturatedAtOnceAtVariance1e3) {
  const Vector mean = Eigen::Vector2d(0.3, -2.0);
  Matrix cov(2, 2);
  cov << 1e3, 0.9999e3, 0.9999e3, 1e3;
  const Vector max_u = Eigen::Vector2d(2.0, 3.5);
  pilco::JointSatMoments out;
  pilco::GSatJoint(mean, cov, max_u, &out);
  EXPECT_TRUE(out.mean.allFinite() && out.cov.allFinite() && out.c.allFinite());
  EXPECT_LE((out.cov - out.cov.transpose()).cwiseAbs().maxCoeff(), 1e-15);
  const Eigen::SelfAdjointEigenSolver<Matrix> eig(out.cov);
  EXPECT_GE(eig.eigenvalues().minCoeff(), -1e-12 * eig.eigenvalues().maxCoeff());
  EXPECT_LT(out.mean.cwiseAbs().maxCoeff(), 1e-100);
  EXPECT_LT(out.c.cwiseAbs().maxCoeff(), 1e-100);
  for (int j = 0; j < 2; ++j) {
    EXPECT_NEAR(out.cov(j, j), max_u(j) * max_u(j) * 41.0 / 64.0, 1e-12) << j;
  }
  const double var_diff = cov(0, 0) + cov(1, 1) - 2 * cov(0, 1);  // 0.2
  const double d = mean(0) - mean(1);
  const double cross = max_u(0) * max_u(1) / 64.0 *
                       (81.0 * std::exp(-var_diff / 2) * std::cos(d) +
                        std::exp(-9.0 * var_diff / 2) * std::cos(3.0 * d)) / 2.0;
  EXPECT_NEAR(out.cov(0, 1), cross, 1e-12);
}

// ------------------------------------------------------- no angle at all

// A scene with no angle (the cart-double-pendulum with its angle set
// emptied, as a scene whose state has no angle would be): the GP and the
// policy see the raw state, no (sin, cos) adapter is built, and RP's
// gradient matches central differences. (PILCO's row of a study on such a
// scene runs with angle index -1: tests/core/study/study_test.cc,
// SceneSynthetic.SceneWithoutAnglesBuildsNoTrigAdapter.)
TEST(SceneFeatureExtremes, SceneWithNoAngle) {
  tasks::SceneOptions scene_options;
  scene_options.scene = "cart-double-pendulum";
  absl::StatusOr<tasks::Scene> scene = tasks::MakeScene(scene_options);
  TG_ASSERT_OK(scene.status());
  scene->angle_indices.clear();
  // Start at the target so the angle cost is not saturated at 1 (a zero
  // gradient would make the comparison empty).
  scene->mu0 = scene->target;
  study::SceneSyntheticOptions options;
  options.data = 60;
  options.horizon = 4;
  options.basis_functions = 6;
  absl::StatusOr<std::unique_ptr<study::FrozenProblem>> frozen =
      study::FrozenProblemFromScene(*scene, options);
  TG_ASSERT_OK(frozen.status());
  const estimators::Problem& problem = (*frozen)->problem;
  EXPECT_TRUE((*frozen)->angle_indices.empty());
  EXPECT_EQ(dynamic_cast<const estimators::AngleFeatureDynamics*>(problem.dynamics), nullptr);
  EXPECT_EQ(dynamic_cast<const estimators::AngleFeaturePolicy*>(problem.policy), nullptr);
  EXPECT_EQ((*frozen)->model->num_inputs(), 6 + 1);

  absl::StatusOr<std::unique_ptr<estimators::Estimator>> rp =
      estimators::MakeEstimator(estimators::Method::kRp, {});
  TG_ASSERT_OK(rp.status());
  estimators::EstimateOptions eo;
  eo.particles = 20;
  policy::RbfPolicy* policy = &(*frozen)->owned_policy->rbf();
  const Vector theta0 = policy->parameters();
  estimators::GradientEstimate at;
  Rng rng0(4, Stream::kStudy, 1);
  TG_ASSERT_OK((*rp)->Estimate(problem, eo, &rng0, &at));
  ASSERT_TRUE(at.finite);
  const diff::VectorFunction objective = [&](const Vector& theta, Vector* out) {
    policy->set_parameters(theta);
    Rng rng(4, Stream::kStudy, 1);
    estimators::GradientEstimate g;
    const bool ok = (*rp)->Estimate(problem, eo, &rng, &g).ok();
    *out = Vector::Constant(1, g.objective);
    return ok;
  };
  const diff::CheckOptions check = FiniteDifferenceCheck(at.objective);
  const diff::CheckResult r = diff::CheckJacobian(objective, theta0, at.gradient.transpose(), check);
  policy->set_parameters(theta0);
  EXPECT_TRUE(r.ok) << r.log;
  EXPECT_GT(at.gradient.norm(), 1e-6) << "the cost is saturated: the check would be empty";
  std::printf("  no angle: J %.4g, |dJ| %.3g, FD max rel error %.2g, max abs error %.2g "
              "(absolute floor %.2g)\n",
              at.objective, at.gradient.norm(), r.max_relative_error, r.max_abs_error,
              check.absolute_tolerance);
}

}  // namespace scenes_test
}  // namespace totalgrad
