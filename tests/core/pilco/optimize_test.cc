// PILCO's BFGS (minimize) and the top-level policy-search API.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/common/rng.h"
#include "core/gaussian/angle_features.h"
#include "core/pilco/bfgs.h"
#include "core/gp/gp.h"
#include "core/pilco/pilco.h"
#include "core/tasks/cartpole.h"
#include "tests/core/pilco/pilco_test_util.h"
#include "tests/testutil/testutil.h"

namespace totalgrad::pilco {
namespace optimize_test {

bool Rosenbrock(const Vector& x, double* f, Vector* g) {
  const int n = static_cast<int>(x.size());
  *f = 0;
  g->setZero(n);
  for (int i = 0; i + 1 < n; ++i) {
    const double a = x(i + 1) - x(i) * x(i), b = 1 - x(i);
    *f += 100 * a * a + b * b;
    (*g)(i) += -400 * a * x(i) - 2 * b;
    (*g)(i + 1) += 200 * a;
  }
  return true;
}

TEST(BfgsTest, MinimisesRosenbrockWithinTheBudget) {
  Vector x = Vector::Constant(6, -1.2);
  BfgsOptions o;
  const BfgsSummary s = MinimizeBfgs(Rosenbrock, o, &x);
  EXPECT_LT(s.final_value, 1e-8) << s.BriefReport();
  EXPECT_TRUE(x.isApprox(Vector::Ones(6), 1e-3)) << x.transpose();
  EXPECT_LE(s.line_searches, 150);
  EXPECT_LE(s.evaluations, 1 + 150 * 30);
  // History never increases (RHO = 0: non-increase).
  for (size_t i = 1; i < s.history.size(); ++i) EXPECT_LE(s.history[i], s.history[i - 1]);
}

TEST(BfgsTest, RespectsTheLineSearchBudget) {
  Vector x = Vector::Constant(10, -1.2);
  BfgsOptions o;
  o.max_line_searches = 7;
  o.max_evaluations_per_line_search = 3;
  const BfgsSummary s = MinimizeBfgs(Rosenbrock, o, &x);
  EXPECT_LE(s.line_searches, 7);
  EXPECT_LE(s.evaluations, 1 + s.line_searches * 3);
  EXPECT_LT(s.final_value, s.initial_value);
}

TEST(BfgsTest, WrongGradientStopsAfterTwoFailedLineSearches) {
  // The "gradient" points uphill: no line search can succeed.
  const Objective bad = [](const Vector& x, double* f, Vector* g) {
    *f = x.squaredNorm();
    *g = -2 * x;
    return true;
  };
  Vector x = Vector::Constant(3, 1.0);
  const BfgsSummary s = MinimizeBfgs(bad, BfgsOptions(), &x);
  EXPECT_EQ(s.termination, BfgsSummary::Termination::kTwoFailedLineSearches) << s.BriefReport();
  EXPECT_EQ(s.line_searches, 2);
  EXPECT_LE(s.final_value, s.initial_value);
}

TEST(BfgsTest, FailedEvaluationsAreSteppedAround) {
  // f undefined for |x| > 2: the line search halves back.
  const Objective partial = [](const Vector& x, double* f, Vector* g) {
    if (x.cwiseAbs().maxCoeff() > 2.0) return false;
    *f = (x.array() - 1.5).square().sum();
    *g = 2 * (x.array() - 1.5).matrix();
    return true;
  };
  Vector x = Vector::Constant(2, -1.0);
  const BfgsSummary s = MinimizeBfgs(partial, BfgsOptions(), &x);
  EXPECT_LT(s.final_value, 1e-10) << s.BriefReport();
  const Objective never = [](const Vector&, double*, Vector*) { return false; };
  x = Vector::Zero(2);
  EXPECT_EQ(MinimizeBfgs(never, BfgsOptions(), &x).termination,
            BfgsSummary::Termination::kInitialEvaluationFailed);
}

TEST(BfgsTest, CancellationIsPolled) {
  Vector x = Vector::Constant(4, -1.2);
  BfgsOptions o;
  int polls = 0;
  o.should_stop = [&] { return ++polls > 3; };
  const BfgsSummary s = MinimizeBfgs(Rosenbrock, o, &x);
  EXPECT_EQ(s.termination, BfgsSummary::Termination::kCancelled);
  EXPECT_EQ(s.line_searches, 3);
}

// ------------------------------------------------------------ top-level API

GaussianInputGp CartPoleGp(int n, int angle_index, uint64_t seed, double beta_centre = 0.0) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> uniform(-10, 10);
  const tasks::CartPole plant;
  RowMatrix states(n, 4), y(n, 4);
  Vector u(n);
  for (int i = 0; i < n; ++i) {
    tasks::State s(0.3 * normal(rng), beta_centre + 0.5 * normal(rng), 0.5 * normal(rng),
                   1.0 * normal(rng));
    u(i) = uniform(rng);
    tasks::State next;
    EXPECT_TRUE(plant.Step(s, u(i), &next).ok());
    states.row(i) = s.transpose();
    y.row(i) = (next - s).transpose();
  }
  RowMatrix features;
  gaussian::StatesToFeatures(states, angle_index, &features);
  RowMatrix x(n, features.cols() + 1);
  x << features, u;
  RowMatrix log_hyp(4, x.cols() + 2);
  for (int a = 0; a < 4; ++a) {
    for (int j = 0; j < x.cols(); ++j) {
      const double m = x.col(j).mean();
      log_hyp(a, j) = std::log(std::sqrt((x.col(j).array() - m).square().sum() / (n - 1)));
    }
    const double m = y.col(a).mean();
    const double sd = std::sqrt((y.col(a).array() - m).square().sum() / (n - 1));
    log_hyp(a, x.cols()) = std::log(sd);
    log_hyp(a, x.cols() + 1) = std::log(sd / 10);
  }
  auto gp = GaussianInputGpFromData(x, y, log_hyp);
  EXPECT_TRUE(gp.ok()) << gp.status();
  return *gp;
}

PilcoProblem SwingUpProblem(int angle_index) {
  PilcoProblem p;
  p.mu0 = Vector::Zero(4);
  p.S0 = 0.01 * Matrix::Identity(4, 4);
  p.horizon = 15;
  p.cost = std::make_shared<gaussian::GaussianCost>(*gaussian::GaussianCost::Tip(4, 0, 1, 0.5, 0.25));
  p.propagation.angle_index = angle_index;
  p.propagation.num_basis = 5;
  return p;
}

TEST(PilcoApiTest, InitialPolicyFollowsPilco) {
  const PilcoProblem problem = SwingUpProblem(1);
  Rng rng(7, Stream::kPolicyInit);
  absl::StatusOr<Vector> params = InitialPolicyParameters(problem, &rng);
  TG_ASSERT_OK(params.status());
  ASSERT_EQ(params->size(), 5 * 5 + 5 + 5);
  const Eigen::Map<const RowMatrix> centres(params->data(), 5, 5);
  // Centres near the start features [0, 0, 0, sin 0, cos 0].
  EXPECT_LT(centres.leftCols(4).cwiseAbs().maxCoeff(), 0.6);
  EXPECT_GT(centres.col(4).minCoeff(), 0.9);
  EXPECT_NEAR((*params)(25 + 3), std::log(0.7), 1e-15);
  EXPECT_EQ((*params)(25), 0.0);
}

// Balancing from upright: the cost is informative, so a few line searches
// must reduce J clearly.
TEST(PilcoApiTest, OptimizePolicyReducesJAndReportsThePrediction) {
  for (const int angle : {1, -1}) {
    const GaussianInputGp gp = CartPoleGp(60, angle, 41, M_PI);
    PilcoProblem problem = SwingUpProblem(angle);
    problem.mu0(1) = M_PI;
    Rng rng(3, Stream::kPolicyInit);
    absl::StatusOr<Vector> params = InitialPolicyParameters(problem, &rng);
    TG_ASSERT_OK(params.status());
    absl::StatusOr<Trajectory> before = Propagate(gp, problem, *params);
    TG_ASSERT_OK(before.status());
    PilcoOptions options;
    options.bfgs.max_line_searches = 20;
    absl::StatusOr<PilcoResult> result = OptimizePolicy(gp, problem, options, &*params);
    TG_ASSERT_OK(result.status());
    EXPECT_LT(result->prediction.total_cost, before->total_cost - 0.1) << result->BriefReport();
    EXPECT_EQ(result->prediction.means.size(), 16u);
    EXPECT_EQ(result->prediction.cost_std.size(), 15);
    EXPECT_LE(result->optimizer.line_searches, 20);
    absl::StatusOr<Trajectory> after = Propagate(gp, problem, *params);
    TG_ASSERT_OK(after.status());
    EXPECT_DOUBLE_EQ(after->total_cost, result->prediction.total_cost);
    EXPECT_DOUBLE_EQ(after->total_cost, result->optimizer.final_value);
  }
}

TEST(PilcoApiTest, InconsistentProblemIsNamed) {
  const GaussianInputGp gp = CartPoleGp(30, 1, 42);
  PilcoProblem problem = SwingUpProblem(-1);  // GP expects sin/cos features
  Vector params = Vector::Zero(5 * 4 + 4 + 5);
  absl::StatusOr<Trajectory> tr = Propagate(gp, problem, params);
  EXPECT_EQ(tr.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(tr.status().message().find("inputs"), std::string::npos) << tr.status();
  problem = SwingUpProblem(1);
  problem.cost = nullptr;
  EXPECT_EQ(Propagate(gp, problem, params).status().code(), absl::StatusCode::kInvalidArgument);
}

// The trial runner hands PILCO a trained GpModel: the conversion must give the
// same predictor as building it from the data and hyperparameters.
TEST(PilcoApiTest, GpModelConversionMatchesFromData) {
  const GaussianInputGp ref = CartPoleGp(40, 1, 43);
  gp::GpHyperparameters hyp;
  hyp.log_lengthscales = (-0.5 * ref.inv_lengthscale_sq.array().log()).matrix();
  hyp.log_signal_std = (0.5 * ref.signal_var.array().log()).matrix();
  hyp.log_noise_std = (0.5 * ref.noise_var.array().log()).matrix();
  // The targets are recovered as y = (K + sn^2 I) beta.
  RowMatrix targets(40, 4);
  for (int a = 0; a < 4; ++a) {
    targets.col(a) = ref.variance_weights[a].ldlt().solve(ref.beta.col(a));
  }
  auto model = gp::GpModel::Create(ref.inputs, targets, hyp);
  TG_ASSERT_OK(model.status());
  const GaussianInputGp conv = GaussianInputGpFromModel(*model);
  for (int a = 0; a < 4; ++a) EXPECT_EQ(model->jitter(a), 0.0);
  EXPECT_TRUE(::totalgrad::testing::MatricesNear(conv.beta, ref.beta, 1e-8, 1e-6));
  EXPECT_TRUE(::totalgrad::testing::MatricesNear(conv.inv_lengthscale_sq, ref.inv_lengthscale_sq,
                                                 0, 1e-14));
  PilcoProblem problem = SwingUpProblem(1);
  Rng prng(5, Stream::kPolicyInit);
  const Vector params = *InitialPolicyParameters(problem, &prng);
  auto a = Propagate(conv, problem, params);
  auto b = Propagate(ref, problem, params);
  TG_ASSERT_OK(a.status());
  TG_ASSERT_OK(b.status());
  EXPECT_NEAR(a->total_cost, b->total_cost, 1e-8);
}

TEST(PilcoApiTest, BuildDynamicsModelSwitchesToFitcAboveM) {
  const GaussianInputGp ref = CartPoleGp(40, 1, 44);
  gp::GpHyperparameters hyp;
  hyp.log_lengthscales = (-0.5 * ref.inv_lengthscale_sq.array().log()).matrix();
  hyp.log_signal_std = (0.5 * ref.signal_var.array().log()).matrix();
  hyp.log_noise_std = (0.5 * ref.noise_var.array().log()).matrix();
  RowMatrix targets(40, 4);
  for (int a = 0; a < 4; ++a) {
    targets.col(a) = ref.variance_weights[a].ldlt().solve(ref.beta.col(a));
  }
  DynamicsModelOptions options;
  options.num_inducing = 40;
  RowMatrix z;
  Rng rng(1, Stream::kGpInit);
  DynamicsModelReport report;
  auto full = BuildDynamicsModel(ref.inputs, targets, hyp, options, &z, &rng, &report);
  TG_ASSERT_OK(full.status());
  EXPECT_FALSE(report.sparse);
  EXPECT_EQ(full->num_points(), 40);
  options.num_inducing = 15;
  options.first_fit_iterations = 10;
  auto sparse = BuildDynamicsModel(ref.inputs, targets, hyp, options, &z, &rng, &report);
  TG_ASSERT_OK(sparse.status());
  EXPECT_TRUE(report.sparse);
  EXPECT_EQ(sparse->num_points(), 15);
  EXPECT_EQ(z.rows(), 15);
  EXPECT_LE(report.fitc.final_nlml, report.fitc.initial_nlml) << report.BriefReport();
  // Warm start keeps Z's size and improves further (or stays).
  const double first = report.fitc.final_nlml;
  auto again = BuildDynamicsModel(ref.inputs, targets, hyp, options, &z, &rng, &report);
  TG_ASSERT_OK(again.status());
  EXPECT_NEAR(report.fitc.initial_nlml, first, 1e-9 * std::abs(first));
}

TEST(AngleFeaturesTest, MapAndChainRule) {
  RowMatrix states(2, 4);
  states << 0.1, 0.2, 0.3, 0.4, -1, 3.0, 2, 1;
  RowMatrix f;
  gaussian::StatesToFeatures(states, 1, &f);
  ASSERT_EQ(f.cols(), 5);
  EXPECT_DOUBLE_EQ(f(0, 0), 0.1);
  EXPECT_DOUBLE_EQ(f(0, 1), 0.3);
  EXPECT_DOUBLE_EQ(f(0, 2), 0.4);
  EXPECT_DOUBLE_EQ(f(1, 3), std::sin(3.0));
  EXPECT_DOUBLE_EQ(f(1, 4), std::cos(3.0));
  RowMatrix fb = RowMatrix::Ones(2, 5), sb;
  gaussian::StatesToFeaturesBackward(states, 1, fb, &sb);
  EXPECT_DOUBLE_EQ(sb(1, 1), std::cos(3.0) - std::sin(3.0));
  EXPECT_DOUBLE_EQ(sb(1, 0), 1.0);
  gaussian::StatesToFeatures(states, -1, &f);
  EXPECT_TRUE(f.isApprox(states));
}

}  // namespace optimize_test
}  // namespace totalgrad::pilco
