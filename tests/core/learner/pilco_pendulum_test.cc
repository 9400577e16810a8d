// PILCO on PILCO's own simplest benchmark, the pendulum swing-up, with its
// saturating cost in closed form: after one learned episode the policy must
// have moved the pendulum. Regression test of the optimiser's
// parameterisation: optimising the RBF weights directly (instead of PILCO's
// pseudo-targets) stalled here after one line search with an exactly zero
// gradient, and the evaluation cost stayed at ~40 of 40.
#include <gtest/gtest.h>

#include <string>
#include <utility>
#include <vector>

#include "core/learner/trial.h"
#include "tests/testutil/test_base.h"

namespace totalgrad::learner {
namespace pilco_pendulum_test {

TEST(PilcoPendulum, OneLearnedEpisodeSwingsThePendulum) {
  TrialOptions o;
  for (const auto& [k, v] : std::vector<std::pair<std::string, std::string>>{
           {"scene", "pendulum"}, {"method", "PILCO"}, {"cost", "saturating"},
           {"episodes", "1"}, {"horizon", "40"}, {"basis_functions", "20"},
           {"eval_rollouts", "10"}, {"seed", "1"}}) {
    TG_ASSERT_OK(SetTrialOption(k, v, &o));
  }
  TG_ASSERT_OK_AND_ASSIGN(TrialSummary summary, RunTrial(o, nullptr));
  ASSERT_EQ(summary.episodes.size(), 2u);
  EXPECT_GT(summary.episodes[0].real_cost, 39.0);  // the random episode: hanging all along
  // Hanging all along costs ~1 per step (40); the learned policy spends
  // most of the horizon near the top.
  EXPECT_LT(summary.final_eval_cost, 30.0);
}

}  // namespace pilco_pendulum_test
}  // namespace totalgrad::learner
