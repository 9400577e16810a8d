#include "core/learner/trial.h"

#include <cmath>
#include <cstring>

#include <gtest/gtest.h>

namespace totalgrad::learner {
namespace trial_test {

TrialOptions Tiny() {
  TrialOptions o;
  for (const auto& [k, v] : std::vector<std::pair<std::string, std::string>>{
           {"episodes", "2"}, {"policy_steps", "4"}, {"particles", "8"}, {"eval_rollouts", "2"},
           {"horizon", "10"}, {"basis_functions", "10"}, {"gp_iterations", "20"},
           {"predicted_cost_particles", "20"}, {"seed", "5"}}) {
    EXPECT_TRUE(SetTrialOption(k, v, &o).ok()) << k;
  }
  return o;
}

class Recorder final : public TrialObserver {
 public:
  void OnEpisode(const EpisodeResult& r) override { results.push_back(r); }
  bool ShouldCancel() override { return ++polls > cancel_after; }
  std::vector<EpisodeResult> results;
  int polls = 0;
  int cancel_after = 1 << 30;
};

TEST(Trial, RunsAndReportsEveryEpisode) {
  Recorder recorder;
  auto summary = RunTrial(Tiny(), &recorder);
  ASSERT_TRUE(summary.ok()) << summary.status();
  ASSERT_EQ(recorder.results.size(), 3u);
  EXPECT_EQ(recorder.results[0].episode, 0);
  EXPECT_TRUE(std::isnan(recorder.results[0].eval_cost_mean));
  for (int e = 1; e <= 2; ++e) {
    const EpisodeResult& r = recorder.results[e];
    EXPECT_EQ(r.episode, e);
    EXPECT_TRUE(std::isfinite(r.real_cost));
    EXPECT_GE(r.eval_cost_mean, 0);
    EXPECT_LE(r.eval_cost_mean, 10.0);  // horizon 10, costs in [0, 1]
    EXPECT_TRUE(std::isfinite(r.predicted_cost));
    EXPECT_EQ(r.hyperparameters.num_outputs(), 4);
  }
  EXPECT_EQ(summary->final_eval_cost, recorder.results.back().eval_cost_mean);
  EXPECT_EQ(summary->success, summary->final_eval_cost < 15.0);
}

TEST(Trial, SameSeedSameNumbersBitForBit) {
  auto a = RunTrial(Tiny(), nullptr);
  auto b = RunTrial(Tiny(), nullptr);
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_EQ(a->episodes.size(), b->episodes.size());
  for (size_t e = 0; e < a->episodes.size(); ++e) {
    const EpisodeResult &x = a->episodes[e], &y = b->episodes[e];
    EXPECT_EQ(std::memcmp(&x.real_cost, &y.real_cost, sizeof(double)), 0) << e;
    if (e > 0) {
      EXPECT_EQ(x.eval_cost_mean, y.eval_cost_mean) << e;
      EXPECT_EQ(x.eval_cost_std, y.eval_cost_std) << e;
      EXPECT_EQ(x.predicted_cost, y.predicted_cost) << e;
      EXPECT_EQ(x.hyperparameters.log_lengthscales, y.hyperparameters.log_lengthscales) << e;
    }
  }
  TrialOptions other = Tiny();
  other.seed = 6;
  auto c = RunTrial(other, nullptr);
  ASSERT_TRUE(c.ok());
  EXPECT_NE(c->episodes[1].eval_cost_mean, a->episodes[1].eval_cost_mean);
}

TEST(Trial, CancellationStopsTheTrial) {
  Recorder recorder;
  recorder.cancel_after = 2;
  auto summary = RunTrial(Tiny(), &recorder);
  ASSERT_FALSE(summary.ok());
  EXPECT_EQ(summary.status().code(), absl::StatusCode::kCancelled);
}

TEST(TrialOptions, UnknownKeyAndBadValuesAreNamed) {
  TrialOptions o;
  absl::Status s = SetTrialOption("particels", "3", &o);
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("particels"), std::string::npos);
  s = SetTrialOption("particles", "many", &o);
  EXPECT_NE(s.message().find("many"), std::string::npos);
  s = SetTrialOption("noise_k", "nan", &o);
  EXPECT_FALSE(s.ok());
  s = SetTrialOption("method", "QQ", &o);
  EXPECT_NE(s.message().find("QQ"), std::string::npos);
  o.particles = 0;
  s = o.Validate();
  EXPECT_NE(s.message().find("particles"), std::string::npos);
  o = TrialOptions();
  o.scene.scene = "acrobot";  // not a scene (pendulum is one since issue 14)
  EXPECT_FALSE(o.Validate().ok());
}

TEST(TrialOptions, PairsRoundTrip) {
  TrialOptions o = Tiny();
  o.optimizer.learning_rate = 1.0 / 3.0;
  o.scene.noise_k = 0.01;
  TrialOptions back;
  for (const auto& [k, v] : TrialOptionPairs(o)) ASSERT_TRUE(SetTrialOption(k, v, &back).ok()) << k;
  EXPECT_EQ(TrialOptionPairs(back), TrialOptionPairs(o));
  EXPECT_EQ(back.optimizer.learning_rate, 1.0 / 3.0);
}

// --gp-inducing for particle methods: FITC once the data exceed M. Horizon
// 15: episode 1 fits N = 15 <= 20 points (full GP), episode 2 N = 30 > 20
// (FITC with 20 inducing inputs). Checked against the same trial with the
// full GP throughout: episode 1 must agree bit for bit, episode 2's model
// must differ (otherwise FITC was not used).
TrialOptions TinyFitc(const std::string& method, const std::string& inducing) {
  TrialOptions o = Tiny();
  EXPECT_TRUE(SetTrialOption("method", method, &o).ok());
  EXPECT_TRUE(SetTrialOption("horizon", "15", &o).ok());
  EXPECT_TRUE(SetTrialOption("gp_inducing", inducing, &o).ok());
  return o;
}

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

// Learned episode e of two runs of the same trial: finite, no non-finite
// gradient, and the same bits in costs and policy.
void ExpectFiniteAndIdentical(const EpisodeResult& x, const EpisodeResult& y, size_t e) {
  EXPECT_TRUE(std::isfinite(x.real_cost)) << e;
  EXPECT_TRUE(std::isfinite(x.eval_cost_mean)) << e;
  EXPECT_TRUE(std::isfinite(x.predicted_cost)) << e;
  EXPECT_TRUE(x.policy_parameters.allFinite()) << e;
  EXPECT_EQ(x.flags.non_finite_gradients, 0) << e;
  EXPECT_TRUE(SameBits(x.real_cost, y.real_cost)) << e;
  EXPECT_TRUE(SameBits(x.eval_cost_mean, y.eval_cost_mean)) << e;
  EXPECT_TRUE(SameBits(x.predicted_cost, y.predicted_cost)) << e;
  ASSERT_EQ(x.policy_parameters.size(), y.policy_parameters.size());
  EXPECT_EQ(std::memcmp(x.policy_parameters.data(), y.policy_parameters.data(),
                        sizeof(double) * x.policy_parameters.size()),
            0)
      << e;
}

class ParticleTrialFitc : public ::testing::TestWithParam<std::string> {};

TEST_P(ParticleTrialFitc, RunsFiniteAndDeterministically) {
  const TrialOptions o = TinyFitc(GetParam(), "20");
  ASSERT_TRUE(o.Validate().ok()) << o.Validate();
  auto a = RunTrial(o, nullptr);
  ASSERT_TRUE(a.ok()) << a.status();
  auto b = RunTrial(o, nullptr);
  ASSERT_TRUE(b.ok()) << b.status();
  ASSERT_EQ(a->episodes.size(), 3u);
  ASSERT_EQ(b->episodes.size(), 3u);
  for (size_t e = 1; e < a->episodes.size(); ++e) {
    ExpectFiniteAndIdentical(a->episodes[e], b->episodes[e], e);
  }
  auto full = RunTrial(TinyFitc(GetParam(), "0"), nullptr);
  ASSERT_TRUE(full.ok()) << full.status();
  // Episode 1 (N = 15 <= 20): the full GP in both runs.
  EXPECT_TRUE(SameBits(full->episodes[1].predicted_cost, a->episodes[1].predicted_cost));
  EXPECT_EQ(full->episodes[1].policy_parameters, a->episodes[1].policy_parameters);
  // Episode 2 (N = 30 > 20): FITC, a different model, hence a different policy.
  EXPECT_EQ(full->episodes[2].hyperparameters.log_lengthscales,
            a->episodes[2].hyperparameters.log_lengthscales);
  EXPECT_NE(full->episodes[2].predicted_cost, a->episodes[2].predicted_cost);
  EXPECT_NE(full->episodes[2].policy_parameters, a->episodes[2].policy_parameters);
}

INSTANTIATE_TEST_SUITE_P(Methods, ParticleTrialFitc, ::testing::Values("RP", "TP"));

// The option reaches the particle methods' GP (a large tolerance makes the
// low-rank variance active at these sizes and changes the trial), and PILCO
// ignores it (the same bits).
TEST(Trial, GpVarianceToleranceReachesTheParticleModelOnly) {
  for (const char* method : {"RP", "PILCO"}) {
    TrialOptions exact = Tiny();
    ASSERT_TRUE(SetTrialOption("method", method, &exact).ok());
    ASSERT_TRUE(SetTrialOption("horizon", "30", &exact).ok());
    ASSERT_TRUE(SetTrialOption("gp_variance_tolerance", "0", &exact).ok());
    TrialOptions fast = exact;
    ASSERT_TRUE(SetTrialOption("gp_variance_tolerance", "0.5", &fast).ok());
    auto a = RunTrial(exact, nullptr);
    auto b = RunTrial(fast, nullptr);
    ASSERT_TRUE(a.ok()) << a.status();
    ASSERT_TRUE(b.ok()) << b.status();
    const EpisodeResult& x = a->episodes.back();
    const EpisodeResult& y = b->episodes.back();
    if (std::string(method) == "PILCO") {
      EXPECT_TRUE(SameBits(x.predicted_cost, y.predicted_cost));
      EXPECT_EQ(x.policy_parameters, y.policy_parameters);
    } else {
      EXPECT_NE(x.policy_parameters, y.policy_parameters) << "the option did not reach the model";
    }
  }
}

TEST(TrialOptions, GpVarianceToleranceValues) {
  TrialOptions o = Tiny();
  for (const char* ok : {"0", "1e-6", "0.01", "0.5"}) {
    ASSERT_TRUE(SetTrialOption("gp_variance_tolerance", ok, &o).ok()) << ok;
    EXPECT_TRUE(o.Validate().ok()) << ok << ": " << o.Validate();
    EXPECT_EQ(GpOptions(o).variance_rank_tolerance, o.gp_variance_tolerance);
  }
  for (const char* bad : {"-1e-3", "1", "2"}) {
    ASSERT_TRUE(SetTrialOption("gp_variance_tolerance", bad, &o).ok()) << bad;
    const absl::Status s = o.Validate();
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << bad;
    EXPECT_NE(s.message().find("gp_variance_tolerance"), std::string::npos) << s;
  }
  // Non-finite values: the text parser refuses them, and a struct holding
  // one fails Validate(), both naming the option.
  for (const char* bad : {"nan", "inf", "small"}) {
    const absl::Status parse = SetTrialOption("gp_variance_tolerance", bad, &o);
    EXPECT_EQ(parse.code(), absl::StatusCode::kInvalidArgument) << bad;
    EXPECT_NE(parse.message().find("gp_variance_tolerance"), std::string::npos) << parse;
  }
  for (double bad : {std::nan(""), HUGE_VAL}) {
    o.gp_variance_tolerance = bad;
    const absl::Status s = o.Validate();
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << bad;
    EXPECT_NE(s.message().find("gp_variance_tolerance"), std::string::npos) << s;
  }
}

TEST(TrialOptions, GpInducingValues) {
  TrialOptions o = Tiny();
  for (const char* ok : {"-1", "0", "1", "300"}) {
    ASSERT_TRUE(SetTrialOption("gp_inducing", ok, &o).ok()) << ok;
    EXPECT_TRUE(o.Validate().ok()) << ok << ": " << o.Validate();
  }
  ASSERT_TRUE(SetTrialOption("gp_inducing", "-2", &o).ok());
  const absl::Status s = o.Validate();
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("gp_inducing"), std::string::npos);
  EXPECT_FALSE(SetTrialOption("gp_inducing", "many", &o).ok());
}

}  // namespace trial_test
}  // namespace totalgrad::learner

namespace totalgrad::learner {
namespace trial_test {

TEST(PilcoTrial, RunsDeterministicallyAndRecordsPerStepPredictions) {
  TrialOptions o = Tiny();
  ASSERT_TRUE(SetTrialOption("method", "PILCO", &o).ok());
  ASSERT_TRUE(SetTrialOption("basis_functions", "5", &o).ok());
  ASSERT_TRUE(SetTrialOption("cost", "tip", &o).ok());
  auto a = RunTrial(o, nullptr);
  ASSERT_TRUE(a.ok()) << a.status();
  auto b = RunTrial(o, nullptr);
  ASSERT_TRUE(b.ok());
  ASSERT_EQ(a->episodes.size(), 3u);
  for (int e = 1; e <= 2; ++e) {
    const EpisodeResult& r = a->episodes[e];
    ASSERT_EQ(r.predicted_cost_mean_per_step.size(), 10);
    ASSERT_EQ(r.predicted_cost_std_per_step.size(), 10);
    EXPECT_NEAR(r.predicted_cost_mean_per_step.sum(), r.predicted_cost, 1e-9);
    EXPECT_TRUE(std::isfinite(r.eval_cost_mean));
    // sin/cos features by default: 5 policy inputs, C = 5.
    EXPECT_EQ(r.policy_parameters.size(), 5 * 5 + 5 + 5);
    EXPECT_EQ(r.eval_cost_mean, b->episodes[e].eval_cost_mean);
  }
}

// pilco_line_searches reaches PILCO's BFGS: the default budget (the scene's
// 150) and the explicit value 150 give the same bits; 1 and 2 line searches
// stop earlier, at other policies, and 1 search ends at a higher predicted
// cost than the full budget (BFGS never returns a worse point).
TEST(PilcoTrial, LineSearchBudgetReachesTheOptimiser) {
  auto run = [](const char* line_searches) {
    TrialOptions o = Tiny();
    EXPECT_TRUE(SetTrialOption("method", "PILCO", &o).ok());
    EXPECT_TRUE(SetTrialOption("basis_functions", "5", &o).ok());
    EXPECT_TRUE(SetTrialOption("episodes", "1", &o).ok());
    if (line_searches != nullptr) {
      EXPECT_TRUE(SetTrialOption("pilco_line_searches", line_searches, &o).ok());
    }
    auto trial = RunTrial(o, nullptr);
    EXPECT_TRUE(trial.ok()) << trial.status();
    return trial.ok() ? trial->episodes[1] : EpisodeResult();
  };
  const EpisodeResult by_default = run(nullptr);
  const EpisodeResult explicit_150 = run("150");
  const EpisodeResult one = run("1");
  const EpisodeResult two = run("2");
  ASSERT_EQ(by_default.policy_parameters.size(), one.policy_parameters.size());
  EXPECT_TRUE(by_default.policy_parameters == explicit_150.policy_parameters);
  EXPECT_FALSE(one.policy_parameters == two.policy_parameters);
  EXPECT_FALSE(one.policy_parameters == by_default.policy_parameters);
  EXPECT_GT(one.predicted_cost, by_default.predicted_cost);
}

TEST(PilcoTrial, RawAngleFeaturesWork) {
  TrialOptions o = Tiny();
  ASSERT_TRUE(SetTrialOption("method", "PILCO", &o).ok());
  ASSERT_TRUE(SetTrialOption("basis_functions", "5", &o).ok());
  ASSERT_TRUE(SetTrialOption("angle_features", "raw", &o).ok());
  ASSERT_TRUE(SetTrialOption("seed", "1", &o).ok());
  auto a = RunTrial(o, nullptr);
  ASSERT_TRUE(a.ok()) << a.status();
  EXPECT_EQ(a->episodes[1].policy_parameters.size(), 5 * 4 + 4 + 5);
}

// Regression: with raw angle inputs and seed 5, the warm-started policy of
// episode 2 has a pre-saturation variance above 236, where gSat's variance
// used to evaluate 0 * Inf = NaN ("input covariance is not finite"); fixed in
// core/pilco/saturation.cc. The trial must now complete with finite numbers.
TEST(PilcoTrial, RawAngleLargeControlVarianceStaysFinite) {
  TrialOptions o = Tiny();
  ASSERT_TRUE(SetTrialOption("method", "PILCO", &o).ok());
  ASSERT_TRUE(SetTrialOption("basis_functions", "5", &o).ok());
  ASSERT_TRUE(SetTrialOption("angle_features", "raw", &o).ok());
  auto a = RunTrial(o, nullptr);
  ASSERT_TRUE(a.ok()) << a.status();
  for (const EpisodeResult& r : a->episodes) EXPECT_TRUE(std::isfinite(r.real_cost));
  for (size_t e = 1; e < a->episodes.size(); ++e)
    EXPECT_TRUE(std::isfinite(a->episodes[e].predicted_cost)) << e;
}

// Every angle representation is valid for every method; other values are
// refused by name.
TEST(TrialOptions, AngleFeaturesValuesForEveryMethod) {
  for (const char* method : {"RP", "GR", "LR", "TP", "GLR", "GTP", "GTP+sn", "DEL", "PILCO"}) {
    for (const char* value : {"auto", "raw", "sincos"}) {
      TrialOptions o = Tiny();
      ASSERT_TRUE(SetTrialOption("method", method, &o).ok()) << method;
      ASSERT_TRUE(SetTrialOption("angle_features", value, &o).ok()) << value;
      EXPECT_TRUE(o.Validate().ok()) << method << " " << value << ": " << o.Validate();
    }
  }
  TrialOptions o = Tiny();
  const absl::Status s = SetTrialOption("angle_features", "polar", &o);
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("angle_features"), std::string::npos);
  EXPECT_NE(s.message().find("polar"), std::string::npos);
  o.angle_features = static_cast<AngleFeatures>(99);  // set directly, bypassing SetTrialOption
  EXPECT_EQ(o.Validate().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(o.Validate().message().find("angle_features"), std::string::npos);
}

// Particle methods on (sin, cos) features: a short trial runs with finite
// numbers, is deterministic, has the 5-input policy, and differs from the
// same trial on the raw state (and raw = auto, bit for bit).
class ParticleTrialSinCos : public ::testing::TestWithParam<std::string> {};

TEST_P(ParticleTrialSinCos, RunsFiniteDeterministicallyAndDiffersFromRaw) {
  TrialOptions o = Tiny();
  ASSERT_TRUE(SetTrialOption("method", GetParam(), &o).ok());
  ASSERT_TRUE(SetTrialOption("angle_features", "sincos", &o).ok());
  ASSERT_TRUE(o.Validate().ok()) << o.Validate();
  auto a = RunTrial(o, nullptr);
  ASSERT_TRUE(a.ok()) << a.status();
  auto b = RunTrial(o, nullptr);
  ASSERT_TRUE(b.ok()) << b.status();
  ASSERT_EQ(a->episodes.size(), 3u);
  ASSERT_EQ(b->episodes.size(), 3u);
  for (size_t e = 1; e < a->episodes.size(); ++e) {
    const EpisodeResult& x = a->episodes[e];
    ExpectFiniteAndIdentical(x, b->episodes[e], e);
    // C = 10 basis functions on [s, s_dot, beta_dot, sin beta, cos beta].
    EXPECT_EQ(x.policy_parameters.size(), 10 * 5 + 5 + 10) << e;
    // GP inputs [features, u]: 6 length-scales per output.
    EXPECT_EQ(x.hyperparameters.num_inputs(), 6) << e;
  }
  TrialOptions raw_options = o;
  ASSERT_TRUE(SetTrialOption("angle_features", "raw", &raw_options).ok());
  auto raw = RunTrial(raw_options, nullptr);
  ASSERT_TRUE(raw.ok()) << raw.status();
  EXPECT_EQ(raw->episodes[1].policy_parameters.size(), 10 * 4 + 4 + 10);
  EXPECT_NE(raw->episodes[1].predicted_cost, a->episodes[1].predicted_cost);
  EXPECT_NE(raw->episodes[2].real_cost, a->episodes[2].real_cost);
  TrialOptions auto_options = o;
  ASSERT_TRUE(SetTrialOption("angle_features", "auto", &auto_options).ok());
  auto automatic = RunTrial(auto_options, nullptr);
  ASSERT_TRUE(automatic.ok()) << automatic.status();
  for (size_t e = 1; e < raw->episodes.size(); ++e) {
    EXPECT_TRUE(SameBits(raw->episodes[e].predicted_cost, automatic->episodes[e].predicted_cost));
    EXPECT_EQ(raw->episodes[e].policy_parameters, automatic->episodes[e].policy_parameters);
  }
}

INSTANTIATE_TEST_SUITE_P(Methods, ParticleTrialSinCos, ::testing::Values("RP", "TP"));

// Threads never change the numbers: every method, with the full GP, with FITC
// (RP and TP) and with sin/cos features, gives the same bits on 1, 2 and 3
// threads (3 does not divide the 4 GP outputs or the particle blocks evenly).
class TrialThreads : public ::testing::TestWithParam<std::string> {};

TEST_P(TrialThreads, SameBitsForAnyThreadCount) {
  std::vector<TrialOptions> variants;
  TrialOptions o = Tiny();
  ASSERT_TRUE(SetTrialOption("method", GetParam(), &o).ok());
  ASSERT_TRUE(SetTrialOption("particles", "70", &o).ok());  // more than one particle block
  variants.push_back(o);
  if (GetParam() == "RP" || GetParam() == "TP") {
    TrialOptions fitc = TinyFitc(GetParam(), "20");
    ASSERT_TRUE(SetTrialOption("particles", "70", &fitc).ok());
    variants.push_back(fitc);
    TrialOptions sincos = o;
    ASSERT_TRUE(SetTrialOption("angle_features", "sincos", &sincos).ok());
    variants.push_back(sincos);
    // The low-rank variance active (a large tolerance at these sizes).
    TrialOptions lowrank = o;
    ASSERT_TRUE(SetTrialOption("horizon", "30", &lowrank).ok());
    ASSERT_TRUE(SetTrialOption("gp_variance_tolerance", "0.5", &lowrank).ok());
    variants.push_back(lowrank);
  }
  for (const TrialOptions& options : variants) {
    auto one = RunTrial(options, nullptr);
    ASSERT_TRUE(one.ok()) << one.status();
    for (int threads : {2, 3}) {
      RunOptions run;
      run.threads = threads;
      auto many = RunTrial(options, nullptr, run);
      ASSERT_TRUE(many.ok()) << many.status();
      ASSERT_EQ(many->episodes.size(), one->episodes.size());
      for (size_t e = 1; e < one->episodes.size(); ++e)
        ExpectFiniteAndIdentical(one->episodes[e], many->episodes[e], e);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Methods, TrialThreads,
                         ::testing::Values("RP", "GR", "LR", "TP", "GLR", "GTP", "GTP+sn", "DEL",
                                           "PILCO"),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           std::string name = info.param;
                           for (char& c : name)
                             if (c == '+') c = '_';
                           return name;
                         });

TEST(Trial, EpisodesReportTheirCpuTimeByPhase) {
  auto summary = RunTrial(Tiny(), nullptr);
  ASSERT_TRUE(summary.ok()) << summary.status();
  for (size_t e = 1; e < summary->episodes.size(); ++e) {
    const EpisodeResult& r = summary->episodes[e];
    const EpisodeTiming& t = r.timing;
    EXPECT_EQ(t.policy_steps, 4) << e;
    EXPECT_GT(t.policy_cpu, 0) << e;
    EXPECT_GT(t.model_cpu, 0) << e;
    EXPECT_GT(t.evaluation_cpu, 0) << e;
    EXPECT_GE(t.prediction_cpu, 0) << e;
    EXPECT_EQ(r.cpu_seconds, t.total_cpu()) << e;
    // CPU time of one thread cannot exceed its wall time by more than clock granularity.
    EXPECT_LE(t.policy_cpu, t.policy_wall + 0.01) << e;
  }
}

// With a sparse GP too (gp_inducing: FITC on feature inputs behind the adapter
// once N = 30 > 20 in episode 2).
TEST(ParticleTrialSinCosFitc, RunsFiniteAndUsesFitc) {
  TrialOptions o = TinyFitc("RP", "20");
  ASSERT_TRUE(SetTrialOption("angle_features", "sincos", &o).ok());
  auto a = RunTrial(o, nullptr);
  ASSERT_TRUE(a.ok()) << a.status();
  TrialOptions full_options = TinyFitc("RP", "0");
  ASSERT_TRUE(SetTrialOption("angle_features", "sincos", &full_options).ok());
  auto full = RunTrial(full_options, nullptr);
  ASSERT_TRUE(full.ok()) << full.status();
  for (size_t e = 1; e < a->episodes.size(); ++e) {
    EXPECT_TRUE(std::isfinite(a->episodes[e].predicted_cost)) << e;
    EXPECT_TRUE(a->episodes[e].policy_parameters.allFinite()) << e;
    EXPECT_EQ(a->episodes[e].flags.non_finite_gradients, 0) << e;
  }
  EXPECT_TRUE(SameBits(full->episodes[1].predicted_cost, a->episodes[1].predicted_cost));
  EXPECT_NE(full->episodes[2].predicted_cost, a->episodes[2].predicted_cost);
}

}  // namespace trial_test
}  // namespace totalgrad::learner
