// Trial checkpoints: the binary format round-trips exactly and refuses what
// it cannot read; a trial resumed from the checkpoint of any episode gives
// the same bits as the uninterrupted trial (full GP, FITC with its warm
// started inducing inputs, PILCO; the double pendulum's two torques with a
// particle method and with PILCO); EvaluatePolicy reproduces the trial's own
// evaluation of its final policy.
#include "core/learner/checkpoint.h"
#include "core/learner/evaluation.h"
#include "core/gaussian/angle_features.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace totalgrad::learner {
namespace checkpoint_test {

TrialOptions Tiny(const std::vector<std::pair<std::string, std::string>>& extra = {}) {
  TrialOptions o;
  std::vector<std::pair<std::string, std::string>> pairs = {
      {"episodes", "4"},      {"policy_steps", "4"},  {"particles", "8"},
      {"eval_rollouts", "3"}, {"horizon", "10"},      {"basis_functions", "10"},
      {"gp_iterations", "20"}, {"predicted_cost_particles", "20"}, {"seed", "5"}};
  pairs.insert(pairs.end(), extra.begin(), extra.end());
  for (const auto& [k, v] : pairs) EXPECT_TRUE(SetTrialOption(k, v, &o).ok()) << k << "=" << v;
  return o;
}

class Collector final : public TrialObserver {
 public:
  void OnEpisode(const EpisodeResult& r) override { results.push_back(r); }
  bool WantsCheckpoints() override { return true; }
  void OnCheckpoint(const TrialCheckpoint& c) override { checkpoints.push_back(c); }
  std::vector<EpisodeResult> results;
  std::vector<TrialCheckpoint> checkpoints;
};

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

template <typename M>
bool SameBits(const M& a, const M& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() &&
         (a.size() == 0 || std::memcmp(a.data(), b.data(), sizeof(double) * a.size()) == 0);
}

// Everything an episode result holds but its timing.
void ExpectSameResult(const EpisodeResult& x, const EpisodeResult& y) {
  SCOPED_TRACE(::testing::Message() << "episode " << x.episode);
  EXPECT_EQ(x.episode, y.episode);
  EXPECT_TRUE(SameBits(x.real_cost, y.real_cost));
  EXPECT_TRUE(SameBits(x.eval_cost_mean, y.eval_cost_mean));
  EXPECT_TRUE(SameBits(x.eval_cost_std, y.eval_cost_std));
  EXPECT_TRUE(SameBits(x.predicted_cost, y.predicted_cost));
  EXPECT_TRUE(SameBits(x.held_fraction, y.held_fraction));
  EXPECT_TRUE(SameBits(x.gradient_norm_mean, y.gradient_norm_mean));
  EXPECT_TRUE(SameBits(x.gradient_snr_last, y.gradient_snr_last));
  EXPECT_TRUE(SameBits(x.ess_median, y.ess_median));
  EXPECT_EQ(x.lr_share, y.lr_share);
  EXPECT_TRUE(SameBits(x.policy_parameters, y.policy_parameters));
  EXPECT_TRUE(SameBits(x.hyperparameters.log_lengthscales, y.hyperparameters.log_lengthscales));
  EXPECT_TRUE(SameBits(x.hyperparameters.log_signal_std, y.hyperparameters.log_signal_std));
  EXPECT_TRUE(SameBits(x.hyperparameters.log_noise_std, y.hyperparameters.log_noise_std));
  EXPECT_TRUE(SameBits(x.predicted_cost_mean_per_step, y.predicted_cost_mean_per_step));
  EXPECT_EQ(x.flags.non_finite_gradients, y.flags.non_finite_gradients);
  EXPECT_EQ(x.flags.gp_jitter, y.flags.gp_jitter);
  // The trajectories travel in the checkpoint (version 4), bit for bit.
  EXPECT_EQ(EncodeEpisodeTrajectories(x.trajectories), EncodeEpisodeTrajectories(y.trajectories));
}

// Runs `options` once uninterrupted, then resumed from the checkpoint of
// every episode, and expects the same results.
void ExpectResumedRunsEqualTheUninterruptedOne(const TrialOptions& options) {
  Collector whole;
  auto summary = RunTrial(options, &whole);
  ASSERT_TRUE(summary.ok()) << summary.status();
  ASSERT_EQ(whole.checkpoints.size(), static_cast<size_t>(options.episodes) + 1);
  for (const TrialCheckpoint& checkpoint : whole.checkpoints) {
    SCOPED_TRACE(::testing::Message() << "resumed after episode " << checkpoint.episode);
    // Through the wire format, as a worker gets it.
    auto decoded = DecodeCheckpoint(EncodeCheckpoint(checkpoint));
    ASSERT_TRUE(decoded.ok()) << decoded.status();
    Collector resumed;
    auto again = RunTrial(options, &resumed, &*decoded);
    ASSERT_TRUE(again.ok()) << again.status();
    ASSERT_EQ(resumed.results.size(), whole.results.size());
    for (size_t e = 0; e < whole.results.size(); ++e) {
      ExpectSameResult(resumed.results[e], whole.results[e]);
      // The restored episodes are reported from the checkpoint, timing and all.
      if (static_cast<int>(e) <= checkpoint.episode) {
        EXPECT_TRUE(SameBits(resumed.results[e].optimisation_seconds,
                             whole.results[e].optimisation_seconds));
      }
    }
    EXPECT_TRUE(SameBits(again->final_eval_cost, summary->final_eval_cost));
    EXPECT_EQ(again->success, summary->success);
    // Only the episodes after the checkpoint produce new checkpoints.
    EXPECT_EQ(resumed.checkpoints.size(),
              static_cast<size_t>(options.episodes - checkpoint.episode));
  }
}

TEST(TrialCheckpoint, EncodingRoundTripsExactly) {
  Collector collector;
  ASSERT_TRUE(RunTrial(Tiny({{"episodes", "2"}}), &collector).ok());
  ASSERT_EQ(collector.checkpoints.size(), 3u);
  for (const TrialCheckpoint& checkpoint : collector.checkpoints) {
    const std::string bytes = EncodeCheckpoint(checkpoint);
    auto decoded = DecodeCheckpoint(bytes);
    ASSERT_TRUE(decoded.ok()) << decoded.status();
    EXPECT_EQ(EncodeCheckpoint(*decoded), bytes);
    EXPECT_EQ(decoded->episode, checkpoint.episode);
    EXPECT_EQ(decoded->options, checkpoint.options);
    EXPECT_TRUE(SameBits(decoded->states, checkpoint.states));
    EXPECT_TRUE(SameBits(decoded->policy_parameters, checkpoint.policy_parameters));
    ASSERT_EQ(decoded->episodes.size(), checkpoint.episodes.size());
    // Episode 0 has no evaluation: NaN survives as NaN.
    EXPECT_TRUE(std::isnan(decoded->episodes[0].eval_cost_mean));
    // The last episode's rollout verdict (a field version 1 did not have).
    EXPECT_TRUE(SameBits(decoded->episodes.back().held_fraction,
                         checkpoint.episodes.back().held_fraction));
  }
  {
    const std::vector<EpisodeResult>& episodes = collector.checkpoints.back().episodes;
    EXPECT_FALSE(std::isnan(episodes.back().held_fraction));
    EXPECT_TRUE(std::isnan(episodes[1].held_fraction) && episodes.size() == 3);
  }
  // After episode 0 there is no model yet; after episode 1 there is.
  EXPECT_FALSE(collector.checkpoints[0].hyperparameters.has_value());
  EXPECT_TRUE(collector.checkpoints[1].hyperparameters.has_value());
  EXPECT_EQ(collector.checkpoints[2].forces.size(), 30);  // 3 episodes x horizon 10
}

// A version-2 checkpoint (issue 25's first build, 24478a0: fields after
// version 1 by name, doubles only), taken from a real trial of the
// table1-tip-k001 sweep (RP seed 10, k = 0.01, after learned episode 1),
// still reads: its fields as they were, the fields added since as absent.
TEST(TrialCheckpoint, VersionTwoStillReads) {
  std::ifstream in(std::string(TOTALGRAD_SOURCE_DIR) +
                       "/tests/core/learner/testdata/checkpoint_v2_rp_episode1.bin",
                   std::ios::binary);
  ASSERT_TRUE(in);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_EQ(bytes[8], 2);  // the format version's low byte
  auto decoded = DecodeCheckpoint(bytes);
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  EXPECT_EQ(decoded->episode, 1);
  ASSERT_EQ(decoded->episodes.size(), 2u);
  EXPECT_EQ(decoded->episodes[0].real_cost, 29.98998604479523);
  EXPECT_EQ(decoded->states.rows(), 60);  // two episodes of 30 steps
  EXPECT_TRUE(std::isnan(decoded->episodes[1].held_fraction));  // not the last episode
  EXPECT_TRUE(std::isnan(decoded->episodes[1].gradient_norm_mean));  // added after version 2
  EXPECT_TRUE(decoded->episodes[1].lr_share.empty());
  absl::StatusOr<TrialOptions> options = TrialOptionsFromStoredPairs(decoded->options);
  ASSERT_TRUE(options.ok());
  EXPECT_EQ(options->scene.noise_k, 0.01);
  EXPECT_EQ(options->verdict_rollouts, 100);
  EXPECT_TRUE(CheckResumable(*decoded, *options).ok());
  // Written again, it is this build's version and reads back the same.
  auto again = DecodeCheckpoint(EncodeCheckpoint(*decoded));
  ASSERT_TRUE(again.ok()) << again.status();
  EXPECT_TRUE(SameBits(again->policy_parameters, decoded->policy_parameters));
  ExpectSameResult(again->episodes[1], decoded->episodes[1]);
}

// A version-3 checkpoint (the Table-1 workers' build d8a6c09: typed named
// fields, no trajectories), taken from a real trial of the table1-tip-k001
// sweep (LR seed 10, job 84 attempt 2, after learned episode 3), still
// reads: its diagnostics as they were, its episodes without trajectories,
// and it resumes the trial it belongs to.
TEST(TrialCheckpoint, VersionThreeStillReads) {
  std::ifstream in(std::string(TOTALGRAD_SOURCE_DIR) +
                       "/tests/core/learner/testdata/checkpoint_v3_lr_episode3.bin",
                   std::ios::binary);
  ASSERT_TRUE(in);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_EQ(bytes[8], 3);  // the format version's low byte
  auto decoded = DecodeCheckpoint(bytes);
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  EXPECT_EQ(decoded->episode, 3);
  ASSERT_EQ(decoded->episodes.size(), 4u);
  // As the coordinator stored them (episodes rows of job 84 attempt 2).
  EXPECT_EQ(decoded->episodes[3].real_cost, 26.103428788707355);
  EXPECT_EQ(decoded->episodes[3].gradient_snr_mean, 0.9397306984496048);
  for (const EpisodeResult& e : decoded->episodes) EXPECT_TRUE(e.trajectories.empty());
  absl::StatusOr<TrialOptions> options = TrialOptionsFromStoredPairs(decoded->options);
  ASSERT_TRUE(options.ok());
  EXPECT_EQ(options->method, estimators::Method::kLr);
  EXPECT_TRUE(CheckResumable(*decoded, *options).ok());
  auto again = DecodeCheckpoint(EncodeCheckpoint(*decoded));
  ASSERT_TRUE(again.ok()) << again.status();
  ExpectSameResult(again->episodes[3], decoded->episodes[3]);
}

TEST(TrialCheckpoint, WhatCannotBeReadIsRefusedByName) {
  Collector collector;
  ASSERT_TRUE(RunTrial(Tiny({{"episodes", "1"}}), &collector).ok());
  const std::string bytes = EncodeCheckpoint(collector.checkpoints.back());
  const auto message = [](const absl::StatusOr<TrialCheckpoint>& decoded) {
    EXPECT_EQ(decoded.status().code(), absl::StatusCode::kInvalidArgument);
    return std::string(decoded.status().message());
  };
  EXPECT_NE(message(DecodeCheckpoint("definitely not a checkpoint")).find("not a totalgrad"),
            std::string::npos);
  std::string flipped = bytes;
  flipped[bytes.size() / 2] ^= 0x01;
  EXPECT_NE(message(DecodeCheckpoint(flipped)).find("checksum mismatch"), std::string::npos);
  EXPECT_NE(message(DecodeCheckpoint(bytes.substr(0, bytes.size() - 100))).find("checksum"),
            std::string::npos);
  std::string newer = bytes;
  newer[8] = 5;  // the format version's low byte
  EXPECT_NE(message(DecodeCheckpoint(newer)).find("format version 5; this build reads versions 1 to 4"),
            std::string::npos);
  // A checkpoint of another trial is not resumed.
  auto decoded = DecodeCheckpoint(bytes);
  ASSERT_TRUE(decoded.ok());
  const absl::Status other = CheckResumable(*decoded, Tiny({{"episodes", "1"}, {"seed", "6"}}));
  EXPECT_EQ(other.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(other.message().find("option seed is '6' here, the checkpoint has seed=5"),
            std::string::npos)
      << other;
  auto refused = RunTrial(Tiny({{"episodes", "1"}, {"seed", "6"}}), nullptr, &*decoded);
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kInvalidArgument);
}

TEST(TrialCheckpoint, ResumedParticleTrialGivesTheSameBits) {
  ExpectResumedRunsEqualTheUninterruptedOne(Tiny());
}

// gp_inducing = 15, horizon 10: episode 1 fits the full GP (N = 10), from
// episode 2 on FITC (N = 20, 30, ...), whose inducing inputs are warm started
// from the previous episode; the checkpoints carry them.
TEST(TrialCheckpoint, ResumedFitcTrialGivesTheSameBits) {
  const TrialOptions options = Tiny({{"gp_inducing", "15"}, {"episodes", "4"}});
  Collector probe;
  ASSERT_TRUE(RunTrial(options, &probe).ok());
  EXPECT_EQ(probe.checkpoints[1].inducing_inputs.rows(), 0);   // full GP so far
  EXPECT_EQ(probe.checkpoints[2].inducing_inputs.rows(), 15);  // FITC reached
  ExpectResumedRunsEqualTheUninterruptedOne(options);
}

TEST(TrialCheckpoint, ResumedPilcoTrialGivesTheSameBits) {
  ExpectResumedRunsEqualTheUninterruptedOne(
      Tiny({{"method", "PILCO"}, {"episodes", "3"}, {"gp_inducing", "15"}}));
}

// The double pendulum's two torques: forces N F in the checkpoint, resumed
// from every episode with the same bits; a checkpoint whose data do not fit
// the scene is refused by name.
TEST(TrialCheckpoint, ResumedTwoControlTrialGivesTheSameBits) {
  const TrialOptions options =
      Tiny({{"scene", "double-pendulum"}, {"method", "TP"}, {"episodes", "3"}, {"basis_functions", "6"}});
  Collector probe;
  ASSERT_TRUE(RunTrial(options, &probe).ok());
  const TrialCheckpoint& last = probe.checkpoints.back();
  EXPECT_EQ(last.states.rows(), 40);       // 4 episodes x horizon 10
  EXPECT_EQ(last.forces.size(), 2 * 40);   // two torques per transition
  ExpectResumedRunsEqualTheUninterruptedOne(options);

  TrialCheckpoint one_control = last;
  one_control.forces.conservativeResize(40);
  const absl::Status refused = CheckResumable(one_control, options);
  EXPECT_EQ(refused.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(refused.message().find("do not fit scene 'double-pendulum'"), std::string::npos)
      << refused;
  // Forces that are no whole number per transition cannot even be decoded.
  TrialCheckpoint ragged = last;
  ragged.forces.conservativeResize(41);
  const auto decoded = DecodeCheckpoint(EncodeCheckpoint(ragged));
  EXPECT_EQ(decoded.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(decoded.status().message().find("inconsistent sizes"), std::string::npos)
      << decoded.status();
}

// PILCO with two angles and two torques (its C x F pseudo-targets, BFGS per
// episode) resumes with the same bits too.
TEST(TrialCheckpoint, ResumedTwoControlPilcoTrialGivesTheSameBits) {
  ExpectResumedRunsEqualTheUninterruptedOne(Tiny({{"scene", "double-pendulum"},
                                                  {"method", "PILCO"},
                                                  {"episodes", "2"},
                                                  {"basis_functions", "6"}}));
}

// PILCO's linear policy (trial option policy = linear): the particle methods
// and PILCO resume from every episode's checkpoint with the same bits (its
// parameters are the checkpoint's policy vector), one control and two.
TEST(TrialCheckpoint, ResumedLinearPolicyTrialsGiveTheSameBits) {
  for (const TrialOptions& options :
       {Tiny({{"policy", "linear"}, {"episodes", "3"}}),
        Tiny({{"policy", "linear"}, {"method", "PILCO"}, {"episodes", "2"}}),
        Tiny({{"policy", "linear"}, {"scene", "double-pendulum"}, {"method", "TP"},
              {"episodes", "2"}}),
        Tiny({{"policy", "linear"}, {"scene", "double-pendulum"}, {"method", "PILCO"},
              {"episodes", "2"}})}) {
    SCOPED_TRACE(estimators::MethodName(options.method) + " " + options.scene.scene);
    Collector probe;
    ASSERT_TRUE(RunTrial(options, &probe).ok());
    ASSERT_FALSE(probe.checkpoints.empty());
    absl::StatusOr<tasks::Scene> scene = tasks::MakeScene(options.scene);
    ASSERT_TRUE(scene.ok());
    // F (Ep + 1) parameters: W and b on the policy's inputs (the raw state
    // or its angle features).
    const int ep = gaussian::FeatureDim(scene->state_dim(), FeatureAngles(options, *scene));
    EXPECT_EQ(probe.checkpoints.back().policy_parameters.size(),
              scene->control_dim() * (ep + 1));
    ExpectResumedRunsEqualTheUninterruptedOne(options);
  }
}

// `totalgrad evaluate` of a trial's final policy with the trial's seed and
// episode reproduces the trial's own evaluation, bit for bit (RBF and linear
// policies).
TEST(TrialCheckpoint, EvaluatePolicyReproducesTheTrialsEvaluation) {
  for (const TrialOptions& options :
       {Tiny({{"episodes", "2"}}), Tiny({{"method", "PILCO"}, {"episodes", "1"}}),
        Tiny({{"scene", "double-pendulum"}, {"episodes", "1"}}),
        Tiny({{"scene", "double-pendulum"}, {"method", "PILCO"}, {"episodes", "1"}}),
        Tiny({{"policy", "linear"}, {"episodes", "1"}}),
        Tiny({{"policy", "linear"}, {"method", "PILCO"}, {"episodes", "1"}})}) {
    auto summary = RunTrial(options, nullptr);
    ASSERT_TRUE(summary.ok()) << summary.status();
    const EpisodeResult& last = summary->episodes.back();
    auto evaluation = EvaluatePolicy(options, last.policy_parameters, last.episode,
                                     options.eval_rollouts);
    ASSERT_TRUE(evaluation.ok()) << evaluation.status();
    EXPECT_EQ(evaluation->costs.size(), static_cast<size_t>(options.eval_rollouts));
    EXPECT_TRUE(SameBits(evaluation->mean, last.eval_cost_mean)) << options.method;
    EXPECT_TRUE(SameBits(evaluation->std, last.eval_cost_std)) << options.method;
    auto wrong = EvaluatePolicy(options, Vector::Zero(3), last.episode, 2);
    EXPECT_EQ(wrong.status().code(), absl::StatusCode::kInvalidArgument);
  }
}

}  // namespace checkpoint_test
}  // namespace totalgrad::learner
