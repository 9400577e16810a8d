// Every particle method runs a short trial end to end (learner::RunTrial on
// a tiny protocol) without a non-finite value, including with P = 2, where
// the Gaussian fits of GR, GLR, GTP and DEL are singular and need jitter.
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "core/estimators/estimator.h"
#include "core/learner/trial.h"

namespace totalgrad::learner {
namespace methods_trial_test {

class Watcher final : public TrialObserver {
 public:
  void OnEpisode(const EpisodeResult& r) override { episodes.push_back(r); }
  void OnPolicyStep(int, int, double objective, double step_norm) override {
    ++steps;
    if (!std::isfinite(objective) || !std::isfinite(step_norm)) ++non_finite;
  }
  std::vector<EpisodeResult> episodes;
  int steps = 0;
  int non_finite = 0;
};

TrialOptions Tiny(const std::string& method, int particles) {
  TrialOptions o;
  for (const auto& [k, v] : std::vector<std::pair<std::string, std::string>>{
           {"method", method}, {"episodes", "2"}, {"policy_steps", "10"},
           {"particles", std::to_string(particles)}, {"eval_rollouts", "1"}, {"horizon", "15"},
           {"basis_functions", "5"}, {"gp_iterations", "5"}, {"predicted_cost_particles", "10"},
           {"seed", "7"}}) {
    EXPECT_TRUE(SetTrialOption(k, v, &o).ok()) << k << "=" << v;
  }
  return o;
}

void ExpectCleanTrial(const TrialOptions& options, const std::string& label) {
  Watcher watcher;
  const auto summary = RunTrial(options, &watcher);
  ASSERT_TRUE(summary.ok()) << label << ": " << summary.status();
  ASSERT_EQ(watcher.episodes.size(), 3u) << label;
  EXPECT_EQ(watcher.steps, 2 * options.policy_steps) << label;
  EXPECT_EQ(watcher.non_finite, 0) << label;
  for (int e = 1; e <= 2; ++e) {
    const EpisodeResult& r = watcher.episodes[e];
    EXPECT_EQ(r.flags.non_finite_gradients, 0) << label << " episode " << e;
    EXPECT_TRUE(std::isfinite(r.predicted_cost)) << label;
    EXPECT_TRUE(std::isfinite(r.eval_cost_mean)) << label;
    EXPECT_TRUE(r.policy_parameters.allFinite()) << label;
  }
}

class MethodTrial : public ::testing::TestWithParam<std::string> {};

TEST_P(MethodTrial, RunsWithoutNonFiniteValues) {
  for (int particles : {2, 5}) {
    ExpectCleanTrial(Tiny(GetParam(), particles), GetParam() + " P=" + std::to_string(particles));
  }
}

// angle_features = sincos: the GP and the policy on (sin, cos) of the angle
// through the estimators' angle adapters, for every method.
TEST_P(MethodTrial, SinCosAngleFeaturesRunWithoutNonFiniteValues) {
  TrialOptions o = Tiny(GetParam(), 5);
  ASSERT_TRUE(SetTrialOption("angle_features", "sincos", &o).ok());
  ExpectCleanTrial(o, GetParam() + " sincos");
}

INSTANTIATE_TEST_SUITE_P(AllMethods, MethodTrial,
                         ::testing::ValuesIn(estimators::ParticleMethodNames()),
                         [](const auto& info) {
                           std::string s = info.param;
                           for (char& c : s)
                             if (c == '+') c = '_';
                           return s;
                         });

// The method options reach the estimators through the trial's key=value space.
TEST(MethodTrial, OptionVariantsRun) {
  const std::vector<std::vector<std::pair<std::string, std::string>>> variants = {
      {{"method", "GTP"}, {"gs_derivative", "exact"}, {"cost", "tip"}},
      {{"method", "GLR"}, {"gs_derivative", "exact"}},
      {{"method", "TP"}, {"lr_weights", "plain"}, {"lr_baseline", "loo"}},
      {{"method", "LR"}, {"lr_baseline", "biw_pair"}},
      {{"method", "GTP+sn"}, {"sn_noise_multiplier", "9"}},
  };
  for (const auto& variant : variants) {
    for (int particles : {2, 5}) {
      TrialOptions o = Tiny("RP", particles);
      std::string label;
      for (const auto& [k, v] : variant) {
        ASSERT_TRUE(SetTrialOption(k, v, &o).ok()) << k << "=" << v;
        label += k + "=" + v + " ";
      }
      ExpectCleanTrial(o, label + "P=" + std::to_string(particles));
    }
  }
}

TEST(MethodTrial, OptionKeysRoundTrip) {
  TrialOptions o;
  ASSERT_TRUE(SetTrialOption("lr_weights", "plain", &o).ok());
  ASSERT_TRUE(SetTrialOption("lr_baseline", "none", &o).ok());
  ASSERT_TRUE(SetTrialOption("gs_derivative", "exact", &o).ok());
  ASSERT_TRUE(SetTrialOption("sn_noise_multiplier", "16", &o).ok());
  EXPECT_FALSE(SetTrialOption("lr_baseline", "bogus", &o).ok());
  TrialOptions copy;
  for (const auto& [k, v] : TrialOptionPairs(o)) ASSERT_TRUE(SetTrialOption(k, v, &copy).ok()) << k;
  EXPECT_EQ(copy.estimator.lr_weights, estimators::LrWeights::kPlain);
  EXPECT_EQ(copy.estimator.lr_baseline, estimators::LrBaseline::kNone);
  EXPECT_EQ(copy.estimator.gs_derivative, estimators::GsDerivative::kExact);
  EXPECT_EQ(copy.estimator.sn_noise_multiplier, 16.0);
  TrialOptions bad = Tiny("GTP+sn", 3);
  ASSERT_TRUE(SetTrialOption("sn_noise_multiplier", "-1", &bad).ok());
  EXPECT_EQ(RunTrial(bad, nullptr).status().code(), absl::StatusCode::kInvalidArgument);
}

}  // namespace methods_trial_test
}  // namespace totalgrad::learner
