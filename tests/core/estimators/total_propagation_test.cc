// Total propagation and the composed methods: the combination rule and its
// limits, TP's exact reduction to RP and LR, per-particle gradients of every
// method, GTP+sn's model, configuration errors.
#include "core/estimators/total_propagation.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "core/estimators/gaussian_resampling.h"
#include "core/estimators/rp.h"
#include "core/estimators/synthetic_problem.h"
#include "tests/core/estimators/linear_gaussian.h"

namespace totalgrad::estimators {
namespace total_propagation_test {

constexpr double kInf = std::numeric_limits<double>::infinity();
const double kNaN = std::nan("");

std::unique_ptr<SyntheticProblem> SmallProblem(int horizon, const std::string& cost = "angle") {
  SyntheticProblemOptions o;
  o.data = 40;
  o.horizon = horizon;
  o.basis_functions = 10;
  o.cost = cost;
  o.seed = 3;
  auto p = MakeSyntheticProblem(o);
  EXPECT_TRUE(p.ok()) << p.status();
  return *std::move(p);
}

std::unique_ptr<Estimator> MakeByName(const std::string& name, const EstimatorOptions& options) {
  absl::StatusOr<Method> method = ParseMethod(name);
  EXPECT_TRUE(method.ok()) << method.status();
  auto e = MakeEstimator(*method, options);
  EXPECT_TRUE(e.ok()) << e.status();
  return e.ok() ? *std::move(e) : nullptr;
}

GradientEstimate RunMethod(const std::string& method, const EstimatorOptions& options, const Problem& problem,
                     int particles, uint64_t seed) {
  absl::StatusOr<std::unique_ptr<Estimator>> e = MakeByName(method, options);
  EXPECT_TRUE(e.ok()) << e.status();
  Rng rng(seed, Stream::kParticleNoise);
  EstimateOptions eo;
  eo.particles = particles;
  eo.keep_per_particle = true;
  GradientEstimate estimate;
  const absl::Status st = (*e)->Estimate(problem, eo, &rng, &estimate);
  EXPECT_TRUE(st.ok()) << method << ": " << st;
  return estimate;
}

TEST(CombinationWeight, IsInverseVarianceWeighting) {
  EXPECT_DOUBLE_EQ(CombinationWeight(1.0, 1.0), 0.5);
  EXPECT_DOUBLE_EQ(CombinationWeight(1.0, 3.0), 0.25);  // 1 / (1 + 3)
  EXPECT_DOUBLE_EQ(CombinationWeight(3.0, 1.0), 0.75);
  EXPECT_NEAR(CombinationWeight(1e-300, 1e300), 0.0, 1e-300);
  EXPECT_NEAR(CombinationWeight(1e300, 1e-300), 1.0, 1e-15);
}

TEST(CombinationWeight, GuardedLimitsNeverNaN) {
  EXPECT_EQ(CombinationWeight(kInf, 1.0), 1.0);   // RP exploded: all LR
  EXPECT_EQ(CombinationWeight(1.0, kInf), 0.0);   // LR exploded: all RP
  EXPECT_EQ(CombinationWeight(kNaN, 1.0), 1.0);   // a NaN branch counts as exploded
  EXPECT_EQ(CombinationWeight(1.0, kNaN), 0.0);
  EXPECT_EQ(CombinationWeight(kInf, kInf), 0.5);
  EXPECT_EQ(CombinationWeight(kNaN, kNaN), 0.5);
  EXPECT_EQ(CombinationWeight(0.0, 0.0), 0.5);    // both exact: any mix
  EXPECT_EQ(CombinationWeight(0.0, 1.0), 0.0);    // RP exact: all RP
  EXPECT_EQ(CombinationWeight(1.0, 0.0), 1.0);
  EXPECT_LT(CombinationWeight(4.9e-324, 1.0), 1e-300);  // a denormal variance is not zero
  EXPECT_GT(CombinationWeight(4.9e-324, 0.0), 0.99);
  for (double a : {0.0, 1e-320, 1e-10, 1.0, 1e10, 1e308, kInf, kNaN})
    for (double b : {0.0, 1e-320, 1e-10, 1.0, 1e10, 1e308, kInf, kNaN}) {
      const double k = CombinationWeight(a, b);
      EXPECT_TRUE(k >= 0.0 && k <= 1.0) << a << " " << b << " -> " << k;
    }
}

// Rows whose squares overflow still give the right ratio.
TEST(RowTraceVariance, SurvivesHugeRows) {
  RowMatrix small(3, 2), huge(3, 2);
  small << 1, 2, 3, 4, 5, 9;
  huge = 1e200 * small;
  const TraceVariance vs = RowTraceVariance(small), vh = RowTraceVariance(huge);
  EXPECT_FALSE(vh.non_finite);
  EXPECT_EQ(vh.value(), kInf);  // the variance itself overflows...
  // ...but the weight is the ratio: equal rows up to 1e200 give k = 1/(1 + 1e400).
  EXPECT_EQ(CombinationWeight(vs, vh), 0.0);
  EXPECT_DOUBLE_EQ(CombinationWeight(vh, vh), 0.5);
  const RowMatrix mid = 1e150 * small;
  EXPECT_NEAR(CombinationWeight(vh, RowTraceVariance(mid)), 1.0, 1e-90);
  RowMatrix bad = small;
  bad(1, 1) = kNaN;
  EXPECT_TRUE(RowTraceVariance(bad).non_finite);
  EXPECT_EQ(CombinationWeight(RowTraceVariance(bad), vs), 1.0);
  EXPECT_TRUE(RowTraceVariance(small.topRows(1)).zero());
}

// Both branches' trace variances in shared passes are the single-branch
// function's, bit for bit: vector lanes and tails (n = 23), scaled rows, one
// branch constant (zero spread), a NaN in one factor, one particle, rows of
// 1e200. A changed order of any sum or a dropped special case fails it.
TEST(ScaledRowTraceVariances, AreEachBranchsOwnBitForBit) {
  Rng rng(7, Stream::kParticleNoise);
  const auto random = [&](Eigen::Index rows, Eigen::Index cols) {
    RowMatrix m(rows, cols);
    for (Eigen::Index i = 0; i < rows; ++i)
      for (Eigen::Index j = 0; j < cols; ++j) m(i, j) = rng.Normal();
    return m;
  };
  const auto expect_same = [](const TraceVariance& x, const TraceVariance& y) {
    EXPECT_EQ(x.non_finite, y.non_finite);
    EXPECT_TRUE(x.scale == y.scale || (std::isnan(x.scale) && std::isnan(y.scale)));
    EXPECT_TRUE(x.normalized == y.normalized ||
                (std::isnan(x.normalized) && std::isnan(y.normalized)));
  };
  const RowMatrix rows = random(37, 23);
  const Vector fa = random(37, 1).col(0), fb = 3.0 * random(37, 1).col(0);
  Vector constant = Vector::Zero(37);
  Vector with_nan = fb;
  with_nan(5) = kNaN;
  const RowMatrix huge = 1e200 * rows;
  struct Case {
    const char* name;
    const Vector* a;
    const Vector* b;
    const RowMatrix* m;
  };
  for (const Case& c : {Case{"random", &fa, &fb, &rows}, Case{"zero spread", &fa, &constant, &rows},
                        Case{"zero spread first", &constant, &fb, &rows},
                        Case{"nan", &fa, &with_nan, &rows}, Case{"huge", &fa, &fb, &huge}}) {
    SCOPED_TRACE(c.name);
    Vector scratch, scratch_a, scratch_b;
    TraceVariance a, b;
    ScaledRowTraceVariances(*c.a, *c.b, *c.m, &scratch_a, &scratch_b, &a, &b);
    expect_same(a, ScaledRowTraceVariance(*c.a, *c.m, &scratch));
    expect_same(b, ScaledRowTraceVariance(*c.b, *c.m, &scratch));
    // The cases are what they say: a constant factor has no spread.
    EXPECT_EQ(a.scale > 0, c.a != &constant);
    EXPECT_EQ(b.scale > 0 || b.non_finite, c.b != &constant);
  }
  TraceVariance a, b;
  Vector scratch, scratch_a, scratch_b;
  const RowMatrix one = rows.topRows(1);
  ScaledRowTraceVariances(fa.head(1), fb.head(1), one, &scratch_a, &scratch_b, &a, &b);
  expect_same(a, ScaledRowTraceVariance(fa.head(1), one, &scratch));
  EXPECT_TRUE(a.zero());
}

// TP with k_LR forced to 0 is RP, forced to 1 is LR: the same numbers, bit
// for bit, from the same random numbers (RP's dedicated pass is the reference).
TEST(TotalPropagation, ForcedWeightsReproduceRpAndLr) {
  auto sp = SmallProblem(8);
  for (const std::string cost : {"angle", "tip"}) {
    auto spc = SmallProblem(8, cost);
    const Problem& problem = spc->problem;
    EstimatorOptions k0, k1;
    k0.forced_k_lr = 0.0;
    k1.forced_k_lr = 1.0;
    const GradientEstimate rp = RunMethod("RP", {}, problem, 9, 1);
    const GradientEstimate tp0 = RunMethod("TP", k0, problem, 9, 1);
    EXPECT_EQ(tp0.gradient, rp.gradient) << cost;
    EXPECT_EQ(tp0.per_particle, rp.per_particle) << cost;
    for (const LrWeights w : {LrWeights::kBatchImportance, LrWeights::kPlain}) {
      EstimatorOptions lr_options, tp_options = k1;
      lr_options.lr_weights = tp_options.lr_weights = w;
      const GradientEstimate lr = RunMethod("LR", lr_options, problem, 9, 1);
      const GradientEstimate tp1 = RunMethod("TP", tp_options, problem, 9, 1);
      EXPECT_EQ(tp1.gradient, lr.gradient) << cost;
      EXPECT_EQ(tp1.per_particle, lr.per_particle) << cost;
      EXPECT_NE(lr.gradient, rp.gradient);
    }
    // The same for the shaped pair: GTP at k = 1 is GLR.
    EstimatorOptions g1 = k1;
    g1.gs_derivative = GsDerivative::kExact;
    EstimatorOptions glr_options;
    glr_options.gs_derivative = GsDerivative::kExact;
    EXPECT_EQ(RunMethod("GTP", g1, problem, 9, 1).gradient, RunMethod("GLR", glr_options, problem, 9, 1).gradient);
  }
}

// The adaptive weights stay in [0, 1] at every step and the estimates stay
// finite, down to P = 2, over a 30-step horizon.
TEST(TotalPropagation, WeightsStayInTheUnitInterval) {
  auto sp = SmallProblem(30);
  for (const std::string method : {"TP", "GTP", "GTP+sn"}) {
    for (int particles : {2, 3, 20}) {
      for (uint64_t seed = 1; seed <= 3; ++seed) {
        const GradientEstimate e = RunMethod(method, {}, sp->problem, particles, seed);
        ASSERT_EQ(e.k_lr.size(), 30u);
        for (double k : e.k_lr) EXPECT_TRUE(k >= 0.0 && k <= 1.0) << method << " k " << k;
        EXPECT_TRUE(e.finite) << method << " P " << particles;
      }
    }
  }
  // With P = 20 over 30 steps both branches matter somewhere.
  const GradientEstimate e = RunMethod("TP", {}, sp->problem, 20, 4);
  double lo = 1, hi = 0;
  for (double k : e.k_lr) lo = std::min(lo, k), hi = std::max(hi, k);
  EXPECT_LT(lo, hi);
}

// Every method: per-particle gradients average to the gradient, and their
// variance is the sample variance of those rows.
TEST(AllMethods, PerParticleGradientsAverageToTheEstimate) {
  auto sp = SmallProblem(6);
  for (const std::string& method : ParticleMethodNames()) {
    const GradientEstimate e = RunMethod(method, {}, sp->problem, 7, 2);
    ASSERT_TRUE(e.finite) << method;
    ASSERT_EQ(e.per_particle.rows(), 7) << method;
    const Vector mean = e.per_particle.colwise().mean().transpose();
    EXPECT_LT((mean - e.gradient).cwiseAbs().maxCoeff(), 1e-12 * (1 + e.gradient.cwiseAbs().maxCoeff()))
        << method;
    EXPECT_LT((ColumnSampleVariance(e.per_particle) - e.per_particle_variance).cwiseAbs().maxCoeff(), 1e-12)
        << method;
    EXPECT_GT(e.gradient.norm(), 0) << method;
    EXPECT_GT(e.per_particle_variance.sum(), 0) << method;
  }
}

// GTP+sn is GTP on the model with the noise variance x25; the caller's problem
// is not modified (the trial's predicted cost uses it afterwards).
TEST(GtpSn, IsGtpWithTheNoiseVarianceTimes25) {
  auto sp = SmallProblem(6);
  Problem noisy = sp->problem;
  noisy.noise_variance_multiplier = 25.0;
  const GradientEstimate sn = RunMethod("GTP+sn", {}, sp->problem, 8, 3);
  const GradientEstimate gtp = RunMethod("GTP", {}, noisy, 8, 3);
  EXPECT_EQ(sn.gradient, gtp.gradient);
  EXPECT_EQ(sp->problem.noise_variance_multiplier, 1.0);
  EXPECT_NE(RunMethod("GTP", {}, sp->problem, 8, 3).gradient, sn.gradient);
}

TEST(BackwardPass, ConfigurationErrors) {
  auto sp = SmallProblem(3);
  Rng rng(1, Stream::kParticleNoise);
  Rollout plain;
  ASSERT_TRUE(SimulateParticles(sp->problem, 4, {}, &rng, &plain).ok());
  BackwardResult result;
  BackwardConfig config;
  EXPECT_EQ(BackwardPass(sp->problem, plain, config, &rng, &result).code(),
            absl::StatusCode::kInvalidArgument)
      << "a rollout without Jacobians";
  RolloutRecording rec;
  rec.jacobians = true;
  Rollout recorded;
  ASSERT_TRUE(SimulateParticles(sp->problem, 4, rec, &rng, &recorded).ok());
  config.pathwise = false;
  EXPECT_EQ(BackwardPass(sp->problem, recorded, config, &rng, &result).code(),
            absl::StatusCode::kInvalidArgument)
      << "no branch";
  GaussianResampler resampler;
  config.pathwise = true;
  config.jump = JumpKind::kLikelihoodRatio;
  config.resampler = &resampler;
  EXPECT_EQ(BackwardPass(sp->problem, recorded, config, &rng, &result).code(),
            absl::StatusCode::kInvalidArgument)
      << "resampling with a jump";
  config.jump = JumpKind::kNone;
  EXPECT_EQ(BackwardPass(sp->problem, recorded, config, &rng, &result).code(),
            absl::StatusCode::kInvalidArgument)
      << "resampler without a resampled rollout";
  EstimatorOptions bad;
  bad.sn_noise_multiplier = -1;
  EXPECT_FALSE(MakeEstimator(Method::kGtpSn, bad).ok());
}

// A rollout that overflows (an explosive linear system) is a non-finite
// estimate for the caller to skip, never an error or a crash, for every method
// and option (exact shaping derivatives of a non-finite fit included).
TEST(AllMethods, OverflowingRolloutIsANonFiniteEstimateNotAnError) {
  const Matrix a = 1e80 * Matrix::Identity(4, 4);
  testing::LinearDynamics dynamics(a, Vector::Constant(4, 1.0), Vector::Zero(4), Vector::Constant(4, 0.01));
  testing::LinearPolicy policy(Vector::Constant(5, 0.1));
  tasks::State target, q;
  target << 0, M_PI, 0, 0;
  q << 1, 1, 0, 0;
  tasks::AngleCost cost(target, q);
  Problem problem;
  problem.dynamics = &dynamics;
  problem.policy = &policy;
  problem.cost = &cost;
  problem.mu0 = Vector::Constant(4, 0.1);
  problem.initial_std = Vector::Constant(4, 0.1);
  problem.horizon = 8;
  for (const std::string& method : ParticleMethodNames()) {
    for (const GsDerivative d : {GsDerivative::kSampled, GsDerivative::kExact}) {
      EstimatorOptions options;
      options.gs_derivative = d;
      absl::StatusOr<std::unique_ptr<Estimator>> e = MakeByName(method, options);
      ASSERT_TRUE(e.ok() && *e != nullptr);
      Rng rng(1, Stream::kParticleNoise);
      EstimateOptions eo;
      eo.particles = 5;
      GradientEstimate estimate;
      const absl::Status st = (*e)->Estimate(problem, eo, &rng, &estimate);
      EXPECT_TRUE(st.ok()) << method << ": " << st;
      EXPECT_FALSE(estimate.finite) << method;
      for (double k : estimate.k_lr) EXPECT_TRUE(k >= 0.0 && k <= 1.0) << method;
    }
  }
}

TEST(Registry, EveryMethodByName) {
  const std::vector<std::string> expected = {"RP", "GR", "LR", "TP", "GLR", "GTP", "GTP+sn", "DEL"};
  EXPECT_EQ(ParticleMethodNames(), expected);
  for (const std::string& m : expected) {
    absl::StatusOr<Method> method = ParseMethod(m);
    ASSERT_TRUE(method.ok()) << m;
    auto e = MakeEstimator(*method, {});
    ASSERT_TRUE(e.ok()) << m;
    EXPECT_EQ((*e)->Name(), m);
  }
  LrBaseline b;
  EXPECT_TRUE(ParseLrBaseline("biw_pair", &b).ok());
  EXPECT_EQ(LrBaselineName(b), "biw_pair");
  EXPECT_FALSE(ParseLrBaseline("x", &b).ok());
  GsDerivative d;
  EXPECT_TRUE(ParseGsDerivative("exact", &d).ok());
  EXPECT_EQ(GsDerivativeName(d), "exact");
  LrWeights w;
  EXPECT_TRUE(ParseLrWeights("plain", &w).ok());
  EXPECT_EQ(LrWeightsName(w), "plain");
}

}  // namespace total_propagation_test
}  // namespace totalgrad::estimators
