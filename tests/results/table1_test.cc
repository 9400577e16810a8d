// The paper's Table 1 grid (results/table1.h) on hand-made trials: the
// cells' Wilson intervals against values worked by hand, the paper's number
// inside or outside our interval, the protocol mark, trials outside the
// grid, pooling across sweeps and the refusal to count a seed twice.
#include "results/table1.h"

#include <gtest/gtest.h>

#include <cmath>
#include <algorithm>

#include "io/record_format.h"
#include "results/stats.h"

namespace totalgrad::results {
namespace table1_test {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The options of a paper-protocol job of row (cost, noise_k), as stored.
record::TextPairs PaperOptions(const std::string& cost, const std::string& noise_k) {
  record::TextPairs options = {{"method", "RP"}, {"seed", "1"}};
  for (const auto& pair : PaperProtocol()) options.push_back(pair);
  options.emplace_back("cost", cost);
  options.emplace_back("noise_k", noise_k);
  options.emplace_back("verdict_rollouts", "100");
  return options;
}

CompletedTrial Trial(const std::string& sweep, int64_t job_id, const std::string& method, int seed,
                  bool success, const std::string& cost, const std::string& noise_k,
                  double held_fraction = kNaN) {
  CompletedTrial trial;
  trial.sweep = sweep;
  trial.job_id = job_id;
  trial.method = method;
  trial.seed = std::to_string(seed);
  trial.success = success;
  trial.held_fraction = held_fraction;
  trial.options = PaperOptions(cost, noise_k);
  return trial;
}

const Table1Cell& Cell(const Table1& table, size_t row, const std::string& method) {
  const std::vector<std::string>& methods = Table1Methods();
  const size_t column = std::find(methods.begin(), methods.end(), method) - methods.begin();
  return table.cells.at(row * methods.size() + column);
}

// Rows in Table1Rows() order.
constexpr size_t kAngle001 = 0, kAngle1 = 1, kTip001 = 2, kTip1 = 3;

TEST(Table1Test, TheGridIsThePapersWithItsNumbers) {
  ASSERT_EQ(Table1Methods(),
            (std::vector<std::string>{"PILCO", "RP", "GR", "LR", "TP", "GTP", "GLR", "GTP+sn"}));
  ASSERT_EQ(Table1Rows().size(), 4u);
  EXPECT_EQ(Table1Rows()[kAngle001].Label(), "angle, k = 0.01");
  EXPECT_EQ(Table1Rows()[kAngle1].Label(), "angle, k = 1");
  EXPECT_EQ(Table1Rows()[kTip001].Label(), "tip, k = 0.01");
  EXPECT_EQ(Table1Rows()[kTip1].Label(), "tip, k = 1");
  // A corner of each row, and the two cells the paper left empty.
  EXPECT_EQ(PaperSuccessRate(kAngle001, "PILCO"), 0.88);
  EXPECT_EQ(PaperSuccessRate(kAngle001, "GTP+sn"), 0.88);
  EXPECT_EQ(PaperSuccessRate(kAngle1, "TP"), 0.99);
  EXPECT_EQ(PaperSuccessRate(kTip001, "GLR"), 0.45);
  EXPECT_EQ(PaperSuccessRate(kTip1, "RP"), 0.15);
  EXPECT_EQ(PaperSuccessRate(kTip1, "GLR"), 0.35);
  EXPECT_TRUE(std::isnan(PaperSuccessRate(kAngle1, "GTP+sn")));
  EXPECT_TRUE(std::isnan(PaperSuccessRate(kTip1, "GTP+sn")));
  EXPECT_TRUE(std::isnan(PaperSuccessRate(kTip1, "DEL")));
  EXPECT_TRUE(std::isnan(PaperSuccessRate(4, "RP")));
}

TEST(Table1Test, ACellsRatesAndWilsonIntervalsAreTheHandComputedOnes) {
  // Ten PILCO trials on (tip, k = 1), eight successes; six classified by
  // the rollout verdict, of which three held (held_fraction >= 0.5, the
  // edge 0.5 included) and three did not.
  std::vector<CompletedTrial> trials;
  const double held[10] = {0.5, 0.9, 1.0, 0.49, 0.0, 0.2, kNaN, kNaN, kNaN, kNaN};
  for (int seed = 0; seed < 10; ++seed) {
    trials.push_back(Trial("t", seed + 1, "PILCO", seed, seed >= 2, "tip", "1", held[seed]));
  }
  absl::StatusOr<Table1> table = ComputeTable1(trials);
  ASSERT_TRUE(table.ok()) << table.status();
  const Table1Cell& cell = Cell(*table, kTip1, "PILCO");
  EXPECT_EQ(cell.success.trials, 10);
  EXPECT_EQ(cell.success.successes, 8);
  EXPECT_EQ(cell.success.rate, 0.8);
  // Wilson, z = 1.959964, z^2 = 3.841459, n = 10, p = 0.8:
  //   centre = (p + z^2 / 2n) / (1 + z^2 / n) = 0.992073 / 1.384146 = 0.716740
  //   half   = z / (1 + z^2 / n) * sqrt(p (1 - p) / n + z^2 / 4n^2)
  //          = 1.416010 * sqrt(0.016 + 0.009604) = 1.416010 * 0.160011 = 0.226578
  EXPECT_NEAR(cell.success.low, 0.716740 - 0.226578, 2e-6);
  EXPECT_NEAR(cell.success.high, 0.716740 + 0.226578, 2e-6);
  EXPECT_EQ(cell.held.trials, 6);
  EXPECT_EQ(cell.held.successes, 3);
  EXPECT_EQ(cell.held.rate, 0.5);
  // n = 6, p = 1/2: centre 1/2; half = z / (1 + z^2/6) * sqrt(1/24 + z^2/144)
  //   = 1.959964 / 1.640243 * sqrt(0.041667 + 0.026677) = 1.194923 * 0.261426 = 0.312384
  EXPECT_NEAR(cell.held.low, 0.5 - 0.312384, 2e-6);
  EXPECT_NEAR(cell.held.high, 0.5 + 0.312384, 2e-6);
  EXPECT_EQ(cell.paper_success_rate, 0.73);
  EXPECT_EQ(PaperInInterval(cell), "yes");  // 0.73 in [0.490, 0.943]
  EXPECT_EQ(cell.off_protocol_trials, 0);
  EXPECT_EQ(cell.protocol_differences, "");
  EXPECT_EQ(cell.sweeps, std::vector<std::string>{"t"});

  // Every other cell is there, empty: NaN rates, no verdict on the paper.
  const Table1Cell& empty = Cell(*table, kAngle001, "GTP");
  EXPECT_EQ(empty.success.trials, 0);
  EXPECT_TRUE(std::isnan(empty.success.rate) && std::isnan(empty.success.low) &&
              std::isnan(empty.success.high) && std::isnan(empty.held.rate));
  EXPECT_EQ(empty.paper_success_rate, 0.65);
  EXPECT_EQ(PaperInInterval(empty), "");
  EXPECT_EQ(table->cells.size(), 32u);
  EXPECT_EQ(table->trials_outside, 0);
}

TEST(Table1Test, ThePapersNumberIsInsideOrOutsideOurInterval) {
  // (tip, k = 1): GTP 4 of 10 gives [0.168180, 0.687326], and the paper's
  // 0.69 lies just above it; TP 5 of 10 gives [0.236593, 0.763407], which
  // holds the paper's 0.48. The paper has no GTP+sn at k = 1.
  std::vector<CompletedTrial> trials;
  for (int seed = 0; seed < 10; ++seed) {
    trials.push_back(Trial("t", 100 + seed, "GTP", seed, seed < 4, "tip", "1"));
    trials.push_back(Trial("t", 200 + seed, "TP", seed, seed < 5, "tip", "1"));
    trials.push_back(Trial("t", 300 + seed, "GTP+sn", seed, true, "tip", "1"));
  }
  absl::StatusOr<Table1> table = ComputeTable1(trials);
  ASSERT_TRUE(table.ok()) << table.status();
  const Table1Cell& gtp = Cell(*table, kTip1, "GTP");
  EXPECT_NEAR(gtp.success.high, 0.687326, 1e-6);
  EXPECT_EQ(PaperInInterval(gtp), "no");
  const Table1Cell& tp = Cell(*table, kTip1, "TP");
  EXPECT_NEAR(tp.success.low, 0.236593, 1e-6);
  EXPECT_NEAR(tp.success.high, 0.763407, 1e-6);
  EXPECT_EQ(PaperInInterval(tp), "yes");
  const Table1Cell& sn = Cell(*table, kTip1, "GTP+sn");
  EXPECT_EQ(sn.success.trials, 10);
  EXPECT_EQ(PaperInInterval(sn), "");

  // The ends of the interval count as inside.
  Table1Cell edge;
  edge.success.trials = 1;
  edge.success.low = 0.25;
  edge.success.high = 0.5;
  edge.paper_success_rate = 0.5;
  EXPECT_EQ(PaperInInterval(edge), "yes");
  edge.paper_success_rate = 0.25;
  EXPECT_EQ(PaperInInterval(edge), "yes");
  edge.paper_success_rate = 0.2500001;
  EXPECT_EQ(PaperInInterval(edge), "yes");
  edge.paper_success_rate = 0.2499999;
  EXPECT_EQ(PaperInInterval(edge), "no");
}

TEST(Table1Test, TheProtocolMarkNamesEachOptionThatDiffers) {
  EXPECT_TRUE(ProtocolDifferences(PaperOptions("tip", "1")).empty());
  // Numbers compare as numbers.
  record::TextPairs same = PaperOptions("tip", "1");
  for (auto& [key, value] : same) {
    if (key == "threshold") value = "15.0";
    if (key == "episodes") value = "1.5e1";
  }
  EXPECT_TRUE(ProtocolDifferences(same).empty());

  record::TextPairs options = PaperOptions("tip", "1");
  for (auto& [key, value] : options) {
    if (key == "particles") value = "50";
    if (key == "scene") value = "cartpole-balance";
  }
  options.erase(std::find_if(options.begin(), options.end(),
                             [](const auto& pair) { return pair.first == "eval_rollouts"; }));
  EXPECT_EQ(ProtocolDifferences(options),
            (std::vector<std::string>{"scene = cartpole-balance (paper cartpole-swingup)",
                                      "particles = 50 (paper 300)",
                                      "eval_rollouts missing (paper 30)"}));

  // In a cell: how many trials were off the protocol, and each difference
  // once, in first-appearance order.
  std::vector<CompletedTrial> trials;
  for (int seed = 0; seed < 4; ++seed) {
    CompletedTrial trial = Trial("t", seed, "RP", seed, true, "angle", "0.01");
    for (auto& [key, value] : trial.options) {
      if (key == "particles" && seed >= 1) value = "50";
      if (key == "episodes" && seed == 3) value = "5";
    }
    trials.push_back(trial);
  }
  absl::StatusOr<Table1> table = ComputeTable1(trials);
  ASSERT_TRUE(table.ok()) << table.status();
  const Table1Cell& cell = Cell(*table, kAngle001, "RP");
  EXPECT_EQ(cell.success.trials, 4);
  EXPECT_EQ(cell.off_protocol_trials, 3);
  EXPECT_EQ(cell.protocol_differences, "particles = 50 (paper 300); episodes = 5 (paper 15)");
}

TEST(Table1Test, TrialsOutsideTheGridAreCountedByReason) {
  std::vector<CompletedTrial> trials = {
      Trial("a", 1, "DEL", 1, true, "angle", "1"),
      Trial("a", 2, "DEL", 2, true, "angle", "1"),
      Trial("a", 3, "RP", 1, true, "saturating", "1"),
      Trial("a", 4, "RP", 2, true, "angle", "0.1"),
      Trial("a", 5, "RP", 3, true, "angle", "1"),
  };
  trials.push_back(Trial("a", 6, "RP", 4, true, "angle", "1"));
  trials.back().options.erase(std::find_if(
      trials.back().options.begin(), trials.back().options.end(),
      [](const auto& pair) { return pair.first == "noise_k"; }));
  absl::StatusOr<Table1> table = ComputeTable1(trials);
  ASSERT_TRUE(table.ok()) << table.status();
  EXPECT_EQ(table->trials_outside, 5);
  EXPECT_EQ(table->outside,
            (std::vector<std::string>{"2 trials of method DEL (not a Table 1 method)",
                                      "1 trial with cost 'saturating' (Table 1 has angle and tip)",
                                      "1 trial with noise_k 0.1 (Table 1 has 0.01 and 1)",
                                      "1 trial without the option 'noise_k'"}));
  EXPECT_EQ(Cell(*table, kAngle1, "RP").success.trials, 1);
}

TEST(Table1Test, CellsPoolTheirSweepsButASeedInTwoSweepsIsRefusedNamingBoth) {
  // Different seeds of one cell from two sweeps pool.
  std::vector<CompletedTrial> trials = {
      Trial("first", 1, "PILCO", 10, true, "tip", "1"),
      Trial("first", 2, "PILCO", 11, false, "tip", "1"),
      Trial("second", 7, "PILCO", 12, true, "tip", "1"),
      // The same seed in another cell is another trial.
      Trial("second", 8, "PILCO", 10, true, "tip", "0.01"),
  };
  absl::StatusOr<Table1> table = ComputeTable1(trials);
  ASSERT_TRUE(table.ok()) << table.status();
  const Table1Cell& pooled = Cell(*table, kTip1, "PILCO");
  EXPECT_EQ(pooled.success.trials, 3);
  EXPECT_EQ(pooled.success.successes, 2);
  EXPECT_EQ(pooled.sweeps, (std::vector<std::string>{"first", "second"}));
  EXPECT_EQ(Cell(*table, kTip001, "PILCO").success.trials, 1);

  // Seed 11 of PILCO on (tip, k = 1) re-run in a second sweep.
  trials.push_back(Trial("rerun", 41, "PILCO", 11, true, "tip", "1"));
  table = ComputeTable1(trials);
  ASSERT_EQ(table.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(table.status().message(),
            "seed 11 of PILCO in (tip, k = 1) is in sweep first (job 2) and in sweep rerun "
            "(job 41): pooling them would count the seed twice; name only one of the two "
            "sweeps");

  // Twice in one sweep (two variants that map to one cell).
  std::vector<CompletedTrial> twice = {Trial("s", 1, "RP", 3, true, "angle", "1"),
                                    Trial("s", 2, "RP", 3, false, "angle", "1")};
  twice[0].variant = "particle_std=0";
  twice[1].variant = "particle_std=1";
  table = ComputeTable1(twice);
  ASSERT_EQ(table.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(table.status().message().find("seed 3 of RP in (angle, k = 1) is twice in sweep s "
                                          "(job 1, variant 'particle_std=0', and job 2, "
                                          "variant 'particle_std=1')"),
            std::string::npos)
      << table.status();
}

TEST(Table1Test, ACellsFieldsAreNamedAsTheSweepTablesAndWrittenOnce) {
  std::vector<CompletedTrial> trials = {Trial("s", 1, "RP", 1, true, "angle", "1", 0.75)};
  absl::StatusOr<Table1> table = ComputeTable1(trials);
  ASSERT_TRUE(table.ok()) << table.status();
  const Table1Cell& cell = Cell(*table, kAngle1, "RP");
  EXPECT_EQ(io::CsvLine(io::RecordCsvColumns(Table1CellFields())),
            "cost,noise_k,method,trials,successes,success_rate,wilson95_low,wilson95_high,"
            "classified,held,held_rate,held_wilson95_low,held_wilson95_high,"
            "paper_success_rate,paper_in_interval,off_protocol_trials,protocol_differences,"
            "sweeps");
  const nlohmann::ordered_json json = io::RecordToJson(Table1CellFields(), cell);
  EXPECT_EQ(json["noise_k"], 1.0);
  EXPECT_EQ(json["paper_success_rate"], 0.74);
  EXPECT_EQ(json["paper_in_interval"], "yes");
  EXPECT_EQ(json["held"], 1);
  EXPECT_EQ(json["sweeps"], nlohmann::json::array({"s"}));
  // Every statistic the sweep's table has, the grid's cell has by the same name.
  for (const auto& field : TableCellFields()) {
    const std::string name = field.name;
    if (name == "variant" || name == "median_final_cost") continue;
    EXPECT_TRUE(json.contains(name)) << name;
  }
}

}  // namespace table1_test
}  // namespace totalgrad::results
