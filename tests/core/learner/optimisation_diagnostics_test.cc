// The optimisation diagnostics of issue 27 against hand-computed cases: the
// signal-to-noise ratio, the first/middle/last steps and the means, the ESS
// summaries and the LR share; the BIW weights' effective sample size; and
// what a trial records per method (particle methods their quantities, PILCO
// none), without changing any other number of the trial.
#include "core/learner/optimisation_diagnostics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "core/estimators/likelihood_ratio.h"
#include "core/learner/trial.h"
#include "core/learner/trial_options.h"

namespace totalgrad::learner {
namespace optimisation_diagnostics_test {

Vector Values(std::initializer_list<double> values) {
  Vector v(static_cast<Eigen::Index>(values.size()));
  Eigen::Index i = 0;
  for (double x : values) v(i++) = x;
  return v;
}

estimators::GradientEstimate Estimate(Vector gradient, Vector variance,
                                      std::vector<double> ess = {}, std::vector<double> k_lr = {}) {
  estimators::GradientEstimate e;
  e.gradient = std::move(gradient);
  e.per_particle_variance = std::move(variance);
  e.ess = std::move(ess);
  e.k_lr = std::move(k_lr);
  return e;
}

TEST(OptimisationDiagnostics, SignalToNoiseByHand) {
  // ||(3, 4)|| = 5; the mean's variance trace (2 + 6) / 2 = 4, root 2.
  EXPECT_DOUBLE_EQ(OptimisationDiagnostics::SignalToNoise(Values({3, 4}), Values({2, 6}), 2), 2.5);
  // No noise: undefined (NaN, never an infinity the store would refuse), and
  // the mean over the steps leaves such a step out.
  EXPECT_TRUE(std::isnan(OptimisationDiagnostics::SignalToNoise(Values({1, 0}), Values({0, 0}), 5)));
  OptimisationDiagnostics d(2, 2);
  d.AddStep(0, Estimate(Values({1, 0}), Values({0, 0})), 1);
  d.AddStep(1, Estimate(Values({3, 4}), Values({2, 6})), 1);
  EpisodeSummary r;
  d.Fill(&r);
  EXPECT_TRUE(std::isnan(r.gradient_snr_first));
  EXPECT_DOUBLE_EQ(r.gradient_snr_last, 2.5);
  EXPECT_DOUBLE_EQ(r.gradient_snr_mean, 2.5);
}

TEST(OptimisationDiagnostics, FirstMiddleLastAndMeansByHand) {
  // S = 4 steps: first = step 1, middle = step 2 (S/2), last = step 4.
  OptimisationDiagnostics d(4, 2);
  d.AddStep(0, Estimate(Values({3, 4}), Values({2, 6})), 0.5);    // norm 5, snr 2.5
  d.AddStep(1, Estimate(Values({0, 2}), Values({8, 0})), 1.5);    // norm 2, snr 1
  // Step 2 was non-finite: the optimiser skipped it, so it is not added.
  d.AddStep(3, Estimate(Values({6, 8}), Values({50, 150})), 2.5); // norm 10, snr 1
  EpisodeSummary r;
  d.Fill(&r);
  EXPECT_DOUBLE_EQ(r.gradient_norm_first, 5);
  EXPECT_DOUBLE_EQ(r.gradient_norm_middle, 2);
  EXPECT_DOUBLE_EQ(r.gradient_norm_last, 10);
  EXPECT_DOUBLE_EQ(r.gradient_norm_mean, 17.0 / 3);
  EXPECT_DOUBLE_EQ(r.gradient_snr_first, 2.5);
  EXPECT_DOUBLE_EQ(r.gradient_snr_middle, 1);
  EXPECT_DOUBLE_EQ(r.gradient_snr_last, 1);
  EXPECT_DOUBLE_EQ(r.gradient_snr_mean, 1.5);
  EXPECT_DOUBLE_EQ(r.step_norm_first, 0.5);
  EXPECT_DOUBLE_EQ(r.step_norm_middle, 1.5);
  EXPECT_DOUBLE_EQ(r.step_norm_last, 2.5);
  EXPECT_DOUBLE_EQ(r.step_norm_mean, 1.5);
  // No importance weights, no combination: absent, not zero.
  EXPECT_TRUE(std::isnan(r.ess_min) && std::isnan(r.ess_median) && std::isnan(r.ess_low_fraction));
  EXPECT_TRUE(r.lr_share.empty());
  // At the paper's protocol the middle step is step 300 (index 299).
  OptimisationDiagnostics paper(600, 300);
  paper.AddStep(298, Estimate(Values({1}), Values({1})), 7);
  paper.AddStep(299, Estimate(Values({1}), Values({1})), 9);
  EpisodeSummary p;
  paper.Fill(&p);
  EXPECT_EQ(p.step_norm_middle, 9);
  EXPECT_TRUE(std::isnan(p.step_norm_first));  // step 1 was not taken
}

TEST(OptimisationDiagnostics, EssSummariesAndLrShareByHand) {
  // P = 300: "low" is ESS < 30.
  OptimisationDiagnostics d(2, 300);
  d.AddStep(0, Estimate(Values({1}), Values({1}), {1, 50, 20, 40}, {0.25, 0.5, 1.0, 0.0}), 1);
  // min 1, median (20 + 40) / 2 = 30, below 30: 1 and 20, half.
  d.AddStep(1, Estimate(Values({1}), Values({1}), {300, 300, 10, 300}, {0.75, 0.5, 0.0, 0.0}), 1);
  // min 10, median 300, below 30: one of four.
  EpisodeSummary r;
  d.Fill(&r);
  EXPECT_DOUBLE_EQ(r.ess_min, (1 + 10) / 2.0);
  EXPECT_DOUBLE_EQ(r.ess_median, (30 + 300) / 2.0);
  EXPECT_DOUBLE_EQ(r.ess_low_fraction, (0.5 + 0.25) / 2);
  EXPECT_EQ(r.lr_share, (std::vector<double>{0.5, 0.5, 0.5, 0.0}));
}

TEST(MeanEffectiveSampleSize, UniformIsPIdentityIsOneAndAHandCase) {
  const int p = 7;
  EXPECT_NEAR(estimators::MeanEffectiveSampleSize(RowMatrix::Constant(p, p, 1.0 / p)), p, 1e-12);
  EXPECT_DOUBLE_EQ(estimators::MeanEffectiveSampleSize(RowMatrix::Identity(p, p)), 1);
  RowMatrix c(2, 2);
  c << 0.9, 0.2, 0.1, 0.8;  // columns sum to 1
  // Row 0: 1.1^2 / 0.85; row 1: 0.9^2 / 0.65.
  EXPECT_NEAR(estimators::MeanEffectiveSampleSize(c), (1.21 / 0.85 + 0.81 / 0.65) / 2, 1e-15);
  RowMatrix zero_row = c;
  zero_row.row(1).setZero();
  EXPECT_NEAR(estimators::MeanEffectiveSampleSize(zero_row), 1.21 / 0.85 / 2, 1e-15);
  RowMatrix nan = c;
  nan(0, 1) = std::nan("");
  EXPECT_TRUE(std::isnan(estimators::MeanEffectiveSampleSize(nan)));
}

TrialOptions Tiny(const std::string& method) {
  TrialOptions o;
  for (const auto& [k, v] : std::vector<std::pair<std::string, std::string>>{
           {"method", method}, {"episodes", "2"}, {"policy_steps", "4"}, {"particles", "10"},
           {"eval_rollouts", "2"}, {"horizon", "8"}, {"basis_functions", "6"},
           {"gp_iterations", "10"}, {"predicted_cost_particles", "20"}, {"seed", "3"},
           {"verdict_rollouts", "4"}, {"verdict_hold_seconds", "0.3"}}) {
    EXPECT_TRUE(SetTrialOption(k, v, &o).ok()) << k;
  }
  return o;
}

TEST(TrialDiagnostics, EachMethodRecordsWhatItHas) {
  for (const std::string method : {"RP", "LR", "TP", "GTP+sn", "DEL", "PILCO"}) {
    SCOPED_TRACE(method);
    absl::StatusOr<TrialSummary> trial = RunTrial(Tiny(method), nullptr);
    ASSERT_TRUE(trial.ok()) << trial.status();
    const EpisodeResult& zero = trial->episodes[0];
    EXPECT_TRUE(std::isnan(zero.gradient_norm_mean));
    for (size_t e = 1; e < trial->episodes.size(); ++e) {
      const EpisodeResult& r = trial->episodes[e];
      const bool particle = method != "PILCO";
      const bool biw = method == "LR" || method == "TP" || method == "GTP+sn";
      const bool combines = method == "TP" || method == "GTP+sn";
      EXPECT_EQ(std::isfinite(r.gradient_norm_mean), particle);
      EXPECT_EQ(std::isfinite(r.gradient_snr_first), particle);
      EXPECT_EQ(std::isfinite(r.step_norm_last), particle);
      EXPECT_EQ(std::isfinite(r.ess_median), biw);
      if (biw) {
        EXPECT_GE(r.ess_min, 0);
        EXPECT_LE(r.ess_min, r.ess_median);
        EXPECT_LE(r.ess_median, 10 + 1e-9);
        EXPECT_GE(r.ess_low_fraction, 0);
        EXPECT_LE(r.ess_low_fraction, 1);
      }
      EXPECT_EQ(r.lr_share.size(), combines ? 8u : 0u);
      for (double k : r.lr_share) {
        EXPECT_GE(k, 0);
        EXPECT_LE(k, 1);
      }
    }
  }
}

}  // namespace optimisation_diagnostics_test
}  // namespace totalgrad::learner
