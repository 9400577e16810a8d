// Trial snapshots as JSON files: every field, the trial's options included,
// comes back as it was written (the options as the whole struct: every field
// of every module's table).
#include "io/snapshot_json.h"

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>

#include "tests/testutil/every_option.h"
#include "tests/testutil/test_base.h"

namespace totalgrad::io {
namespace snapshot_json_test {

template <typename M>
bool SameBits(const M& a, const M& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() &&
         (a.size() == 0 || std::memcmp(a.data(), b.data(), sizeof(double) * a.size()) == 0);
}

learner::TrialSnapshot SnapshotWithEveryOption() {
  learner::TrialSnapshot s;
  s.episode = 2;
  s.options = learner::TrialOptionPairs(::totalgrad::testing::EveryOptionChanged());
  s.states = RowMatrix{{0.1, 1.0 / 3.0, -0.2, 2.5}, {1e-17, 3.0, 0.25, -7.0}};
  s.forces = Vector{{9.5, -1.0 / 7.0}};
  s.next_states = RowMatrix{{0.2, 0.5, -0.1, 2.0}, {0.0, 3.1, 0.5, -6.0}};
  s.hyperparameters.log_lengthscales = RowMatrix::Constant(4, 5, 0.125);
  s.hyperparameters.log_signal_std = Vector::Constant(4, -0.5);
  s.hyperparameters.log_noise_std = Vector::Constant(4, -1.0 / 3.0);
  s.policy_parameters_before = Vector{{1.0, 2.0, 1.0 / 11.0}};
  s.policy_parameters = Vector{{3.0, 4.0, 5.0}};
  return s;
}

void ExpectSameSnapshot(const learner::TrialSnapshot& a, const learner::TrialSnapshot& b) {
  EXPECT_EQ(a.episode, b.episode);
  absl::StatusOr<learner::TrialOptions> options_a = learner::TrialOptionsFromPairs(a.options);
  absl::StatusOr<learner::TrialOptions> options_b = learner::TrialOptionsFromPairs(b.options);
  TG_ASSERT_OK(options_a.status());
  TG_ASSERT_OK(options_b.status());
  EXPECT_TRUE(*options_a == *options_b);
  EXPECT_TRUE(SameBits(a.states, b.states));
  EXPECT_TRUE(SameBits(a.forces, b.forces));
  EXPECT_TRUE(SameBits(a.next_states, b.next_states));
  EXPECT_TRUE(SameBits(a.hyperparameters.log_lengthscales, b.hyperparameters.log_lengthscales));
  EXPECT_TRUE(SameBits(a.hyperparameters.log_signal_std, b.hyperparameters.log_signal_std));
  EXPECT_TRUE(SameBits(a.hyperparameters.log_noise_std, b.hyperparameters.log_noise_std));
  EXPECT_TRUE(SameBits(a.policy_parameters_before, b.policy_parameters_before));
  EXPECT_TRUE(SameBits(a.policy_parameters, b.policy_parameters));
}

TEST(SnapshotJson, EveryOptionAndNumberRoundTripsThroughTheText) {
  const learner::TrialSnapshot written = SnapshotWithEveryOption();
  const std::string text = SnapshotsToJson({written}).dump();
  absl::StatusOr<std::vector<learner::TrialSnapshot>> read = SnapshotsFromJson(nlohmann::json::parse(text));
  TG_ASSERT_OK(read.status());
  ASSERT_EQ(read->size(), 1u);
  ExpectSameSnapshot(written, read->front());
  // The options are the whole struct, every field changed.
  absl::StatusOr<learner::TrialOptions> options = learner::TrialOptionsFromPairs(read->front().options);
  TG_ASSERT_OK(options.status());
  EXPECT_TRUE(*options == ::totalgrad::testing::EveryOptionChanged());
}

TEST(SnapshotJson, EveryOptionRoundTripsThroughAFile) {
  const std::string path = (std::filesystem::path(::totalgrad::testing::MakeTempDir()) / "s.json").string();
  const learner::TrialSnapshot written = SnapshotWithEveryOption();
  TG_ASSERT_OK(WriteSnapshotFile(path, {written, written}));
  absl::StatusOr<std::vector<learner::TrialSnapshot>> read = ReadSnapshotFile(path);
  TG_ASSERT_OK(read.status());
  ASSERT_EQ(read->size(), 2u);
  ExpectSameSnapshot(written, (*read)[1]);
}

}  // namespace snapshot_json_test
}  // namespace totalgrad::io
