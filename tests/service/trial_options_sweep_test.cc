// Trial options through sweep files: a sweep whose protocol sets every option
// of every module's table (tests/testutil/every_option.h) expands to a job
// whose option pairs give back the whole struct, and the service's
// ResolveOptions keeps them as they are.
#include <gtest/gtest.h>

#include <string>

#include "absl/strings/str_cat.h"
#include "server/sweep/sweep_spec.h"
#include "tests/service/service_testutil.h"
#include "tests/testutil/every_option.h"

namespace totalgrad::sweep {
namespace {

TEST(TrialOptionsSweepTest, EveryFieldRoundTripsThroughASweepFile) {
  const learner::TrialOptions changed = ::totalgrad::testing::EveryOptionChanged();
  std::string toml = "name = \"every-option\"\n[grid]\n";
  std::string protocol = "[protocol]\n";
  for (const auto& [key, value] : learner::TrialOptionPairs(changed)) {
    // method and seed are grid axes (a sweep names its methods); the rest
    // is protocol, each value as TOML text.
    if (key == "method" || key == "seed") {
      absl::StrAppend(&toml, key, " = [\"", value, "\"]\n");
    } else {
      absl::StrAppend(&protocol, key, " = \"", value, "\"\n");
    }
  }
  TG_ASSERT_OK_AND_ASSIGN(SweepSpec spec, ParseSweepToml(toml + protocol, "every-option.toml"));
  TG_ASSERT_OK(CanonicalizeSpec(&spec));
  TG_ASSERT_OK_AND_ASSIGN(std::vector<ExpandedJob> jobs, ExpandJobs(spec));
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0].method, "GTP");
  EXPECT_EQ(jobs[0].seed, "42");
  absl::StatusOr<learner::TrialOptions> back = learner::TrialOptionsFromPairs(jobs[0].options);
  TG_ASSERT_OK(back.status());
  EXPECT_TRUE(*back == changed) << "a field did not survive the sweep file";
  TG_ASSERT_OK_AND_ASSIGN(OptionList resolved, ResolveOptions(jobs[0].options));
  EXPECT_EQ(resolved, jobs[0].options);
}

}  // namespace
}  // namespace totalgrad::sweep
