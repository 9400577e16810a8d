// Trial options through sweep files: a sweep whose protocol sets every option
// of every module's table (tests/testutil/every_option.h) expands to a job
// whose option pairs give back the whole struct, and the service's
// ResolveOptions keeps them as they are.
#include <gtest/gtest.h>

#include <map>
#include <string>
#include <utility>

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
  TG_ASSERT_OK_AND_ASSIGN(OptionPairs resolved, ResolveOptions(jobs[0].options));
  EXPECT_EQ(resolved, jobs[0].options);
}

// Issue 29: a grid over scenes stores each job with its own scene's horizon
// and threshold unless the protocol sets them; set, they hold for every scene.
TEST(TrialOptionsSweepTest, EachJobStoresItsScenesHorizonAndThreshold) {
  const std::string toml = R"(name = "scenes"
[grid]
method = ["RP"]
seed = [1]
scene = ["pendulum", "cartpole-swingup", "pendubot"]
[protocol]
episodes = 1
)";
  const auto value_of = [](const ExpandedJob& job, const std::string& key) {
    for (const auto& [k, v] : job.options)
      if (k == key) return v;
    return std::string("(absent)");
  };
  TG_ASSERT_OK_AND_ASSIGN(SweepSpec spec, ParseSweepToml(toml, "scenes.toml"));
  TG_ASSERT_OK(CanonicalizeSpec(&spec));
  TG_ASSERT_OK_AND_ASSIGN(std::vector<ExpandedJob> jobs, ExpandJobs(spec));
  ASSERT_EQ(jobs.size(), 3u);
  std::map<std::string, std::pair<std::string, std::string>> by_scene;
  for (const ExpandedJob& job : jobs)
    by_scene[value_of(job, "scene")] = {value_of(job, "horizon"), value_of(job, "threshold")};
  EXPECT_EQ(by_scene["pendulum"], std::make_pair(std::string("40"), std::string("20")));
  EXPECT_EQ(by_scene["cartpole-swingup"], std::make_pair(std::string("30"), std::string("15")));
  EXPECT_EQ(by_scene["pendubot"], std::make_pair(std::string("60"), std::string("30")));

  TG_ASSERT_OK_AND_ASSIGN(SweepSpec fixed,
                          ParseSweepToml(toml + "horizon = 25\nthreshold = 9\n", "fixed.toml"));
  TG_ASSERT_OK(CanonicalizeSpec(&fixed));
  TG_ASSERT_OK_AND_ASSIGN(std::vector<ExpandedJob> fixed_jobs, ExpandJobs(fixed));
  for (const ExpandedJob& job : fixed_jobs) {
    EXPECT_EQ(value_of(job, "horizon"), "25");
    EXPECT_EQ(value_of(job, "threshold"), "9");
  }
}

}  // namespace
}  // namespace totalgrad::sweep
