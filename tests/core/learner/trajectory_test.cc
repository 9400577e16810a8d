// Episode trajectories (issue 27 item 2): every episode of a trial records
// its real trajectory, each learned episode the model's prediction of it,
// the last the rollout verdict's rollouts; the trajectories re-costed give
// the stored costs bit for bit and re-classified give the stored verdict;
// the prediction is the particles' (PILCO's) mean and std; the format
// round-trips exactly and refuses what it cannot read; recording changes no
// number of the trial.
#include "core/learner/trajectory.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "core/learner/checkpoint.h"
#include "core/learner/evaluation.h"
#include "core/learner/trial.h"

namespace totalgrad::learner {
namespace trajectory_test {

TrialOptions Tiny(const std::string& method) {
  TrialOptions o;
  const std::vector<std::pair<std::string, std::string>> pairs = {
      {"method", method},      {"episodes", "2"},          {"policy_steps", "3"},
      {"particles", "8"},      {"eval_rollouts", "3"},     {"horizon", "10"},
      {"basis_functions", "8"}, {"gp_iterations", "15"},   {"predicted_cost_particles", "20"},
      {"seed", "3"},           {"verdict_rollouts", "5"},  {"verdict_hold_seconds", "0.2"}};
  for (const auto& [k, v] : pairs) EXPECT_TRUE(SetTrialOption(k, v, &o).ok()) << k << "=" << v;
  return o;
}

// The cost of a recorded trajectory as RunEpisode sums it: c(x_1) + ... + c(x_H).
double Recost(const tasks::Scene& scene, const StateTrajectory& t) {
  double total = 0;
  for (Eigen::Index row = 1; row < t.states.rows(); ++row)
    total += scene.cost->Value(t.states.row(row).transpose());
  return total;
}

// A tasks::Episode holding only what RolloutHeld reads (the true states).
tasks::Episode AsEpisode(const StateTrajectory& t) {
  tasks::Episode e;
  e.states = t.states;
  return e;
}

class TrajectoryTrialTest : public ::testing::TestWithParam<const char*> {};

TEST_P(TrajectoryTrialTest, EveryEpisodeRecordsWhatItDid) {
  const TrialOptions options = Tiny(GetParam());
  absl::StatusOr<TrialSummary> summary = RunTrial(options, nullptr);
  ASSERT_TRUE(summary.ok()) << summary.status();
  absl::StatusOr<tasks::Scene> scene = tasks::MakeScene(options.scene);
  ASSERT_TRUE(scene.ok());
  const int h = scene->horizon, d = scene->state_dim(), f = scene->control_dim();
  ASSERT_EQ(summary->episodes.size(), 3u);
  for (const EpisodeResult& e : summary->episodes) {
    SCOPED_TRACE(::testing::Message() << "episode " << e.episode);
    const EpisodeTrajectories& t = e.trajectories;
    ASSERT_EQ(t.real.states.rows(), h + 1);
    ASSERT_EQ(t.real.states.cols(), d);
    ASSERT_EQ(t.real.controls.rows(), h);
    ASSERT_EQ(t.real.controls.cols(), f);
    // Re-costed, the trajectory gives the stored cost, bit for bit.
    EXPECT_EQ(Recost(*scene, t.real), e.real_cost);
    for (Eigen::Index step = 0; step < h; ++step)
      EXPECT_LE(std::abs(t.real.controls(step, 0)), scene->max_control(0)) << step;
    if (e.episode == 0) {
      EXPECT_EQ(t.predicted_mean.size(), 0);
      EXPECT_EQ(t.predicted_std.size(), 0);
    } else {
      ASSERT_EQ(t.predicted_mean.rows(), h + 1);
      ASSERT_EQ(t.predicted_mean.cols(), d);
      ASSERT_EQ(t.predicted_std.rows(), h + 1);
      // Every prediction starts from the start distribution: mean near mu0,
      // std near initial_std (20 particles, or PILCO's exact moments).
      for (int m = 0; m < d; ++m) {
        EXPECT_NEAR(t.predicted_mean(0, m), scene->mu0(m), 4 * scene->initial_std(m)) << m;
        EXPECT_GE(t.predicted_std(h, m), 0.0);
      }
      EXPECT_TRUE(t.predicted_mean.allFinite());
      EXPECT_TRUE(t.predicted_std.allFinite());
    }
    if (e.episode == options.episodes) {
      // The verdict's rollouts, re-classified, give the stored fraction.
      ASSERT_EQ(t.verdict_rollouts.size(), 5u);
      int held = 0;
      for (const StateTrajectory& rollout : t.verdict_rollouts) {
        ASSERT_EQ(rollout.states.rows(), h + 1);
        held += RolloutHeld(*scene, AsEpisode(rollout), options.verdict_distance,
                            VerdictHoldSteps(options, *scene));
      }
      EXPECT_EQ(static_cast<double>(held) / 5, e.held_fraction);
      // The first eval_rollouts of them are the last evaluation's own.
      double sum = 0;
      for (int r = 0; r < options.eval_rollouts; ++r) sum += Recost(*scene, t.verdict_rollouts[r]);
      EXPECT_DOUBLE_EQ(sum / options.eval_rollouts, e.eval_cost_mean);
    } else {
      EXPECT_TRUE(t.verdict_rollouts.empty());
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Methods, TrajectoryTrialTest, ::testing::Values("TP", "PILCO"));

// The particle prediction is the particles' own mean and sample std: with
// predicted_cost_particles = 1 the std is 0 and the mean is that particle.
TEST(TrajectoryTest, OneParticleHasZeroSpread) {
  TrialOptions options = Tiny("RP");
  ASSERT_TRUE(SetTrialOption("predicted_cost_particles", "1", &options).ok());
  absl::StatusOr<TrialSummary> summary = RunTrial(options, nullptr);
  ASSERT_TRUE(summary.ok()) << summary.status();
  const EpisodeTrajectories& t = summary->episodes[1].trajectories;
  ASSERT_GT(t.predicted_std.size(), 0);
  EXPECT_EQ(t.predicted_std.cwiseAbs().maxCoeff(), 0.0);
  EXPECT_GT(t.predicted_mean.cwiseAbs().maxCoeff(), 0.0);
}

EpisodeTrajectories Small() {
  EpisodeTrajectories t;
  t.real.states = RowMatrix::Random(4, 2);
  t.real.controls = RowMatrix::Random(3, 1);
  t.predicted_mean = RowMatrix::Random(4, 2);
  t.predicted_std = RowMatrix::Random(4, 2).cwiseAbs();
  t.predicted_std(1, 1) = std::nan("");
  t.verdict_rollouts.push_back(t.real);
  t.verdict_rollouts.back().states(2, 0) = -0.0;
  return t;
}

TEST(TrajectoryFormatTest, RoundTripsExactly) {
  const EpisodeTrajectories t = Small();
  const std::string bytes = EncodeEpisodeTrajectories(t);
  absl::StatusOr<EpisodeTrajectories> back = DecodeEpisodeTrajectories(bytes);
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_EQ(EncodeEpisodeTrajectories(*back), bytes);
  EXPECT_TRUE(std::isnan(back->predicted_std(1, 1)));
  EXPECT_TRUE(std::signbit(back->verdict_rollouts[0].states(2, 0)));
  EXPECT_EQ(back->real.states, t.real.states);
  // 8 magic + 4 version + 4 matrices + 2 rollout matrices + count + checksum.
  const size_t doubles = 8 + 3 + 8 + 8 + 8 + 3;
  EXPECT_EQ(bytes.size(), 8 + 4 + 6 * 16 + 8 + 8 * doubles + 8);
}

TEST(TrajectoryFormatTest, RefusesWhatItCannotRead) {
  const std::string bytes = EncodeEpisodeTrajectories(Small());
  auto refused = [](const std::string& b, const std::string& says) {
    absl::StatusOr<EpisodeTrajectories> r = DecodeEpisodeTrajectories(b);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find(says), std::string::npos) << r.status();
  };
  refused("", "not totalgrad episode trajectories");
  refused("TGCKPT\0\0" + bytes.substr(8), "not totalgrad episode trajectories");
  std::string flipped = bytes;
  flipped[40] ^= 1;
  refused(flipped, "checksum");
  std::string version = bytes;
  version[8] = 9;
  refused(version, "format version 9");
  refused(bytes.substr(0, bytes.size() - 3), "checksum");
  EpisodeTrajectories bad = Small();
  bad.real.controls = RowMatrix::Random(4, 1);  // as many control rows as states
  refused(EncodeEpisodeTrajectories(bad), "real: states 4x2 do not fit controls 4x1");
  bad = Small();
  bad.predicted_std = RowMatrix::Random(3, 2);
  refused(EncodeEpisodeTrajectories(bad), "differ");
  bad = Small();
  bad.verdict_rollouts[0].states = RowMatrix::Random(2, 2);  // one state too many
  bad.verdict_rollouts[0].controls.resize(0, 0);
  refused(EncodeEpisodeTrajectories(bad), "verdict rollout 0: states 2x2 do not fit controls 0x0");
}

// A rollout that ended before its first step (the unicycle fell at once)
// keeps its start state and no control; it reads back as it was written.
TEST(TrajectoryFormatTest, AnEpisodeThatEndedAtOnceRoundTrips) {
  tasks::Episode fell;
  fell.steps = 0;
  fell.ended = true;
  fell.states = RowMatrix::Random(1, 10);
  fell.observations = fell.states;
  EpisodeTrajectories t = Small();
  t.verdict_rollouts.push_back(TrajectoryOfEpisode(fell));
  EXPECT_EQ(t.verdict_rollouts.back().controls.rows(), 0);
  absl::StatusOr<EpisodeTrajectories> back =
      DecodeEpisodeTrajectories(EncodeEpisodeTrajectories(t));
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_EQ(back->verdict_rollouts.back().states, fell.states);
  EXPECT_EQ(back->verdict_rollouts.back().controls.rows(), 0);
}

// Recording reads the computation: a trial's checkpoint of version 4 holds
// the trajectories, and a trial resumed from it reports them again.
TEST(TrajectoryTest, TheCheckpointCarriesThem) {
  class Keep final : public TrialObserver {
   public:
    void OnEpisode(const EpisodeResult&) override {}
    bool WantsCheckpoints() override { return true; }
    void OnCheckpoint(const TrialCheckpoint& c) override { last = EncodeCheckpoint(c); }
    std::string last;
  } keep;
  const TrialOptions options = Tiny("GTP");
  absl::StatusOr<TrialSummary> summary = RunTrial(options, &keep);
  ASSERT_TRUE(summary.ok()) << summary.status();
  absl::StatusOr<TrialCheckpoint> decoded = DecodeCheckpoint(keep.last);
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  ASSERT_EQ(decoded->episodes.size(), summary->episodes.size());
  for (size_t i = 0; i < decoded->episodes.size(); ++i) {
    EXPECT_EQ(EncodeEpisodeTrajectories(decoded->episodes[i].trajectories),
              EncodeEpisodeTrajectories(summary->episodes[i].trajectories))
        << i;
  }
  EXPECT_EQ(decoded->episodes.back().trajectories.verdict_rollouts.size(), 5u);
}

}  // namespace trajectory_test
}  // namespace totalgrad::learner
