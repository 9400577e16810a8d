// LR pieces: transition log-densities, batch importance weights, the BIW
// baselines, and the LR cotangents.
#include "core/estimators/likelihood_ratio.h"

#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "core/estimators/estimator.h"
#include "core/estimators/synthetic_problem.h"

namespace totalgrad::estimators {
namespace likelihood_ratio_test {

std::unique_ptr<SyntheticProblem> SmallProblem(int horizon) {
  SyntheticProblemOptions o;
  o.data = 40;
  o.horizon = horizon;
  o.basis_functions = 10;
  o.seed = 3;
  auto p = MakeSyntheticProblem(o);
  EXPECT_TRUE(p.ok()) << p.status();
  return *std::move(p);
}

Rollout Record(const Problem& problem, int particles, uint64_t seed) {
  Rng rng(seed, Stream::kParticleNoise);
  Rollout rollout;
  RolloutRecording rec;
  rec.jacobians = true;
  EXPECT_TRUE(SimulateParticles(problem, particles, rec, &rng, &rollout).ok());
  return rollout;
}

TEST(TransitionLogDensities, DiagonalIsEachParticlesOwnDensity) {
  auto sp = SmallProblem(3);
  const Rollout r = Record(sp->problem, 12, 1);
  const StepRecord& step = r.steps[2];
  RowMatrix l;
  TransitionLogDensities(step, &l);
  for (int i = 0; i < 12; ++i) {
    double expected = 0;
    for (int d = 0; d < 4; ++d)
      expected += -0.5 * (std::log(2 * M_PI * step.variance(i, d)) + step.noise(i, d) * step.noise(i, d));
    EXPECT_NEAR(l(i, i), expected, 1e-9 * std::abs(expected));
  }
}

// Every column of the weights (one sample under the mixture of all sources)
// sums to 1, also when the densities are far below the smallest double.
TEST(BiwWeights, EveryColumnSumsToOne) {
  auto sp = SmallProblem(4);
  Rollout r = Record(sp->problem, 30, 2);
  for (double squeeze : {1.0, 1e-6}) {
    for (StepRecord step : r.steps) {
      // squeeze < 1: shrink the variances so that cross densities underflow in
      // linear space (log densities ~ -1e6), as for well-separated particles.
      step.variance *= squeeze;
      RowMatrix lw, linear;
      BiwLogWeights(step, &lw, &linear);
      ASSERT_TRUE(lw.array().isFinite().any());
      const RowMatrix w = lw.array().exp().matrix();
      ASSERT_TRUE(w.allFinite());
      const Eigen::RowVectorXd sums = w.colwise().sum();
      EXPECT_LT((sums.array() - 1.0).abs().maxCoeff(), 1e-12) << "squeeze " << squeeze;
      // The linear weights the estimator uses are the same numbers.
      EXPECT_LT((linear - w).cwiseAbs().maxCoeff(), 1e-14) << "squeeze " << squeeze;
      EXPECT_LT((linear.colwise().sum().array() - 1.0).abs().maxCoeff(), 1e-12);
      // Baselines stay finite where every cross weight underflows.
      Vector g(30), b;
      for (int i = 0; i < 30; ++i) g(i) = 0.1 * i;
      BiwBaseline(lw, g, &b);
      EXPECT_TRUE(b.allFinite());
      Vector b_fast;
      BiwBaseline(lw, linear, g, &b_fast);
      EXPECT_LT((b_fast - b).cwiseAbs().maxCoeff(), 1e-12);
      RowMatrix pb;
      BiwPairBaseline(lw, g, &pb);
      EXPECT_TRUE(pb.allFinite());
    }
  }
}

// The baselines equal their definitions where those are well conditioned.
TEST(BiwBaseline, MatchesTheDefinition) {
  const int p = 6;
  Rng rng(3, Stream::kStudy);
  RowMatrix lw(p, p);
  rng.FillNormal(&lw);
  Vector g(p);
  rng.FillNormal(&g);
  const RowMatrix c = lw.array().exp().matrix();
  Vector b, b_fast;
  BiwBaseline(lw, g, &b);
  BiwBaseline(lw, c, g, &b_fast);
  RowMatrix pb;
  BiwPairBaseline(lw, g, &pb);
  for (int i = 0; i < p; ++i) {
    double num = 0, den = 0;
    for (int j = 0; j < p; ++j)
      if (j != i) num += c(i, j) * g(j), den += c(i, j);
    EXPECT_NEAR(b(i), num / den, 1e-12);
    EXPECT_NEAR(b_fast(i), num / den, 1e-12);
    for (int j = 0; j < p; ++j) {
      double n2 = 0, d2 = 0;
      for (int k = 0; k < p; ++k)
        if (k != j) n2 += c(i, k) * g(k), d2 += c(i, k);
      EXPECT_NEAR(pb(i, j), n2 / d2, 1e-12);
    }
  }
  // One particle: no other sample, the baseline is 0 (no leave-one-out mean).
  RowMatrix one = RowMatrix::Zero(1, 1);
  Vector g1 = Vector::Constant(1, 3.0), b1;
  BiwBaseline(one, g1, &b1);
  EXPECT_EQ(b1(0), 0.0);
}

// Replacing the importance weights by the identity gives plain LR: the
// weighted cotangent with c = I and the leave-one-out baseline is the plain
// one, bit for bit.
TEST(WeightedLr, IdentityWeightsGivePlainLr) {
  auto sp = SmallProblem(3);
  const Rollout r = Record(sp->problem, 15, 4);
  Vector g(15);
  for (int i = 0; i < 15; ++i) g(i) = std::sin(1.0 + i);
  const Vector b = LeaveOneOutBaseline(g);
  for (const StepRecord& step : r.steps) {
    ZetaCotangent plain, weighted;
    PlainLrCotangent(step, g, b, 1.0 / 15, &plain);
    WeightedLrCotangent(step, RowMatrix::Identity(15, 15), g, b, 1.0 / 15, &weighted);
    EXPECT_EQ(plain.mean, weighted.mean);
    EXPECT_EQ(plain.variance, weighted.variance);
    // The per-pair form with b_ij = b_i is the same estimator.
    RowMatrix pair = b.replicate(1, 15);
    ZetaCotangent weighted_pair;
    WeightedLrCotangent(step, RowMatrix::Identity(15, 15), g, pair, 1.0 / 15, &weighted_pair);
    EXPECT_EQ(plain.mean, weighted_pair.mean);
  }
}

TEST(LeaveOneOutBaseline, Definition) {
  Vector g(3);
  g << 1, 2, 6;
  const Vector b = LeaveOneOutBaseline(g);
  EXPECT_DOUBLE_EQ(b(0), 4.0);
  EXPECT_DOUBLE_EQ(b(1), 3.5);
  EXPECT_DOUBLE_EQ(b(2), 1.5);
}

// On the (nonlinear) GP model there is no closed form, but two unbiased
// estimators must agree: RP and LR (plain weights, leave-one-out baseline;
// the GP's input-dependent variance exercises LR's variance path, which the
// linear-Gaussian tests do not). Statistic: each estimate projected on a
// fixed direction u (the normalised mean of an independent RP pilot run),
// averaged over R = 4000 replicates of P = 40 particles, horizon 3, model noise
// variance x1600 (LR's variance scales like 1/noise). Budget:
// |mean_RP - mean_LR| <= 4.5 sqrt(SE_RP^2 + SE_LR^2), SE from the replicate
// variances of the projections; power: the budget must be below |mean_RP| / 3.
TEST(LrOnTheGpModel, AgreesWithRp) {
  auto sp = SmallProblem(3);
  sp->problem.noise_variance_multiplier = 1600.0;
  EstimatorOptions plain;
  plain.lr_weights = LrWeights::kPlain;
  plain.lr_baseline = LrBaseline::kLeaveOneOut;
  auto rp = MakeEstimator(Method::kRp, {});
  auto lr = MakeEstimator(Method::kLr, plain);
  ASSERT_TRUE(rp.ok() && lr.ok());
  const int n = sp->policy->num_parameters();
  const int replicates = 4000;
  EstimateOptions eo;
  eo.particles = 40;
  GradientEstimate g;
  Vector direction = Vector::Zero(n);
  for (int r = 0; r < 50; ++r) {
    Rng rng(99, Stream::kStudy, r);
    ASSERT_TRUE((*rp)->Estimate(sp->problem, eo, &rng, &g).ok());
    direction += g.gradient;
  }
  direction.normalize();
  auto project = [&](Estimator* e, double* mean, double* se) {
    double sum = 0, sq = 0;
    for (int r = 0; r < replicates; ++r) {
      Rng rng(5, Stream::kStudy, r);
      ASSERT_TRUE(e->Estimate(sp->problem, eo, &rng, &g).ok());
      ASSERT_TRUE(g.finite);
      const double v = g.gradient.dot(direction);
      sum += v;
      sq += v * v;
    }
    *mean = sum / replicates;
    *se = std::sqrt(std::max(0.0, (sq / replicates - *mean * *mean) / (replicates - 1)));
  };
  double m_rp, se_rp, m_lr, se_lr;
  project(rp->get(), &m_rp, &se_rp);
  project(lr->get(), &m_lr, &se_lr);
  const double budget = 4.5 * std::sqrt(se_rp * se_rp + se_lr * se_lr);
  std::printf("projected: RP %.6g +- %.2g, LR %.6g +- %.2g, budget %.2g\n", m_rp, se_rp, m_lr, se_lr, budget);
  EXPECT_LE(std::abs(m_rp - m_lr), budget);
  EXPECT_LT(budget, std::abs(m_rp) / 3) << "no power";
}

}  // namespace likelihood_ratio_test
}  // namespace totalgrad::estimators
