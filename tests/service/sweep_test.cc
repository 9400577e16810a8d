// Sweep files: parsing with positions, canonical form and hash, expansion
// through the trial runner's own option validation, and the shipped files.
#include "server/sweep/sweep_spec.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <regex>
#include <nlohmann/json.hpp>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"

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

// The cost estimate printed by `sweep submit` and `run`: additive over the
// jobs (twice the seeds, twice the cost), larger for a heavier protocol.
TEST(SweepSpecTest, CostEstimateAddsUpOverTheJobs) {
  auto estimate = [](const std::string& seeds, int steps) {
    auto spec = ParseSweepToml(absl::StrCat("name = \"c\"\n[grid]\nmethod = [\"RP\", \"TP\"]\nseed = ",
                                            seeds, "\n[protocol]\npolicy_steps = ", steps, "\n"),
                               "c.toml");
    EXPECT_TRUE(spec.ok()) << spec.status();
    auto cost = EstimateSweepCost(*spec);
    EXPECT_TRUE(cost.ok()) << cost.status();
    return *cost;
  };
  const SweepCostEstimate one = estimate("[1]", 600), two = estimate("[1, 2]", 600);
  EXPECT_EQ(one.trials, 2);
  EXPECT_EQ(two.trials, 4);
  EXPECT_GT(one.cpu_seconds, 0);
  EXPECT_NEAR(two.cpu_seconds, 2 * one.cpu_seconds, 1e-9 * one.cpu_seconds);
  EXPECT_LT(estimate("[1]", 60).cpu_seconds, 0.2 * one.cpu_seconds);
  EXPECT_NE(one.Text().find("CPU minutes for 2 trials"), std::string::npos) << one.Text();
  EXPECT_NE(estimate("[1, 2, 3, 4, 5, 6]", 600).Text().find("CPU hours for 12 trials"), std::string::npos);
  // Issue 29: a sweep of seconds said "about 0 CPU minutes".
  const SweepCostEstimate tiny = estimate("[1]", 1);
  ASSERT_LT(tiny.cpu_seconds, 90);
  EXPECT_NE(tiny.Text().find("CPU seconds for 2 trials"), std::string::npos) << tiny.Text();
  EXPECT_EQ(tiny.Text().find("about 0 "), std::string::npos) << tiny.Text();
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

// Issue 12.6: the order of the keys of [protocol] does not make another
// sweep (the canonical form sorts them); a sweep stored by an older build
// under the file-order hash is still recognised (LegacySpecHash).
TEST(SweepSpecTest, ProtocolKeyOrderNeverMatters) {
  TG_ASSERT_OK_AND_ASSIGN(SweepSpec a, ParseSweepToml(
      "name = \"o\"\n[grid]\nmethod = [\"RP\"]\n[protocol]\nepisodes = 2\nparticles = 8\n"
      "horizon = 10\n", "a"));
  TG_ASSERT_OK_AND_ASSIGN(SweepSpec b, ParseSweepToml(
      "name = \"o\"\n[grid]\nmethod = [\"RP\"]\n[protocol]\nhorizon = 10\nparticles = 8\n"
      "episodes = 2\n", "b"));
  std::vector<std::string> b_order;
  for (const auto& [key, value] : b.protocol) b_order.push_back(key);
  EXPECT_EQ(b_order, (std::vector<std::string>{"horizon", "particles", "episodes"}));
  TG_ASSERT_OK(CanonicalizeSpec(&a));
  TG_ASSERT_OK(CanonicalizeSpec(&b));
  EXPECT_EQ(CanonicalJson(a), CanonicalJson(b));
  EXPECT_EQ(SpecHash(a), SpecHash(b));
  // The hash of the old, unsorted canonical form differs, and is what the
  // coordinator also accepts for an already stored sweep.
  const std::string legacy = LegacySpecHash(b, b_order);
  EXPECT_NE(legacy, SpecHash(b));
  EXPECT_EQ(LegacySpecHash(a, {"episodes", "horizon", "particles"}), SpecHash(a));
  SweepSpec unsorted = b;
  unsorted.protocol = {{"horizon", "10"}, {"particles", "8"}, {"episodes", "2"}};
  EXPECT_EQ(legacy, SpecHash(unsorted));
}

// Issue 12.6: counts beyond what the service or the runner can hold are
// refused naming the limit, never wrapped around.
TEST(SweepSpecTest, CountsBeyondTheLimitsNameTheLimit) {
  auto episodes = ParseSweepToml(
      "name = \"big\"\n[grid]\nmethod = [\"RP\"]\n[protocol]\nepisodes = 2147483647\n",
      "big.toml");
  EXPECT_EQ(episodes.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(episodes.status().message().find(
                "big.toml:5:12: protocol.episodes: option 'episodes' is 2147483647; the service "
                "runs trials of at most 10000 learned episodes"),
            std::string::npos)
      << episodes.status();
  auto particles = ParseSweepToml(
      "name = \"big\"\n[grid]\nmethod = [\"RP\"]\n[protocol]\nparticles = 1e12\n", "big.toml");
  EXPECT_EQ(particles.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(particles.status().message().find(
                "protocol.particles: option 'particles': 1e+12 is out of range; counts are at "
                "most 2147483647"),
            std::string::npos)
      << particles.status();
  auto in_grid = ParseSweepToml(
      "name = \"big\"\n[grid]\nmethod = [\"RP\"]\nepisodes = [2, 20000]\n", "big.toml");
  EXPECT_NE(in_grid.status().message().find("grid.episodes[1]: option 'episodes' is 20000"),
            std::string::npos)
      << in_grid.status();
  auto seeds = ParseSweepToml(
      "name = \"big\"\n[grid]\nmethod = [\"RP\"]\n"
      "seed = { first = 9223372036854775807, count = 2 }\n",
      "big.toml");
  EXPECT_NE(seeds.status().message().find(
                "grid.seed: first + count - 1 exceeds 9223372036854775807"),
            std::string::npos)
      << seeds.status();
  // Seeds are JSON numbers for every reader: 2^53 - 1 is the largest taken.
  auto largest_seed = ParseSweepToml(
      "name = \"s\"\n[grid]\nmethod = [\"RP\"]\nseed = [9007199254740991]\n", "s.toml");
  EXPECT_TRUE(largest_seed.ok()) << largest_seed.status();
  auto seed_2_53 = ParseSweepToml(
      "name = \"s\"\n[grid]\nmethod = [\"RP\"]\nseed = [1, 9007199254740992]\n", "s.toml");
  EXPECT_EQ(seed_2_53.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(seed_2_53.status().message().find(
                "grid.seed[1]: seed 9007199254740992 is too large; the service takes seeds in "
                "[0, 2^53)"),
            std::string::npos)
      << seed_2_53.status();
  auto range_past_2_53 = ParseSweepToml(
      "name = \"s\"\n[grid]\nmethod = [\"RP\"]\n"
      "seed = { first = 9007199254740990, count = 3 }\n",
      "s.toml");
  EXPECT_NE(range_past_2_53.status().message().find("seed 9007199254740992 is too large"),
            std::string::npos)
      << range_past_2_53.status();
  auto protocol_seed = ParseSweepToml(
      "name = \"s\"\n[grid]\nmethod = [\"RP\"]\n[protocol]\nseed = 18446744073709551615\n",
      "s.toml");
  EXPECT_EQ(protocol_seed.status().code(), absl::StatusCode::kInvalidArgument)
      << protocol_seed.status();
  // The same limits for a spec that arrives over the wire (no file).
  SweepSpec spec;
  spec.name = "wire";
  spec.grid = {{"method", {"RP"}}};
  spec.protocol = {{"episodes", "2147483647"}};
  const absl::Status status = CanonicalizeSpec(&spec);
  EXPECT_NE(status.message().find("protocol.episodes: option 'episodes' is 2147483647"),
            std::string::npos)
      << status;
}

// Issue 28.5: numeric options are checked against the ranges of their
// option tables at submission: noise_k = 1e308 was accepted and failed three
// times at run time; now the sweep is refused naming the option, its value
// and the allowed range, in the grid and in the protocol.
TEST(SweepSpecTest, ValuesOutsideAnOptionsPhysicalRangeAreRefusedNamingTheRange) {
  auto in_grid = ParseSweepToml(
      "name = \"loud\"\n[grid]\nmethod = [\"RP\"]\nnoise_k = [1.0, 1e308]\n", "loud.toml");
  EXPECT_EQ(in_grid.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(in_grid.status().message().find(
                "option 'noise_k': 1e+308 is out of range: allowed 0 to 10000 (observation "
                "noise variance multiplier"),
            std::string::npos)
      << in_grid.status();
  auto in_protocol = ParseSweepToml(
      "name = \"heavy\"\n[grid]\nmethod = [\"RP\"]\n[protocol]\ngravity = -9.82\n",
      "heavy.toml");
  EXPECT_EQ(in_protocol.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(in_protocol.status().message().find(
                "option 'gravity': -9.82 is out of range: allowed 0 to 1000 (m/s^2)"),
            std::string::npos)
      << in_protocol.status();
  // The ends of a range are allowed.
  TG_EXPECT_OK(ParseSweepToml(
      "name = \"edge\"\n[grid]\nmethod = [\"RP\"]\nnoise_k = [0.0, 10000.0]\n", "edge.toml")
                   .status());
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
  // Horizons 1..1000 (each in its option's range), so that only the count
  // (10^6 jobs) is wrong.
  for (int i = 1; i <= 1000; ++i) many.push_back(std::to_string(i));
  spec.grid = {{"method", {"RP"}}, {"seed", many}, {"horizon", many}};
  const absl::Status status = CanonicalizeSpec(&spec);
  EXPECT_NE(status.message().find("more than 100000 jobs"), std::string::npos) << status;
}

// Every sweep file shipped in deploy/sweeps parses, canonicalises and
// expands to jobs, with the number of jobs its header announces where it
// announces one as "= N trials".
TEST(ShippedSweepsTest, EveryShippedSweepFileIsValid) {
  int files = 0;
  int announcing = 0;
  for (const auto& entry : std::filesystem::directory_iterator(
           std::string(TOTALGRAD_SOURCE_DIR) + "/deploy/sweeps")) {
    if (entry.path().extension() != ".toml") continue;
    SCOPED_TRACE(entry.path().string());
    ++files;
    std::string text;
    TG_ASSERT_OK_AND_ASSIGN(SweepSpec spec, LoadSweepFile(entry.path().string(), &text));
    TG_ASSERT_OK(CanonicalizeSpec(&spec));
    TG_ASSERT_OK_AND_ASSIGN(std::vector<ExpandedJob> jobs, ExpandJobs(spec));
    EXPECT_FALSE(jobs.empty());
    std::smatch announced;
    if (std::regex_search(text, announced, std::regex("= ([0-9,]+) trials"))) {
      std::string number = announced[1].str();
      number.erase(std::remove(number.begin(), number.end(), ','), number.end());
      int count = 0;
      ASSERT_TRUE(absl::SimpleAtoi(number, &count)) << announced[0].str();
      EXPECT_EQ(static_cast<int>(jobs.size()), count) << "the header announces " << count;
      ++announcing;
    }
  }
  EXPECT_GE(files, 6);
  EXPECT_GE(announcing, 4);  // table1, table1-tip-k1, balance-del, the follow-up
}

TEST(ShippedSweepsTest, DemoParsesAndIsSmall) {
  std::string text;
  TG_ASSERT_OK_AND_ASSIGN(SweepSpec spec,
                          LoadSweepFile(std::string(TOTALGRAD_SOURCE_DIR) + "/deploy/sweeps/demo.toml",
                                        &text));
  TG_ASSERT_OK(CanonicalizeSpec(&spec));
  TG_ASSERT_OK_AND_ASSIGN(std::vector<ExpandedJob> jobs, ExpandJobs(spec));
  EXPECT_EQ(spec.name, "demo");
  EXPECT_LE(jobs.size(), 12u);
  // "About a minute on 2 cores": at most 3 CPU minutes by the cost model.
  TG_ASSERT_OK_AND_ASSIGN(SweepCostEstimate cost, EstimateSweepCost(spec));
  EXPECT_LE(cost.cpu_seconds, 180.0) << cost.Text();
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

// ---- [[study]] entries (study jobs) ----

namespace study_entries {

// A tiny synthetic study (the study-file format of `totalgrad study`).
constexpr char kTinyStudy[] =
    R"({"problem": {"synthetic": {"data": 40, "horizon": 5, "basis_functions": 8}},
        "estimators": ["RP", "LR"], "particles": [10], "horizons": [5], "replicates": 3,
        "seed": 7, "reference": {"particles": 20, "replicates": 3}})";

std::string WriteFile(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
  return path;
}

class SweepStudyTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = totalgrad::testing::MakeTempDir(); }
  std::string dir_;
};

TEST_F(SweepStudyTest, StudyFromAFileAndInlineBecomeStudyJobsAfterTheTrials) {
  WriteFile(dir_ + "/tiny.json", kTinyStudy);
  const std::string sweep_file = WriteFile(dir_ + "/mixed.toml", absl::StrCat(R"(
name = "mixed"
[grid]
method = ["RP"]
seed = [1, 2]
[[study]]
name = "from-file"
file = "tiny.json"
[[study]]
name = "inline"
spec = ')", R"({"problem": {"synthetic": {"data": 30}}, "estimators": ["RP"], "particles": [5], "horizons": [3], "replicates": 2, "reference": {"replicates": 2, "particles": 10}}'
)"));
  TG_ASSERT_OK_AND_ASSIGN(SweepSpec spec, LoadSweepFile(sweep_file, nullptr));
  ASSERT_EQ(spec.studies.size(), 2u);
  EXPECT_EQ(spec.studies[0].name, "from-file");
  EXPECT_EQ(spec.studies[0].source, dir_ + "/tiny.json");
  EXPECT_EQ(spec.studies[1].source, "inline");
  TG_ASSERT_OK(CanonicalizeSpec(&spec));
  TG_ASSERT_OK_AND_ASSIGN(std::vector<ExpandedJob> jobs, ExpandJobs(spec));
  ASSERT_EQ(jobs.size(), 4u);
  EXPECT_EQ(jobs[0].kind, JobKind::kTrial);
  EXPECT_EQ(jobs[1].kind, JobKind::kTrial);
  EXPECT_EQ(jobs[2].kind, JobKind::kStudy);
  EXPECT_EQ(jobs[2].method, "study");
  EXPECT_EQ(jobs[2].variant, "from-file");
  EXPECT_EQ(jobs[2].seed, "7");
  EXPECT_EQ(jobs[2].episodes_expected, 0);
  EXPECT_TRUE(jobs[2].options.empty());
  EXPECT_EQ(jobs[3].seed, "1");  // the study default
  // The payload is the canonical JSON of the study file.
  const nlohmann::json payload = nlohmann::json::parse(jobs[2].payload);
  EXPECT_EQ(payload, nlohmann::json::parse(kTinyStudy));
  EXPECT_EQ(jobs[2].payload, payload.dump());
  // The studies are part of the hash.
  SweepSpec other = spec;
  other.studies[1].name = "renamed";
  EXPECT_NE(SpecHash(spec), SpecHash(other));
}

TEST_F(SweepStudyTest, AStudyOnlySweepNeedsNoGridAndKeepsTrialSweepsHashesUnchanged) {
  TG_ASSERT_OK_AND_ASSIGN(SweepSpec spec, ParseSweepToml(absl::StrCat(
      "name = \"only\"\n[[study]]\nname = \"s\"\nspec = '''", kTinyStudy, "'''\n"), dir_ + "/only.toml"));
  EXPECT_TRUE(spec.grid.empty());
  TG_ASSERT_OK(CanonicalizeSpec(&spec));
  TG_ASSERT_OK_AND_ASSIGN(std::vector<ExpandedJob> jobs, ExpandJobs(spec));
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0].kind, JobKind::kStudy);
  // A sweep without studies has no "studies" key: hashes of stored sweeps stay valid.
  TG_ASSERT_OK_AND_ASSIGN(SweepSpec trial, ParseSweepToml("name = \"t\"\n[grid]\nmethod = [\"RP\"]\n", "t"));
  TG_ASSERT_OK(CanonicalizeSpec(&trial));
  EXPECT_EQ(CanonicalJson(trial).find("studies"), std::string::npos);
  EXPECT_NE(CanonicalJson(spec).find("studies"), std::string::npos);
}

TEST_F(SweepStudyTest, TheSnapshotIsInlinedKeepingOnlyTheStudiedEpisode) {
  // The documented swing-up study's snapshot file (episodes 1..n).
  const std::string snapshot = std::string(TOTALGRAD_SOURCE_DIR) +
                               "/docs/error-vs-time/swingup_tp_seed1.json";
  WriteFile(dir_ + "/snap.json",
            absl::StrCat(R"({"problem": {"snapshot": ")", snapshot,
                         R"(", "episode": 3}, "estimators": ["RP"], "particles": [5],
                            "horizons": [3], "replicates": 2,
                            "reference": {"replicates": 2, "particles": 10}})"));
  TG_ASSERT_OK_AND_ASSIGN(SweepSpec spec, ParseSweepToml(
      "name = \"snap\"\n[[study]]\nname = \"ep3\"\nfile = \"snap.json\"\n", dir_ + "/snap.toml"));
  ASSERT_EQ(spec.studies.size(), 1u);
  const nlohmann::json payload = nlohmann::json::parse(spec.studies[0].spec_json);
  const nlohmann::json& inlined = payload["problem"]["snapshot"];
  ASSERT_TRUE(inlined.is_object()) << payload["problem"].dump().substr(0, 200);
  ASSERT_EQ(inlined["snapshots"].size(), 1u);
  EXPECT_EQ(inlined["snapshots"][0]["episode"], 3);
  // Self-contained: the coordinator's check accepts it without any file.
  TG_EXPECT_OK(CanonicalStudySpec(spec.studies[0].spec_json).status());
}

// `scene = "..."` in a [[study]]: a synthetic study runs on that scene (one
// file, several scenes, a job each); a snapshot study must already be on it.
TEST_F(SweepStudyTest, StudyEntriesTakeTheScene) {
  WriteFile(dir_ + "/syn.json",
            R"({"problem": {"synthetic": {"data": 20}}, "estimators": ["RP"], "particles": [5],
                "horizons": [3], "replicates": 2, "reference": {"replicates": 2, "particles": 10}})");
  TG_ASSERT_OK_AND_ASSIGN(
      SweepSpec spec,
      ParseSweepToml("name = \"scenes\"\n"
                     "[[study]]\nname = \"pendulum\"\nfile = \"syn.json\"\nscene = \"pendulum\"\n"
                     "[[study]]\nname = \"pendubot\"\nfile = \"syn.json\"\nscene = \"pendubot\"\n",
                     dir_ + "/scenes.toml"));
  ASSERT_EQ(spec.studies.size(), 2u);
  EXPECT_EQ(nlohmann::json::parse(spec.studies[0].spec_json)["problem"]["synthetic"]["scene"],
            "pendulum");
  EXPECT_EQ(nlohmann::json::parse(spec.studies[1].spec_json)["problem"]["synthetic"]["scene"],
            "pendubot");
  TG_ASSERT_OK_AND_ASSIGN(std::vector<ExpandedJob> jobs, ExpandJobs(spec));
  ASSERT_EQ(jobs.size(), 2u);
  EXPECT_NE(jobs[0].payload, jobs[1].payload);

  const std::string snapshot = std::string(TOTALGRAD_SOURCE_DIR) +
                               "/docs/error-vs-time/swingup_tp_seed1.json";
  WriteFile(dir_ + "/snap.json",
            absl::StrCat(R"({"problem": {"snapshot": ")", snapshot, R"(", "episode": 3}})"));
  TG_EXPECT_OK(ParseSweepToml("name = \"s\"\n[[study]]\nname = \"a\"\nfile = \"snap.json\"\n"
                              "scene = \"cartpole-swingup\"\n",
                              dir_ + "/snap.toml")
                   .status());
  for (const auto& [scene, expected] : std::vector<std::pair<std::string, std::string>>{
           {"pendulum", "snapshot is of scene 'cartpole-swingup', not 'pendulum'"},
           {"acrobot", "unknown scene 'acrobot'"}}) {
    const absl::StatusOr<SweepSpec> bad = ParseSweepToml(
        absl::StrCat("name = \"s\"\n[[study]]\nname = \"a\"\nfile = \"snap.json\"\nscene = \"",
                     scene, "\"\n"),
        dir_ + "/bad.toml");
    EXPECT_EQ(bad.status().code(), absl::StatusCode::kInvalidArgument) << scene;
    EXPECT_NE(bad.status().message().find(expected), std::string::npos) << bad.status();
    EXPECT_NE(bad.status().message().find("bad.toml:"), std::string::npos) << bad.status();
  }
}

// Each malformed entry: the error names the sweep file, the entry and what is wrong.
TEST_F(SweepStudyTest, MalformedStudyEntriesNameTheFileTheEntryAndTheProblem) {
  WriteFile(dir_ + "/bad_field.json",
            R"({"problem": {"synthetic": {}}, "replicates": 1})");
  WriteFile(dir_ + "/not_json.json", "{ this is not json");
  WriteFile(dir_ + "/no_snapshot.json",
            R"({"problem": {"snapshot": "missing-snapshot.json"}})");
  struct Case {
    std::string entry;
    std::vector<std::string> expected;  // substrings of the message
  } cases[] = {
      {"file = \"x.json\"\n", {"bad.toml:", "study[0]", "name: missing"}},
      {"name = \"a\"\nfile = \"bad_field.json\"\nspec = \"{}\"\n",
       {"bad.toml:", "study[0] 'a'", "exactly one of file"}},
      {"name = \"a\"\n", {"bad.toml:", "study[0] 'a'", "exactly one of file"}},
      {"name = \"a b\"\nfile = \"bad_field.json\"\n", {"bad.toml:", "not a valid name"}},
      {"name = \"a\"\nfile = \"absent.json\"\n", {"bad.toml:", "study[0] 'a'", "absent.json"}},
      {"name = \"a\"\nfile = \"bad_field.json\"\n",
       {"bad.toml:", "study[0] 'a'", "bad_field.json", "replicates"}},
      {"name = \"a\"\nfile = \"not_json.json\"\n",
       {"bad.toml:", "study[0] 'a'", "not_json.json", "not valid JSON"}},
      {"name = \"a\"\nfile = \"no_snapshot.json\"\n",
       {"bad.toml:", "study[0] 'a'", "missing-snapshot.json"}},
      {"name = \"a\"\nspec = '{\"problem\": {\"synthetic\": {}}, \"estimators\": [\"NOPE\"]}'\n",
       {"bad.toml:", "study[0] 'a'", "NOPE"}},
      {"name = \"a\"\nspec = '{not json'\n", {"bad.toml:", "study[0] 'a'", "not valid JSON"}},
      {"name = \"a\"\nspec = '{}'\nseeds = \"1\"\n", {"bad.toml:", "study[0].seeds", "unknown field"}},
      {"name = \"a\"\nfile = 3\n", {"bad.toml:", "study[0].file", "must be a string"}},
  };
  for (const Case& c : cases) {
    const absl::StatusOr<SweepSpec> spec =
        ParseSweepToml(absl::StrCat("name = \"bad\"\n[[study]]\n", c.entry), dir_ + "/bad.toml");
    ASSERT_FALSE(spec.ok()) << c.entry;
    EXPECT_EQ(spec.status().code(), absl::StatusCode::kInvalidArgument) << c.entry;
    for (const std::string& part : c.expected) {
      EXPECT_NE(spec.status().message().find(part), std::string::npos)
          << "entry:\n" << c.entry << "message: " << spec.status().message()
          << "\nmissing: " << part;
    }
  }
  // Two studies with one name.
  const absl::StatusOr<SweepSpec> twice = ParseSweepToml(
      absl::StrCat("name = \"bad\"\n[[study]]\nname = \"s\"\nspec = '''", kTinyStudy,
                   "'''\n[[study]]\nname = \"s\"\nspec = '''", kTinyStudy, "'''\n"),
      dir_ + "/bad.toml");
  ASSERT_FALSE(twice.ok());
  EXPECT_NE(twice.status().message().find("study[1] 's': name: repeats"), std::string::npos)
      << twice.status().message();
  // A study table that is not an array of tables.
  const absl::StatusOr<SweepSpec> table =
      ParseSweepToml("name = \"bad\"\n[study]\nname = \"s\"\n", dir_ + "/bad.toml");
  ASSERT_FALSE(table.ok());
  EXPECT_NE(table.status().message().find("[[study]]"), std::string::npos)
      << table.status().message();
}

// What the coordinator receives is re-checked: a spec naming a file (which
// it cannot read) or an invalid study is refused.
TEST_F(SweepStudyTest, TheCoordinatorsCheckRefusesPathsAndInvalidSpecs) {
  SweepSpec spec;
  spec.name = "wire";
  spec.studies.push_back({"s", R"({"problem": {"snapshot": "x.json"}})", "x"});
  absl::Status status = CanonicalizeSpec(&spec);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("study[0] 's': problem.snapshot"), std::string::npos)
      << status.message();
  spec.studies[0].spec_json = R"({"problem": {"synthetic": {}}, "replicates": 1})";
  status = CanonicalizeSpec(&spec);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("replicates"), std::string::npos) << status.message();
  spec.studies[0].spec_json = kTinyStudy;
  TG_EXPECT_OK(CanonicalizeSpec(&spec));
  // A study-only sweep may not carry a protocol (it would apply to nothing).
  spec.protocol.push_back({"episodes", "2"});
  EXPECT_FALSE(CanonicalizeSpec(&spec).ok());
}

// The shipped study sweep parses, inlines its snapshot and expands to study jobs.
TEST(ShippedSweepsTest, StudyDemoIsValid) {
  const std::string path = std::string(TOTALGRAD_SOURCE_DIR) + "/deploy/sweeps/study-demo.toml";
  TG_ASSERT_OK_AND_ASSIGN(SweepSpec spec, LoadSweepFile(path, nullptr));
  TG_ASSERT_OK(CanonicalizeSpec(&spec));
  TG_ASSERT_OK_AND_ASSIGN(std::vector<ExpandedJob> jobs, ExpandJobs(spec));
  ASSERT_FALSE(jobs.empty());
  int studies = 0;
  for (const auto& job : jobs) studies += job.kind == JobKind::kStudy;
  EXPECT_GE(studies, 1);
}

}  // namespace study_entries

}  // namespace
}  // namespace totalgrad::sweep
