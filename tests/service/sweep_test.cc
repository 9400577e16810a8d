// Sweep files: parsing with positions, canonical form and hash, expansion
// through the trial runner's own option validation, and the shipped files.
#include "server/sweep/sweep_spec.h"

#include <gtest/gtest.h>

#include "tests/service/service_testutil.h"

namespace totalgrad::sweep {
namespace {

TEST(SweepSpecTest, ParsesTheGridInFileOrderAndExpandsLastAxisFastest) {
  TG_ASSERT_OK_AND_ASSIGN(SweepSpec spec, ParseSweepToml(R"(
name = "order"
[grid]
seed = [1, 2]
noise_k = [0.01, 1.0]
method = ["RP"]
[protocol]
episodes = 2
)", "order.toml"));
  ASSERT_EQ(spec.grid.size(), 3u);
  EXPECT_EQ(spec.grid[0].key, "seed");
  EXPECT_EQ(spec.grid[1].key, "noise_k");
  TG_ASSERT_OK(CanonicalizeSpec(&spec));
  TG_ASSERT_OK_AND_ASSIGN(std::vector<ExpandedJob> jobs, ExpandJobs(spec));
  ASSERT_EQ(jobs.size(), 4u);
  EXPECT_EQ(jobs[0].seed, "1");
  EXPECT_EQ(jobs[1].seed, "1");
  EXPECT_EQ(jobs[2].seed, "2");
  EXPECT_EQ(jobs[0].variant, "noise_k=0.01");
  EXPECT_EQ(jobs[1].variant, "noise_k=1");
  EXPECT_EQ(jobs[0].method, "RP");
  EXPECT_EQ(jobs[0].episodes_expected, 3);
  // The job carries every option, so it can be re-run exactly.
  bool has_particles = false;
  for (const auto& [key, value] : jobs[0].options) has_particles |= key == "particles";
  EXPECT_TRUE(has_particles);
}

TEST(SweepSpecTest, EqualSweepsWrittenDifferentlyHaveTheSameHash) {
  TG_ASSERT_OK_AND_ASSIGN(SweepSpec a, ParseSweepToml(
      "name = \"h\"\n[grid]\nmethod = [\"RP\"]\nnoise_k = [1]\n[protocol]\nthreshold = 15\n", "a"));
  TG_ASSERT_OK_AND_ASSIGN(SweepSpec b, ParseSweepToml(
      "# comment\nname = \"h\"\n[grid]\nmethod = [ \"RP\" ]\nnoise_k = [1.0]\n"
      "[protocol]\nthreshold = 15.0\n", "b"));
  TG_ASSERT_OK(CanonicalizeSpec(&a));
  TG_ASSERT_OK(CanonicalizeSpec(&b));
  EXPECT_EQ(CanonicalJson(a), CanonicalJson(b));
  EXPECT_EQ(SpecHash(a), SpecHash(b));
  EXPECT_EQ(SpecHash(a).size(), 64u);
  b.protocol[0].second = "16";
  EXPECT_NE(SpecHash(a), SpecHash(b));
}

TEST(SweepSpecTest, RangesExpandToConsecutiveIntegers) {
  TG_ASSERT_OK_AND_ASSIGN(SweepSpec spec, ParseSweepToml(
      "name = \"r\"\n[grid]\nmethod = [\"RP\"]\nseed = { first = 10, count = 3 }\n", "r"));
  EXPECT_EQ(spec.grid[1].values, (std::vector<std::string>{"10", "11", "12"}));
  auto bad = ParseSweepToml("name = \"r\"\n[grid]\nmethod = [\"RP\"]\nseed = { first = 1 }\n", "r.toml");
  EXPECT_EQ(bad.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(bad.status().message().find("r.toml:4:8: grid.seed: a range must be"), std::string::npos)
      << bad.status();
}

TEST(SweepSpecTest, WholeSpecRulesNameTheField) {
  SweepSpec spec;
  spec.name = "ok";
  spec.grid = {{"method", {"RP"}}, {"seed", {"1"}}};
  spec.protocol = {{"seed", "2"}};
  absl::Status status = CanonicalizeSpec(&spec);
  EXPECT_NE(status.message().find("protocol.seed: also a grid axis"), std::string::npos) << status;
  spec.protocol.clear();
  spec.grid.push_back({"seed", {"3"}});
  status = CanonicalizeSpec(&spec);
  EXPECT_NE(status.message().find("grid.seed: the axis appears twice"), std::string::npos) << status;
  spec.grid = {{"seed", {"1"}}};
  status = CanonicalizeSpec(&spec);
  EXPECT_NE(status.message().find("grid.method: missing"), std::string::npos) << status;
  spec.grid = {{"method", {}}};
  status = CanonicalizeSpec(&spec);
  EXPECT_NE(status.message().find("grid.method: needs at least one value"), std::string::npos);
  spec.name = "../etc";
  EXPECT_EQ(CanonicalizeSpec(&spec).code(), absl::StatusCode::kInvalidArgument);
}

TEST(SweepSpecTest, TooManyJobsAreRefusedBeforeExpansion) {
  SweepSpec spec;
  spec.name = "huge";
  std::vector<std::string> many;
  for (int i = 0; i < 1000; ++i) many.push_back(std::to_string(i));
  spec.grid = {{"method", {"RP"}}, {"seed", many}, {"horizon", many}};
  const absl::Status status = CanonicalizeSpec(&spec);
  EXPECT_NE(status.message().find("more than 100000 jobs"), std::string::npos) << status;
}

TEST(ShippedSweepsTest, DemoParsesAndIsSmall) {
  std::string text;
  TG_ASSERT_OK_AND_ASSIGN(SweepSpec spec,
                          LoadSweepFile(std::string(TOTALGRAD_SOURCE_DIR) + "/deploy/sweeps/demo.toml",
                                        &text));
  TG_ASSERT_OK(CanonicalizeSpec(&spec));
  TG_ASSERT_OK_AND_ASSIGN(std::vector<ExpandedJob> jobs, ExpandJobs(spec));
  EXPECT_EQ(spec.name, "demo");
  EXPECT_LE(jobs.size(), 8u);
}

// table1.toml lists every method of the paper; it is valid exactly when the
// trial runner knows all of them, and otherwise refused at the first unknown
// method's line.
TEST(ShippedSweepsTest, Table1IsValidOrNamesTheFirstMissingMethod) {
  const std::string path = std::string(TOTALGRAD_SOURCE_DIR) + "/deploy/sweeps/table1.toml";
  absl::StatusOr<SweepSpec> spec = LoadSweepFile(path, nullptr);
  if (!spec.ok()) {
    EXPECT_NE(spec.status().message().find(path + ":"), std::string::npos) << spec.status();
    EXPECT_NE(spec.status().message().find("grid.method["), std::string::npos) << spec.status();
    EXPECT_NE(spec.status().message().find("unknown method"), std::string::npos) << spec.status();
    return;
  }
  TG_ASSERT_OK(CanonicalizeSpec(&*spec));
  TG_ASSERT_OK_AND_ASSIGN(std::vector<ExpandedJob> jobs, ExpandJobs(*spec));
  EXPECT_EQ(jobs.size(), 9u * 2 * 2 * 100);
}

}  // namespace
}  // namespace totalgrad::sweep
