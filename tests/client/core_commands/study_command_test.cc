// `totalgrad trial --snapshot-episodes` and `totalgrad study FILE`: snapshot
// files round-trip bit for bit, study files are parsed with every error
// named, and a tiny study runs end to end from a trial's snapshot to the
// table, CSV, JSON and gnuplot plots.
#include "client/core_commands/study_format.h"
#include "client/core_commands/study_plots.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <limits>
#include <cstdio>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "client/core_commands/commands.h"
#include "tests/client/core_commands/run_command.h"
#include "core/common/rng.h"
#include "core/diff/gradient_checker.h"
#include "core/estimators/estimator.h"
#include "io/snapshot_json.h"
#include "io/study_file.h"
#include "io/study_results.h"
#include "tests/testutil/testutil.h"

namespace totalgrad::cli {
namespace study_command_test {

using ::testing::HasSubstr;
// The study file parser and snapshot files live in core/study; the table and
// plots in the CLI: this file tests both, as `totalgrad study` uses them.
using io::InlineStudyDocument;
using io::LoadStudyProblem;
using io::ParseEpisodeList;
using io::ParseStudySpec;
using io::ReadSnapshotFile;
using io::ReadStudyDocument;
using io::SnapshotsFromJson;
using io::SnapshotsToJson;
using io::StudySpec;
using io::WriteSnapshotFile;

using testing_support::CommandRun;
using testing_support::RunCommand;

std::string Dir(const std::string& name) { return testing_support::FreshDir(name); }

void Write(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
}

const std::vector<std::string> kTinyTrial = {
    "trial", "--episodes", "2", "--policy-steps", "3", "--particles", "10", "--horizon", "8",
    "--basis-functions", "6", "--eval-rollouts", "1", "--gp-iterations", "10", "--seed", "4"};

TEST(EpisodeList, ParsesAndNamesBadEntries) {
  absl::StatusOr<std::vector<int>> e = ParseEpisodeList("1, 5,10");
  TG_ASSERT_OK(e.status());
  EXPECT_EQ(*e, (std::vector<int>{1, 5, 10}));
  EXPECT_THAT(std::string(ParseEpisodeList("1,x").status().message()), HasSubstr("'x'"));
  EXPECT_THAT(std::string(ParseEpisodeList("0").status().message()), HasSubstr("positive"));
  EXPECT_FALSE(ParseEpisodeList("").ok());
}

TEST(TrialSnapshots, FileRoundTripsBitForBit) {
  const std::string dir = Dir("snapshots_round_trip");
  const std::string file = dir + "/s.json";
  std::vector<std::string> args = kTinyTrial;
  for (const char* a : {"--snapshot-episodes", "1,2", "--snapshot-file"}) args.push_back(a);
  args.push_back(file);
  const CommandRun run = RunCommand(args);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  absl::StatusOr<std::vector<learner::TrialSnapshot>> read = ReadSnapshotFile(file);
  TG_ASSERT_OK(read.status());
  ASSERT_EQ(read->size(), 2u);
  EXPECT_EQ((*read)[0].episode, 1);
  EXPECT_EQ((*read)[1].episode, 2);
  EXPECT_EQ((*read)[1].states.rows(), 16);
  // Writing what was read and reading it again changes nothing, bit for bit.
  TG_ASSERT_OK(WriteSnapshotFile(dir + "/t.json", *read));
  absl::StatusOr<std::vector<learner::TrialSnapshot>> again = ReadSnapshotFile(dir + "/t.json");
  TG_ASSERT_OK(again.status());
  for (size_t i = 0; i < 2; ++i) {
    const auto &a = (*read)[i], &b = (*again)[i];
    EXPECT_EQ(a.options, b.options);
    EXPECT_EQ(a.states, b.states);
    EXPECT_EQ(a.forces, b.forces);
    EXPECT_EQ(a.next_states, b.next_states);
    EXPECT_EQ(a.hyperparameters.log_lengthscales, b.hyperparameters.log_lengthscales);
    EXPECT_EQ(a.hyperparameters.log_signal_std, b.hyperparameters.log_signal_std);
    EXPECT_EQ(a.hyperparameters.log_noise_std, b.hyperparameters.log_noise_std);
    EXPECT_EQ(a.policy_parameters_before, b.policy_parameters_before);
    EXPECT_EQ(a.policy_parameters, b.policy_parameters);
  }
  // The snapshot rebuilds the trial's model: the predicted cost the trial
  // printed (episode 2, --json run) equals a rollout on the rebuilt problem.
  // (Checked bit for bit in tests/core/study; here only that it loads.)
  absl::StatusOr<std::unique_ptr<study::FrozenProblem>> p =
      study::FrozenProblemFromSnapshot((*read)[1], study::SnapshotPolicy::kAfter);
  TG_ASSERT_OK(p.status());
}

TEST(TrialSnapshots, BadEpisodeListIsUsageError) {
  std::vector<std::string> args = kTinyTrial;
  args.push_back("--snapshot-episodes");
  args.push_back("1,two");
  const CommandRun run = RunCommand(args);
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_THAT(run.err, HasSubstr("'two'"));
}

TEST(SnapshotJson, ErrorsNameTheField) {
  nlohmann::json doc = {{"format", "totalgrad-trial-snapshots"}, {"version", 1}};
  EXPECT_THAT(std::string(SnapshotsFromJson(doc).status().message()), HasSubstr("snapshots"));
  doc["snapshots"] = nlohmann::json::array({{{"episode", 1}, {"options", nlohmann::json::object()},
                                             {"states", {{0, 0, 0, 0}, {1, 2, 3}}}}});
  EXPECT_THAT(std::string(SnapshotsFromJson(doc).status().message()),
              HasSubstr("snapshots[0].states[1]: has 3 entries"));
  EXPECT_THAT(std::string(SnapshotsFromJson(nlohmann::json::object()).status().message()),
              HasSubstr("format"));
}

TEST(ParseStudySpec, DefaultsAndNamedErrors) {
  nlohmann::json doc = {{"problem", {{"snapshot", "snaps.json"}}}};
  absl::StatusOr<StudySpec> spec = ParseStudySpec(doc, "/base");
  TG_ASSERT_OK(spec.status());
  EXPECT_TRUE(spec->from_snapshot);
  EXPECT_EQ(spec->snapshot_file, "/base/snaps.json");
  EXPECT_EQ(spec->snapshot_policy, study::SnapshotPolicy::kBefore);
  EXPECT_EQ(spec->options.estimators.size(), study::DefaultEstimators().size());
  EXPECT_EQ(spec->options.particles, (std::vector<int>{10, 30, 100, 300, 1000, 3000}));
  EXPECT_EQ(spec->options.horizons, (std::vector<int>{10, 30, 60, 100}));

  doc = {{"problem", {{"synthetic", {{"data", 30}, {"seed", 3}}}}},
         {"estimators", {"RP", {{"label", "LR(plain)"}, {"method", "LR"},
                               {"options", {{"lr_weights", "plain"}, {"forced_k_lr", 0.5}}}}}},
         {"particles", {5, 50}},
         {"reference", {{"particles", 77}}}};
  spec = ParseStudySpec(doc, "");
  TG_ASSERT_OK(spec.status());
  EXPECT_FALSE(spec->from_snapshot);
  EXPECT_EQ(spec->synthetic.data, 30);
  EXPECT_EQ(spec->synthetic.seed, 3u);
  ASSERT_EQ(spec->options.estimators.size(), 2u);
  EXPECT_EQ(spec->options.estimators[1].label, "LR(plain)");
  EXPECT_EQ(spec->options.estimators[1].options.lr_weights, estimators::LrWeights::kPlain);
  EXPECT_EQ(spec->options.estimators[1].options.forced_k_lr, 0.5);
  EXPECT_EQ(spec->options.reference.particles, 77);
  EXPECT_EQ(spec->synthetic_angle_features, learner::AngleFeatures::kAuto);
  doc = {{"problem", {{"synthetic", {{"scene", "pendubot"}, {"angle_features", "raw"}}}}}};
  spec = ParseStudySpec(doc, "");
  TG_ASSERT_OK(spec.status());
  EXPECT_EQ(spec->synthetic.scene, "pendubot");
  EXPECT_EQ(spec->synthetic_angle_features, learner::AngleFeatures::kRaw);

  struct Case {
    nlohmann::json doc;
    std::string want;
  };
  const nlohmann::json synthetic = {{"synthetic", nlohmann::json::object()}};
  for (const Case& c : std::vector<Case>{
           {{{"estimators", {"RP"}}}, "missing object 'problem'"},
           {{{"problem", synthetic}, {"particle", {1}}}, "unknown field 'particle'"},
           {{{"problem", {{"snapshot", 3}}}}, "problem.snapshot"},
           {{{"problem", {{"snapshot", "a"}, {"policy", "middle"}}}}, "problem.policy"},
           {{{"problem", synthetic}, {"estimators", {"XYZ"}}}, "XYZ"},
           {{{"problem", synthetic},
             {"estimators", {{{"method", "LR"}, {"options", {{"lr_weights", "heavy"}}}}}}},
            "heavy"},
           {{{"problem", synthetic},
             {"estimators", {{{"method", "LR"}, {"options", {{"colour", "red"}}}}}}},
            "unknown estimator option 'colour'"},
           {{{"problem", synthetic}, {"horizons", {10, "x"}}}, "horizons[1]"},
           {{{"problem", synthetic}, {"replicates", 1}}, "replicates"},
           {{{"problem", synthetic}, {"reference", {{"estimators", {"PILCO"}}}}}, "PILCO"},
           {{{"problem", {{"synthetic", {{"scene", "acrobot"}}}}}}, "unknown scene 'acrobot'"},
           {{{"problem", {{"synthetic", {{"scene", "unicycle"}}}}}},
            "problem.synthetic.scene: 'unicycle' has no studies yet: "},
           {{{"problem", {{"synthetic", {{"angle_features", "polar"}}}}}}, "'polar'"}}) {
    const absl::StatusOr<StudySpec> s = ParseStudySpec(c.doc, "");
    EXPECT_EQ(s.status().code(), absl::StatusCode::kInvalidArgument) << c.doc.dump();
    EXPECT_THAT(std::string(s.status().message()), HasSubstr(c.want)) << c.doc.dump();
  }
}

// From a trial to plots: the trial saves a snapshot, the study file names it
// (relative path), the command prints the table and writes every output.
TEST(StudyCommand, EndToEndFromATrialSnapshot) {
  const std::string dir = Dir("study_end_to_end");
  std::vector<std::string> args = kTinyTrial;
  args.push_back("--snapshot-episodes");
  args.push_back("2");
  args.push_back("--snapshot-file");
  args.push_back(dir + "/snaps.json");
  ASSERT_EQ(RunCommand(args).exit_code, 0);
  Write(dir + "/study.json", R"JSON({
    "problem": {"snapshot": "snaps.json", "episode": 2},
    "estimators": ["RP", "TP", {"label": "LR(plain,loo)", "method": "LR",
                   "options": {"lr_weights": "plain", "lr_baseline": "loo"}}, "PILCO"],
    "particles": [10, 40], "horizons": [4, 8], "replicates": 4,
    "reference": {"particles": 100, "replicates": 10}, "sweep_particles": 40})JSON");
  const std::string out = dir + "/out";
  CommandRun run = RunCommand({"study", dir + "/study.json", "--output-dir", out, "--quiet"});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_THAT(run.out, HasSubstr("episode 2"));
  EXPECT_THAT(run.out, HasSubstr("reference gradients"));
  EXPECT_THAT(run.out, HasSubstr("LR(plain,loo)"));
  for (const char* f : {"table.txt", "table.csv", "references.csv", "results.json",
                        "work_precision.gp", "horizon_sweep.gp", "floor.dat"}) {
    EXPECT_TRUE(std::filesystem::exists(out + "/" + f)) << f;
  }
  std::ifstream csv(out + "/table.csv");
  int lines = 0;
  for (std::string line; std::getline(csv, line);) ++lines;
  EXPECT_EQ(lines, 1 + 3 * 2 * 2 + 2);  // header, 3 particle methods x 2 P x 2 H, PILCO x 2 H
  std::ifstream js(out + "/results.json");
  const nlohmann::json doc = nlohmann::json::parse(js);
  EXPECT_EQ(doc.at("cells").size(), 14u);
  EXPECT_EQ(doc.at("references").size(), 2u);
  EXPECT_EQ(doc["references"][0]["gradient"].size(), doc["num_parameters"].get<size_t>());
  if (std::system("gnuplot --version > /dev/null 2>&1") == 0) {
    for (const char* f : {"work_precision.png", "horizon_sweep.png", "work_precision.pdf",
                          "horizon_sweep.pdf"}) {
      ASSERT_TRUE(std::filesystem::exists(out + "/" + f)) << f;
      EXPECT_GT(std::filesystem::file_size(out + "/" + f), 1000u) << f;
    }
    std::ifstream pdf(out + "/work_precision.pdf");
    std::string magic(4, ' ');
    pdf.read(magic.data(), 4);
    EXPECT_EQ(magic, "%PDF");
    // Every point of the work-precision plot carries its P.
    std::ifstream script(out + "/work_precision.gp");
    const std::string text((std::istreambuf_iterator<char>(script)), std::istreambuf_iterator<char>());
    EXPECT_THAT(text, HasSubstr("sprintf('%d', $1) : '') with labels"));
  }
  // CSV and JSON on stdout.
  run = RunCommand({"study", dir + "/study.json", "--format", "csv", "--quiet"});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_THAT(run.out, HasSubstr("estimator,method,particles,horizon"));
  run = RunCommand({"study", dir + "/study.json", "--format", "json", "--quiet"});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_EQ(nlohmann::json::parse(run.out).at("cells").size(), 14u);
}

TEST(StudyCommand, BadFilesExitTwoNamingTheProblem) {
  const std::string dir = Dir("study_bad");
  CommandRun run = RunCommand({"study", dir + "/missing.json"});
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_THAT(run.err, HasSubstr("cannot open"));
  Write(dir + "/bad.json", "{not json");
  run = RunCommand({"study", dir + "/bad.json"});
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_THAT(run.err, HasSubstr("not valid JSON"));
  Write(dir + "/nosnap.json", R"({"problem": {"snapshot": "nowhere.json"}})");
  run = RunCommand({"study", dir + "/nosnap.json"});
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_THAT(run.err, HasSubstr("nowhere.json"));
}


// A sweep's [[study]] may name the scene: it becomes a synthetic study's
// scene; a snapshot study must already be on it; unknown scenes are named.
TEST(SetStudyScene, SetsSyntheticScenesAndChecksSnapshots) {
  const nlohmann::json synthetic = {{"problem", {{"synthetic", {{"data", 30}}}}}};
  absl::StatusOr<nlohmann::json> set = io::SetStudyScene(synthetic, "pendubot");
  TG_ASSERT_OK(set.status());
  EXPECT_EQ((*set)["problem"]["synthetic"]["scene"], "pendubot");
  EXPECT_EQ((*set)["problem"]["synthetic"]["data"], 30);
  EXPECT_THAT(std::string(io::SetStudyScene(synthetic, "acrobot").status().message()),
              HasSubstr("unknown scene 'acrobot'"));
  // A listed scene without trials has no study either, and says why.
  EXPECT_THAT(std::string(io::SetStudyScene(synthetic, "unicycle").status().message()),
              HasSubstr("scene: 'unicycle' has no studies yet: "));
  EXPECT_THAT(std::string(io::SetStudyScene({{"problem", {{"snapshot", "s.json"}}}}, "pendulum")
                              .status()
                              .message()),
              HasSubstr("inlined snapshot"));

  const std::string dir = Dir("study_scene");
  std::vector<std::string> args = kTinyTrial;
  for (const char* a : {"--snapshot-episodes", "1", "--snapshot-file"}) args.push_back(a);
  args.push_back(dir + "/snaps.json");
  ASSERT_EQ(RunCommand(args).exit_code, 0);
  absl::StatusOr<nlohmann::json> inlined =
      InlineStudyDocument({{"problem", {{"snapshot", "snaps.json"}}}}, dir);
  TG_ASSERT_OK(inlined.status());
  TG_EXPECT_OK(io::SetStudyScene(*inlined, "cartpole-swingup").status());
  EXPECT_THAT(std::string(io::SetStudyScene(*inlined, "pendulum").status().message()),
              HasSubstr("snapshot is of scene 'cartpole-swingup', not 'pendulum'"));
}

// A study on another scene end to end (a synthetic pendulum problem), its
// results.json read back unchanged, and `study summary` over it: the
// Markdown table and the JSON name the winner per horizon and time.
TEST(StudyCommand, SceneStudyAndItsSummary) {
  const std::string dir = Dir("study_summary");
  Write(dir + "/study.json", R"JSON({
    "problem": {"synthetic": {"scene": "pendulum", "data": 40}},
    "estimators": ["RP", "LR", "PILCO"],
    "particles": [10, 40, 160], "horizons": [4], "replicates": 4,
    "reference": {"particles": 200, "replicates": 10}})JSON");
  const std::string out = dir + "/out";
  CommandRun run = RunCommand({"study", dir + "/study.json", "--output-dir", out, "--quiet",
                               "--no-plots"});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_THAT(run.out, HasSubstr("scene pendulum"));
  absl::StatusOr<study::StudyResult> read = io::ReadStudyResultFile(out);
  TG_ASSERT_OK(read.status());
  EXPECT_EQ(read->scene, "pendulum");
  ASSERT_EQ(read->cells.size(), 2u * 3 + 1);
  // Written and read back: the tables are the same text.
  std::ifstream csv_file(out + "/table.csv");
  const std::string csv((std::istreambuf_iterator<char>(csv_file)), std::istreambuf_iterator<char>());
  EXPECT_EQ(StudyTableCsv(*read), csv);

  run = RunCommand({"study", "summary", "pendulum=" + out, "--seconds", "1e-4,0.001,100"});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_THAT(run.out, HasSubstr("### pendulum"));
  EXPECT_THAT(run.out, HasSubstr("| H | time per gradient | lowest error | RP | LR | lower error "
                                 "measured in less time |"));
  // Beyond every measured time: no winner, but the best cell measured within
  // 100 s is named (every cell ran in less).
  const size_t row_100s = run.out.find("| 4 | 100 s | n/a");
  ASSERT_NE(row_100s, std::string::npos) << run.out;
  const std::string line = run.out.substr(row_100s, run.out.find('\n', row_100s) - row_100s);
  EXPECT_THAT(line, ::testing::MatchesRegex(".*\\| (RP|LR) [0-9.e+-]+ \\(P = [0-9]+, .*\\) \\|"));
  EXPECT_THAT(run.out, HasSubstr("Fixed-cost estimators"));
  run = RunCommand({"study", "summary", "p=" + out + "/results.json", "--format", "json"});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const nlohmann::json summary = nlohmann::json::parse(run.out);
  ASSERT_EQ(summary.size(), 1u);
  EXPECT_EQ(summary[0]["label"], "p");
  EXPECT_EQ(summary[0]["scene"], "pendulum");
  ASSERT_EQ(summary[0]["rows"].size(), 3u);  // one horizon x 3 default times
  for (const auto& row : summary[0]["rows"]) {
    // best_within names a cell only where it beats the winner (or there is none).
    if (row["best_within"].is_null()) continue;
    EXPECT_TRUE(row["winner"].is_null() ||
                row["best_within"]["error"].get<double>() < row["winner_error"].get<double>())
        << row.dump();
    EXPECT_LE(row["best_within"]["seconds"].get<double>(), row["seconds"].get<double>());
  }

  run = RunCommand({"study", "summary", out});
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_THAT(run.err, HasSubstr("LABEL=PATH"));
  run = RunCommand({"study", "summary", "x=" + dir + "/nowhere"});
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_THAT(run.err, HasSubstr("nowhere"));
  run = RunCommand({"study", "summary", "x=" + out, "--seconds", "0.1,-1"});
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_THAT(run.err, HasSubstr("'-1'"));
  run = RunCommand({"study"});
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_THAT(run.err, HasSubstr("study file is required"));
}

// The committed pendulum study (docs/error-vs-time.md) measures RP's relative
// error at 1e3 at H = 10 and far more beyond. That must be the model's
// exploding pathwise derivatives, not a wrong derivative through the
// pendulum's (sin, cos) features: on the study's own problem (the committed
// snapshot), RP's gradient with its random numbers fixed equals central
// differences of the same sample objective where those converge (H = 3).
// Tolerances from the measured convergence of the differences: J carries
// round-off noise of ~3e-11 (the GP's solves), so steps below 1e-5 lose
// digits, and at 1e-4 the curvature costs ~1e-3; with h = 1e-5 the
// differences are good to ~5e-4 relative plus ~1e-6 absolute. Beyond H = 5
// they do not converge at any step (the sample objective's gradient grows
// ~4x per step: 0.008 at H = 5, 12 at H = 10), which is the explosion the
// study measures. A wrong chain term is off by O(1).
TEST(SceneStudyProblems, RpOnThePendulumStudyIsTheExactDerivativeOfItsSampleObjective) {
  const std::string file = (std::filesystem::path(__FILE__).parent_path() /
                            "../../../docs/error-vs-time/pendulum/study.json")
                               .string();
  absl::StatusOr<nlohmann::json> doc = io::ReadStudyDocument(file);
  TG_ASSERT_OK(doc.status());
  absl::StatusOr<io::StudySpec> spec =
      io::ParseStudySpec(*doc, std::filesystem::path(file).parent_path().string());
  TG_ASSERT_OK(spec.status());
  absl::StatusOr<std::unique_ptr<study::FrozenProblem>> frozen = io::LoadStudyProblem(*spec);
  TG_ASSERT_OK(frozen.status());
  EXPECT_EQ((*frozen)->scene, "pendulum");
  EXPECT_EQ((*frozen)->angle_indices, std::vector<int>{1});
  policy::RbfPolicy* policy = &(*frozen)->owned_policy->rbf();
  ASSERT_NE(policy, nullptr);
  absl::StatusOr<std::unique_ptr<estimators::Estimator>> rp =
      estimators::MakeEstimator(estimators::Method::kRp, {});
  TG_ASSERT_OK(rp.status());
  estimators::Problem problem = (*frozen)->problem;
  problem.horizon = 3;
  estimators::EstimateOptions eo;
  eo.particles = 10;
  const Vector theta0 = policy->parameters();
  estimators::GradientEstimate at;
  Rng rng0(7, Stream::kStudy, 5);
  TG_ASSERT_OK((*rp)->Estimate(problem, eo, &rng0, &at));
  ASSERT_TRUE(at.finite);
  const diff::VectorFunction objective = [&](const Vector& theta, Vector* out) {
    policy->set_parameters(theta);
    Rng rng(7, Stream::kStudy, 5);
    estimators::GradientEstimate g;
    const bool ok = (*rp)->Estimate(problem, eo, &rng, &g).ok();
    *out = Vector::Constant(1, g.objective);
    return ok;
  };
  diff::CheckOptions check;
  check.relative_step = 1e-5;
  check.relative_tolerance = 5e-4;
  check.absolute_tolerance = 2e-6;
  const diff::CheckResult r = diff::CheckJacobian(objective, theta0, at.gradient.transpose(), check);
  policy->set_parameters(theta0);
  EXPECT_TRUE(r.ok) << r.log;
  // The check is not empty: the gradient is far above the absolute floor.
  EXPECT_GT(at.gradient.lpNorm<Eigen::Infinity>(), 500 * check.absolute_tolerance);
  std::printf("  pendulum H = 3: J %.6g, |dJ|_inf %.3g; FD max rel error %.2g, max abs error %.2g\n",
              at.objective, at.gradient.lpNorm<Eigen::Infinity>(), r.max_relative_error,
              r.max_abs_error);
}

// The same problem at H = 10, where RP's error is 1e3 |g*| (the committed
// study): RP's standard error dwarfs LR(plain, loo)'s, so the references'
// agreement check cannot fail; the reference says so (agreement_resolution
// > 1, the note names the estimator g* rests on), and the summary marks the
// winner. (A reference with power: SceneSynthetic.EveryOneControlSceneRunsTheStudy.)
TEST(SceneStudyProblems, AReferenceCheckWithoutPowerIsNamed) {
  const std::filesystem::path docs =
      std::filesystem::path(__FILE__).parent_path() / "../../../docs/error-vs-time";
  for (const auto& [scene, powerless] :
       std::vector<std::pair<std::string, bool>>{{"pendulum", true}}) {
    const std::string file = (docs / scene / "study.json").string();
    absl::StatusOr<nlohmann::json> doc = io::ReadStudyDocument(file);
    TG_ASSERT_OK(doc.status());
    absl::StatusOr<io::StudySpec> spec =
        io::ParseStudySpec(*doc, std::filesystem::path(file).parent_path().string());
    TG_ASSERT_OK(spec.status());
    absl::StatusOr<std::unique_ptr<study::FrozenProblem>> frozen = io::LoadStudyProblem(*spec);
    TG_ASSERT_OK(frozen.status());
    study::StudyOptions o;
    o.estimators = {{"RP", estimators::Method::kRp, {}}};
    o.particles = {10, 30};
    o.horizons = {10};
    o.replicates = 4;
    o.reference.particles = 100;
    o.reference.replicates = 20;
    absl::StatusOr<study::StudyResult> r = study::RunStudy(**frozen, o);
    TG_ASSERT_OK(r.status());
    ASSERT_EQ(r->references.size(), 1u);
    const study::ReferenceGradient& ref = r->references[0];
    EXPECT_TRUE(ref.agree) << scene << ": " << ref.note;
    ASSERT_TRUE(std::isfinite(ref.agreement_resolution)) << scene;
    std::printf("  %s: agreement resolution %.3g; %s\n", scene.c_str(), ref.agreement_resolution,
                ref.note.c_str());
    if (powerless) {
      EXPECT_GT(ref.agreement_resolution, 1.0);
      EXPECT_THAT(ref.note, HasSubstr("the agreement check has no power"));
      EXPECT_THAT(ref.note, HasSubstr("g* rests on LR(plain,loo)"));
    } else {
      EXPECT_LT(ref.agreement_resolution, 1.0) << ref.note;
      EXPECT_THAT(ref.note, ::testing::Not(HasSubstr("no power")));
    }
    // Written and read back, and marked in the summary.
    const std::string out = Dir("power_" + scene);
    io::StudySpec written = *spec;
    written.options = o;
    std::ofstream(out + "/results.json") << io::StudyResultToJson(*r, written).dump();
    absl::StatusOr<study::StudyResult> read = io::ReadStudyResultFile(out);
    TG_ASSERT_OK(read.status());
    EXPECT_EQ(read->references[0].agreement_resolution, ref.agreement_resolution);
    CommandRun run = RunCommand({"study", "summary", scene + "=" + out, "--seconds", "1e-9"});
    ASSERT_EQ(run.exit_code, 0) << run.err;
    EXPECT_EQ(run.out.find("had no power") != std::string::npos, powerless) << run.out;
  }
}

}  // namespace study_command_test
}  // namespace totalgrad::cli
