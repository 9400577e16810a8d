// LearnerTrialRunner's cost estimate (what a worker with a walltime weighs a
// granted trial by): the cost model of the trial its options make.
#include "worker/learner_runner.h"

#include <gtest/gtest.h>

#include "core/learner/cost_model.h"
#include "core/learner/trial_options.h"

namespace totalgrad::worker {
namespace {

JobInput Trial(const std::string& method, const std::string& episodes) {
  JobInput job;
  job.options = {{"method", method}, {"seed", "3"}, {"episodes", episodes}};
  return job;
}

TEST(LearnerTrialRunner, EstimatesATrialByTheCostModelOfItsOptions) {
  const LearnerTrialRunner runner;
  const JobInput job = Trial("RP", "4");
  absl::StatusOr<learner::TrialOptions> options =
      learner::TrialOptionsFromStoredPairs(job.options);
  ASSERT_TRUE(options.ok()) << options.status();
  const std::optional<double> estimate = runner.EstimateCpuSeconds(job);
  ASSERT_TRUE(estimate.has_value());
  EXPECT_GT(*estimate, 0);
  EXPECT_EQ(*estimate, learner::EstimateTrialCost(*options).total_cpu());
  // More learned episodes cost more.
  const std::optional<double> longer = runner.EstimateCpuSeconds(Trial("RP", "8"));
  ASSERT_TRUE(longer.has_value());
  EXPECT_GT(*longer, *estimate);
}

TEST(LearnerTrialRunner, HasNoEstimateForOptionsItCannotRun) {
  const LearnerTrialRunner runner;
  EXPECT_FALSE(runner.EstimateCpuSeconds(Trial("NOPE", "4")).has_value());
  EXPECT_FALSE(runner.EstimateCpuSeconds(Trial("RP", "-2")).has_value());
}

}  // namespace
}  // namespace totalgrad::worker
