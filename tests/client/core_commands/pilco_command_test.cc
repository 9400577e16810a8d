// `totalgrad pilco propagate`: the shipped examples run, the output has the
// documented shape, the gradient blocks match finite differences of J through
// the file format, and bad input is named.
#include "client/core_commands/pilco_command.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "tests/testutil/testutil.h"

namespace totalgrad::cli {
namespace pilco_command_test {

std::string ExamplePath(const std::string& name) {
  // This file is tests/client/core_commands/pilco_command_test.cc.
  const std::filesystem::path root =
      std::filesystem::path(__FILE__).parent_path().parent_path().parent_path().parent_path();
  return (root / "docs" / "pilco-examples" / name).string();
}

nlohmann::json Load(const std::string& name) {
  std::ifstream in(ExamplePath(name));
  EXPECT_TRUE(in.good()) << ExamplePath(name);
  return nlohmann::json::parse(in);
}

double RunJ(const nlohmann::json& doc) {
  absl::StatusOr<PilcoScenario> s = ParsePilcoScenario(doc);
  EXPECT_TRUE(s.ok()) << s.status();
  absl::StatusOr<nlohmann::ordered_json> out = RunPilcoPropagate(*s);
  EXPECT_TRUE(out.ok()) << out.status();
  return (*out)["J"].get<double>();
}

class PilcoExampleTest : public ::testing::TestWithParam<const char*> {};

TEST_P(PilcoExampleTest, RunsWithDocumentedShapeAndGradient) {
  const nlohmann::json doc = Load(GetParam());
  absl::StatusOr<PilcoScenario> s = ParsePilcoScenario(doc);
  TG_ASSERT_OK(s.status());
  absl::StatusOr<nlohmann::ordered_json> out = RunPilcoPropagate(*s);
  TG_ASSERT_OK(out.status());
  const int h = doc["horizon"].get<int>();
  const int c = static_cast<int>(doc["policy"]["centres"].size());
  const int ep = static_cast<int>(doc["policy"]["log_lengthscales"].size());
  EXPECT_EQ((*out)["mean"].size(), static_cast<size_t>(h + 1));
  EXPECT_EQ((*out)["cov"].size(), static_cast<size_t>(h + 1));
  EXPECT_EQ((*out)["cov"][0].size(), 4u);
  EXPECT_EQ((*out)["cost_mean"].size(), static_cast<size_t>(h));
  EXPECT_EQ((*out)["cost_std"].size(), static_cast<size_t>(h));
  double sum = 0;
  for (const auto& v : (*out)["cost_mean"]) sum += v.get<double>();
  EXPECT_NEAR((*out)["J"].get<double>(), sum, 1e-12);
  EXPECT_EQ((*out)["dJ_dcentres"].size(), static_cast<size_t>(c));
  EXPECT_EQ((*out)["dJ_dcentres"][0].size(), static_cast<size_t>(ep));
  EXPECT_EQ((*out)["dJ_dlog_lengthscales"].size(), static_cast<size_t>(ep));
  const bool targets = doc["policy"].contains("targets");
  const char* wkey = targets ? "targets" : "weights";
  const std::string gkey = targets ? "dJ_dtargets" : "dJ_dweights";
  ASSERT_TRUE(out->contains(gkey));
  // Central differences through the file format on a few entries of each block.
  const double h_step = 1e-6;
  auto fd = [&](auto mutate) {
    nlohmann::json p = doc, m = doc;
    mutate(p, +h_step);
    mutate(m, -h_step);
    return (RunJ(p) - RunJ(m)) / (2 * h_step);
  };
  for (int k : {0, c - 1}) {
    const double g = (*out)[gkey][k].get<double>();
    const double n = fd([&](nlohmann::json& d, double e) {
      d["policy"][wkey][k] = d["policy"][wkey][k].get<double>() + e;
    });
    EXPECT_NEAR(g, n, 1e-6 + 1e-5 * std::abs(n)) << wkey << " " << k;
    const double gc = (*out)["dJ_dcentres"][k][ep - 1].get<double>();
    const double nc = fd([&](nlohmann::json& d, double e) {
      d["policy"]["centres"][k][ep - 1] = d["policy"]["centres"][k][ep - 1].get<double>() + e;
    });
    EXPECT_NEAR(gc, nc, 1e-6 + 1e-5 * std::abs(nc)) << "centre " << k;
  }
  for (int m = 0; m < ep; ++m) {
    const double g = (*out)["dJ_dlog_lengthscales"][m].get<double>();
    const double n = fd([&](nlohmann::json& d, double e) {
      d["policy"]["log_lengthscales"][m] = d["policy"]["log_lengthscales"][m].get<double>() + e;
    });
    EXPECT_NEAR(g, n, 1e-6 + 1e-5 * std::abs(n)) << "log l " << m;
  }
}

INSTANTIATE_TEST_SUITE_P(Examples, PilcoExampleTest,
                         ::testing::Values("swingup_sincos_tip.json", "balance_raw_angle.json"));

TEST(PilcoCommandTest, PseudoTargetsAndTheirWeightsGiveTheSamePrediction) {
  nlohmann::json doc = Load("swingup_sincos_tip.json");
  absl::StatusOr<PilcoScenario> s = ParsePilcoScenario(doc);
  TG_ASSERT_OK(s.status());
  absl::StatusOr<nlohmann::ordered_json> a = RunPilcoPropagate(*s);
  TG_ASSERT_OK(a.status());
  doc["policy"].erase("targets");
  doc["policy"]["weights"] = (*a)["weights"];
  EXPECT_NEAR(RunJ(doc), (*a)["J"].get<double>(), 1e-12);
}

// A bad input: how it is made from a good file, and what its error says.
struct Case {
  std::function<void(nlohmann::json*)> mutate;
  std::string want;
};

// Each case, applied to `good`, is refused when parsed: InvalidArgument
// whose message contains the case's text.
void ExpectEachRefused(const nlohmann::json& good, const std::vector<Case>& cases) {
  for (const Case& c : cases) {
    nlohmann::json d = good;
    c.mutate(&d);
    absl::StatusOr<PilcoScenario> s = ParsePilcoScenario(d);
    ASSERT_FALSE(s.ok()) << c.want;
    EXPECT_EQ(s.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_NE(s.status().message().find(c.want), std::string::npos)
        << "want '" << c.want << "', got: " << s.status();
  }
}

TEST(PilcoCommandTest, BadInputIsNamed) {
  const nlohmann::json good = Load("balance_raw_angle.json");
  const std::vector<Case> cases = {
      {[](nlohmann::json* d) { d->erase("mu0"); }, "missing field 'mu0'"},
      {[](nlohmann::json* d) { (*d)["policy"].erase("max_force"); },
       "missing field 'policy.max_force'"},
      {[](nlohmann::json* d) { (*d)["train_inputs"][3][1] = "x"; }, "train_inputs[3][1]"},
      {[](nlohmann::json* d) { (*d)["train_inputs"][2].push_back(1.0); }, "train_inputs[2]"},
      {[](nlohmann::json* d) { (*d)["cost"]["type"] = "energy"; }, "cost.type"},
      {[](nlohmann::json* d) { (*d)["policy"]["targets"] = {1.0}; }, "exactly one of"},
      {[](nlohmann::json* d) { (*d)["horizon"] = 0; }, "horizon"},
  };
  ExpectEachRefused(good, cases);
  // Shape errors found when running.
  nlohmann::json d = good;
  d["policy"]["log_lengthscales"] = {0.0, 0.0};
  absl::StatusOr<PilcoScenario> s = ParsePilcoScenario(d);
  TG_ASSERT_OK(s.status());
  absl::StatusOr<nlohmann::ordered_json> out = RunPilcoPropagate(*s);
  ASSERT_FALSE(out.ok());
  EXPECT_NE(out.status().message().find("policy.log_lengthscales"), std::string::npos);
  // A non-PSD start covariance is a clear numerical error, not a crash.
  d = good;
  d["S0"][1][1] = -1.0;
  s = ParsePilcoScenario(d);
  TG_ASSERT_OK(s.status());
  out = RunPilcoPropagate(*s);
  ASSERT_FALSE(out.ok());
  EXPECT_EQ(out.status().code(), absl::StatusCode::kFailedPrecondition) << out.status();
  EXPECT_NE(out.status().message().find("step 1"), std::string::npos) << out.status();
}


// ------------------------------------------------------------ general form

// Every entry of a JSON number array (any nesting) as doubles, row-major.
std::vector<double> Flat(const nlohmann::json& v) {
  std::vector<double> out;
  if (v.is_array()) {
    for (const auto& e : v) {
      const std::vector<double> sub = Flat(e);
      out.insert(out.end(), sub.begin(), sub.end());
    }
  } else {
    out.push_back(v.get<double>());
  }
  return out;
}

// The general-form examples (docs/pilco-examples/make_general_examples.py):
// two angles and two torques with pseudo-targets C x 2; two angles, FITC and
// weights; one angle with a GP on its own inputs and two widths; two torques
// with one row of length-scales per control and FITC. Output
// shapes as documented, and every gradient block against central
// differences of J through the file format (each block's entries with the
// largest and the smallest index).
class PilcoGeneralExampleTest : public ::testing::TestWithParam<const char*> {};

TEST_P(PilcoGeneralExampleTest, RunsWithDocumentedShapeAndGradient) {
  const nlohmann::json doc = Load(GetParam());
  absl::StatusOr<PilcoScenario> s = ParsePilcoScenario(doc);
  TG_ASSERT_OK(s.status());
  ASSERT_TRUE(s->is_general);
  absl::StatusOr<nlohmann::ordered_json> out = RunPilcoPropagate(*s);
  TG_ASSERT_OK(out.status());
  const int h = doc["horizon"].get<int>();
  const int d = static_cast<int>(doc["mu0"].size());
  const int c = static_cast<int>(doc["policy"]["centres"].size());
  const int ep = static_cast<int>(doc["policy_inputs"].size());
  const bool targets = doc["policy"].contains("targets");
  const char* vkey = targets ? "targets" : "weights";
  const nlohmann::json& values = doc["policy"][vkey];
  const bool matrix_values = values[0].is_array();
  const int f = matrix_values ? static_cast<int>(values[0].size()) : 1;
  EXPECT_EQ((*out)["mean"].size(), static_cast<size_t>(h + 1));
  EXPECT_EQ((*out)["mean"][h].size(), static_cast<size_t>(d));
  EXPECT_EQ((*out)["cov"].size(), static_cast<size_t>(h + 1));
  EXPECT_EQ(Flat((*out)["cov"][h]).size(), static_cast<size_t>(d * d));
  EXPECT_EQ((*out)["cost_mean"].size(), static_cast<size_t>(h));
  EXPECT_EQ((*out)["cost_std"].size(), static_cast<size_t>(h));
  double sum = 0;
  for (const auto& v : (*out)["cost_mean"]) sum += v.get<double>();
  EXPECT_NEAR((*out)["J"].get<double>(), sum, 1e-12);
  EXPECT_EQ(Flat((*out)["dJ_dcentres"]).size(), static_cast<size_t>(c * ep));
  const std::string gkey = targets ? "dJ_dtargets" : "dJ_dweights";
  ASSERT_TRUE(out->contains(gkey));
  // In the shape the file gave: C x F, or a C-vector.
  ASSERT_EQ((*out)[gkey].size(), static_cast<size_t>(c));
  EXPECT_EQ((*out)[gkey][0].is_array(), matrix_values);
  if (matrix_values) {
    EXPECT_EQ((*out)[gkey][0].size(), static_cast<size_t>(f));
  }
  EXPECT_EQ(targets, out->contains("weights"));

  // Fourth-order central differences with step 1e-4: J carries round-off of
  // about 1e-13 relative amplified by the pseudo-target solve (K_cc + 1e-4 I
  // is ill-conditioned), which a 1e-6 step would turn into ~1e-5 errors.
  const double step = 1e-4;
  auto fd = [&](auto mutate) {
    double j[4];
    const double k[4] = {2, 1, -1, -2};
    for (int i = 0; i < 4; ++i) {
      nlohmann::json p = doc;
      mutate(p, k[i] * step);
      j[i] = RunJ(p);
    }
    return (-j[0] + 8 * j[1] - 8 * j[2] + j[3]) / (12 * step);
  };
  auto near = [](double analytic, double numeric) {
    return std::abs(analytic - numeric) <= 1e-7 + 1e-5 * std::abs(numeric);
  };
  double largest = 0;
  for (int k : {0, c - 1}) {
    for (int j : {0, f - 1}) {
      const double g = matrix_values ? (*out)[gkey][k][j].get<double>() : (*out)[gkey][k].get<double>();
      const double n = fd([&](nlohmann::json& dd, double e) {
        nlohmann::json& v = matrix_values ? dd["policy"][vkey][k][j] : dd["policy"][vkey][k];
        v = v.get<double>() + e;
      });
      EXPECT_TRUE(near(g, n)) << vkey << " " << k << "," << j << ": " << g << " vs " << n;
      largest = std::max(largest, std::abs(n));
    }
    for (int m : {0, ep - 1}) {
      const double g = (*out)["dJ_dcentres"][k][m].get<double>();
      const double n = fd([&](nlohmann::json& dd, double e) {
        dd["policy"]["centres"][k][m] = dd["policy"]["centres"][k][m].get<double>() + e;
      });
      EXPECT_TRUE(near(g, n)) << "centre " << k << "," << m << ": " << g << " vs " << n;
    }
  }
  // Log length-scales: Ep numbers, or F x Ep (one row per control), the
  // gradient in the same shape.
  const bool ll_rows = doc["policy"]["log_lengthscales"][0].is_array();
  const int rows = ll_rows ? static_cast<int>(doc["policy"]["log_lengthscales"].size()) : 1;
  ASSERT_EQ((*out)["dJ_dlog_lengthscales"].size(), static_cast<size_t>(ll_rows ? rows : ep));
  for (int r = 0; r < rows; ++r) {
    for (int m = 0; m < ep; ++m) {
      const double g = ll_rows ? (*out)["dJ_dlog_lengthscales"][r][m].get<double>()
                               : (*out)["dJ_dlog_lengthscales"][m].get<double>();
      const double n = fd([&](nlohmann::json& dd, double e) {
        nlohmann::json& v = ll_rows ? dd["policy"]["log_lengthscales"][r][m]
                                    : dd["policy"]["log_lengthscales"][m];
        v = v.get<double>() + e;
      });
      EXPECT_TRUE(near(g, n)) << "log l " << r << "," << m << ": " << g << " vs " << n;
    }
  }
  EXPECT_GT(largest, 1e-4) << "the examples' gradients should not vanish";
}

INSTANTIATE_TEST_SUITE_P(Examples, PilcoGeneralExampleTest,
                         ::testing::Values("general_double_pendulum.json", "general_cdp_fitc.json",
                                           "general_pendulum_dyni.json",
                                           "general_double_pendulum_per_control.json"));

// Today's examples rewritten in the general form (one angle or none, one
// control, full GP; the tip cost as lossSat on z = [x, sin, cos] with
// Q = C^T C, C = [[1 0 0 0 l 0], [0 0 0 0 0 l]]; the angle cost as lossSat
// on x with Q = 2 Q_angle, width 1): the same moment matching code runs, so
// the predicted states are the same bits, and the costs and gradients agree
// to rounding: the two cost forms factorise Q differently (1e-15 relative),
// which the backward pass through the pseudo-targets' solve amplifies to
// about 3e-11 of the field's largest entry (measured); 1e-9 is far below any
// formula difference.
nlohmann::json AsGeneral(const nlohmann::json& old) {
  nlohmann::json g;
  for (const char* k : {"train_inputs", "train_targets", "gp_log_hyp", "mu0", "S0", "horizon"}) {
    g[k] = old[k];
  }
  g["policy"] = old["policy"];
  const int d = static_cast<int>(old["mu0"].size());
  if (old["angle_index"].is_null()) {
    g["angle_indices"] = nlohmann::json::array();
    std::vector<int> all;
    for (int i = 0; i < d; ++i) all.push_back(i);
    g["dynamics_inputs"] = all;
    g["policy_inputs"] = all;
    nlohmann::json q = nlohmann::json::array();
    for (int i = 0; i < d; ++i) {
      nlohmann::json row = nlohmann::json::array();
      for (int j = 0; j < d; ++j) row.push_back(i == j ? 2.0 * old["cost"]["Q"][i].get<double>() : 0.0);
      q.push_back(row);
    }
    g["cost"] = {{"type", "saturating"}, {"target", old["cost"]["target"]}, {"Q", q}, {"width", 1.0}};
  } else {
    const int a = old["angle_index"].get<int>();
    g["angle_indices"] = {a};
    std::vector<int> inputs;
    for (int i = 0; i < d; ++i) {
      if (i != a) inputs.push_back(i);
    }
    inputs.push_back(d);
    inputs.push_back(d + 1);
    g["dynamics_inputs"] = inputs;
    g["policy_inputs"] = inputs;
    const double l = old["cost"]["pendulum_length"].get<double>();
    std::vector<std::vector<double>> q(d + 2, std::vector<double>(d + 2, 0.0));
    const int p = old["cost"]["position_index"].get<int>();
    // C^T C for d = C (z - z_t): rows (x_p + l sin, l cos).
    q[p][p] = 1.0;
    q[p][d] = q[d][p] = l;
    q[d][d] = l * l;
    q[d + 1][d + 1] = l * l;
    std::vector<double> target(d, 0.0);
    target[a] = M_PI;
    g["cost"] = {{"type", "saturating"}, {"target", target}, {"Q", q},
                 {"width", old["cost"]["width"]}};
  }
  return g;
}

TEST_P(PilcoExampleTest, GeneralFormOfTodaysExampleGivesTheSameResult) {
  const nlohmann::json old = Load(GetParam());
  const nlohmann::json general = AsGeneral(old);
  absl::StatusOr<PilcoScenario> a = ParsePilcoScenario(old);
  absl::StatusOr<PilcoScenario> b = ParsePilcoScenario(general);
  TG_ASSERT_OK(a.status());
  TG_ASSERT_OK(b.status());
  ASSERT_TRUE(b->is_general);
  absl::StatusOr<nlohmann::ordered_json> oa = RunPilcoPropagate(*a);
  absl::StatusOr<nlohmann::ordered_json> ob = RunPilcoPropagate(*b);
  TG_ASSERT_OK(oa.status());
  TG_ASSERT_OK(ob.status());
  EXPECT_EQ(Flat((*oa)["mean"]), Flat((*ob)["mean"]));
  EXPECT_EQ(Flat((*oa)["cov"]), Flat((*ob)["cov"]));
  for (const auto& [key, value] : oa->items()) {
    if (key == "mean" || key == "cov") continue;
    ASSERT_TRUE(ob->contains(key)) << key;
    const std::vector<double> x = Flat(value), y = Flat((*ob)[key]);
    ASSERT_EQ(x.size(), y.size()) << key;
    double scale = 0;
    for (double v : x) scale = std::max(scale, std::abs(v));
    for (size_t i = 0; i < x.size(); ++i) {
      EXPECT_NEAR(x[i], y[i], 1e-9 * std::max(scale, 1e-3)) << key << "[" << i << "]";
    }
  }
  EXPECT_EQ(ob->size(), oa->size());
}

// Every bad input of the general form is named: the field (and entry) and
// what is wrong with it.
TEST(PilcoCommandTest, GeneralFormBadInputIsNamed) {
  const nlohmann::json good = Load("general_double_pendulum.json");  // D 4, A 2, F 2, Ep 6
  const double inf = std::numeric_limits<double>::infinity();
  const std::vector<Case> cases = {
      {[](nlohmann::json* d) { (*d)["angle_indx"] = 1; }, "unknown field 'angle_indx'"},
      {[](nlohmann::json* d) { (*d)["policy"]["sf"] = 1; }, "unknown field 'policy.sf'"},
      {[](nlohmann::json* d) { (*d)["cost"]["widths"] = {1.0}; }, "unknown field 'cost.widths'"},
      {[](nlohmann::json* d) { (*d)["angle_index"] = 2; }, "not both"},
      {[](nlohmann::json* d) { (*d)["angle_indices"] = {3, 2}; }, "angle_indices: indices must be strictly increasing"},
      {[](nlohmann::json* d) { (*d)["angle_indices"] = {2, 2}; }, "angle_indices: indices must be strictly increasing"},
      {[](nlohmann::json* d) { (*d)["angle_indices"] = {2, 4}; }, "angle_indices[1]: 4 is out of range [0, 4)"},
      {[](nlohmann::json* d) { (*d)["angle_indices"] = {2.5, 3}; }, "angle_indices[0]: not an integer"},
      {[](nlohmann::json* d) { (*d)["angle_indices"] = 2; }, "angle_indices: not an array"},
      {[](nlohmann::json* d) { (*d)["dynamics_inputs"][5] = 8; }, "dynamics_inputs[5]: 8 is out of range [0, 8)"},
      {[](nlohmann::json* d) { (*d)["dynamics_inputs"][0] = -1; }, "dynamics_inputs[0]: -1 is out of range"},
      {[](nlohmann::json* d) { (*d)["policy_inputs"] = {0, 1, 5, 4, 6, 7}; }, "policy_inputs: indices must be strictly increasing"},
      {[](nlohmann::json* d) { (*d)["policy_inputs"] = nlohmann::json::array(); }, "policy_inputs: empty"},
      {[](nlohmann::json* d) { (*d)["train_inputs"][3].erase(0); }, "train_inputs[3]: has 7 entries"},
      {[](nlohmann::json* d) { for (auto& r : (*d)["train_inputs"]) r.erase(0); }, "train_inputs: must be 50 x 8"},
      {[](nlohmann::json* d) { (*d)["train_targets"].erase(0); }, "train_inputs: must be 49 x 8"},
      {[inf](nlohmann::json* d) { (*d)["train_inputs"][2][1] = inf; }, "train_inputs[2][1]: not finite"},
      {[](nlohmann::json* d) { (*d)["train_targets"][0][0] = "x"; }, "train_targets[0][0]: not a number"},
      {[](nlohmann::json* d) { (*d)["inducing_inputs"] = {{1.0, 2.0}}; }, "inducing_inputs: must be 1 x 8"},
      {[](nlohmann::json* d) { (*d)["gp_log_hyp"][0].erase(0); }, "gp_log_hyp[1]: has 10 entries, row 0 has 9"},
      {[](nlohmann::json* d) { (*d)["gp_log_hyp"].erase(0); }, "gp_log_hyp: must be 4 x 10"},
      {[](nlohmann::json* d) { for (auto& r : (*d)["policy"]["centres"]) r.erase(0); }, "policy.centres: must be 8 x 6"},
      {[](nlohmann::json* d) { (*d)["policy"]["targets"].erase(0); }, "policy.targets: must be C x F"},
      {[](nlohmann::json* d) { (*d)["policy"]["weights"] = (*d)["policy"]["targets"]; }, "exactly one of"},
      {[](nlohmann::json* d) { (*d)["policy"]["log_lengthscales"].erase(0); }, "policy.log_lengthscales: must be 6 numbers"},
      {[](nlohmann::json* d) {
         const nlohmann::json row = (*d)["policy"]["log_lengthscales"];
         (*d)["policy"]["log_lengthscales"] = {row, row, row};
       }, "policy.log_lengthscales: must be 6 numbers (len(policy_inputs), shared) or 2 x 6 (one row per control), is 3 x 6"},
      {[](nlohmann::json* d) { (*d)["policy"]["max_force"] = {2.0}; }, "policy.max_force: must have 2 entries"},
      {[](nlohmann::json* d) { (*d)["policy"]["max_force"] = {2.0, -1.0}; }, "policy.max_force[1]: must be > 0"},
      {[](nlohmann::json* d) { (*d)["policy"]["output_variance_jitter"] = -1.0; }, "policy.output_variance_jitter"},
      {[](nlohmann::json* d) { (*d)["mu0"].erase(0); }, "mu0: must have 4 entries"},
      {[](nlohmann::json* d) { (*d)["S0"][0][1] = 0.5; }, "S0: not symmetric"},
      {[](nlohmann::json* d) { (*d)["S0"].erase(0); }, "S0: must be 4 x 4"},
      {[](nlohmann::json* d) { (*d)["horizon"] = 0; }, "horizon: must be >= 1"},
      {[](nlohmann::json* d) { (*d)["horizon"] = 2.5; }, "horizon: not an integer"},
      {[](nlohmann::json* d) { (*d)["cost"]["type"] = "tip"; }, "cost.type"},
      {[](nlohmann::json* d) { (*d)["cost"]["target"] = {0.0}; }, "cost.target: must have 4 entries"},
      {[](nlohmann::json* d) { (*d)["cost"]["Q"][4][6] = 0.3; }, "cost.Q: not symmetric"},
      {[](nlohmann::json* d) { (*d)["cost"]["Q"].erase(0); }, "cost.Q: must be 8 x 8"},
      {[](nlohmann::json* d) { (*d)["cost"]["width"] = {0.5, 0.0}; }, "cost.width[1]: must be > 0"},
      {[](nlohmann::json* d) { (*d)["cost"]["width"] = nlohmann::json::array(); }, "cost.width: empty list"},
      {[](nlohmann::json* d) { (*d)["cost"]["width"] = "wide"; }, "cost.width: not an array"},
      {[](nlohmann::json* d) { (*d)["cost"].erase("Q"); }, "missing field 'cost.Q'"},
      {[](nlohmann::json* d) { d->erase("dynamics_inputs"); }, "missing field 'dynamics_inputs'"},
  };
  ExpectEachRefused(good, cases);
  // Found when running (it needs the numbers, not only the shapes): Q not
  // positive semi-definite.
  nlohmann::json d = good;
  for (int i = 0; i < 8; ++i) d["cost"]["Q"][i][i] = i == 0 ? -1.0 : 0.0;
  absl::StatusOr<PilcoScenario> s = ParsePilcoScenario(d);
  TG_ASSERT_OK(s.status());
  absl::StatusOr<nlohmann::ordered_json> out = RunPilcoPropagate(*s);
  ASSERT_FALSE(out.ok());
  EXPECT_EQ(out.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(out.status().message().find("saturating cost Q is not positive semi-definite"),
            std::string::npos)
      << out.status();
}

// The unicycle's example (docs/pilco-examples/general_unicycle_linear.json:
// PILCO's linear policy on the 10-entry GP state, the GP on 9 of them and
// both torques, loss_unicycle): the documented output shape, J the sum of
// the expected costs, and every entry of dJ_dw and dJ_db against central
// differences of J through the file format.
TEST(PilcoCommandTest, LinearPolicyAndUnicycleCostGradientsMatchCentralDifferences) {
  const nlohmann::json doc = Load("general_unicycle_linear.json");
  absl::StatusOr<PilcoScenario> s = ParsePilcoScenario(doc);
  TG_ASSERT_OK(s.status());
  EXPECT_EQ(s->general.policy_type, "linear");
  EXPECT_EQ(s->cost_type, "unicycle");
  absl::StatusOr<nlohmann::ordered_json> out = RunPilcoPropagate(*s);
  TG_ASSERT_OK(out.status());
  const int h = doc["horizon"].get<int>(), d = 10, f = 2;
  ASSERT_EQ((*out)["mean"].size(), static_cast<size_t>(h + 1));
  EXPECT_EQ((*out)["mean"][h].size(), static_cast<size_t>(d));
  EXPECT_EQ(Flat((*out)["cov"][h]).size(), static_cast<size_t>(d * d));
  double sum = 0;
  for (const auto& v : (*out)["cost_mean"]) sum += v.get<double>();
  EXPECT_NEAR((*out)["J"].get<double>(), sum, 1e-12);
  EXPECT_GT(sum, 0.0);
  EXPECT_LT(sum, h);  // each expected cost is in [0, 1)
  EXPECT_FALSE(out->contains("dJ_dcentres"));
  ASSERT_EQ((*out)["dJ_dw"].size(), static_cast<size_t>(f));
  ASSERT_EQ((*out)["dJ_db"].size(), static_cast<size_t>(f));
  const double step = 1e-5;
  auto central = [&](auto mutate) {
    nlohmann::json plus = doc, minus = doc;
    mutate(plus, step);
    mutate(minus, -step);
    return (RunJ(plus) - RunJ(minus)) / (2 * step);
  };
  auto near = [](double analytic, double numeric) {
    return std::abs(analytic - numeric) <= 1e-8 + 1e-5 * std::abs(numeric);
  };
  double largest = 0;
  for (int j = 0; j < f; ++j) {
    ASSERT_EQ((*out)["dJ_dw"][j].size(), static_cast<size_t>(d));
    for (int k = 0; k < d; ++k) {
      const double g = (*out)["dJ_dw"][j][k].get<double>();
      const double n = central([&](nlohmann::json& p, double e) {
        p["policy"]["w"][j][k] = p["policy"]["w"][j][k].get<double>() + e;
      });
      EXPECT_TRUE(near(g, n)) << "w " << j << "," << k << ": " << g << " vs " << n;
      largest = std::max(largest, std::abs(n));
    }
    const double g = (*out)["dJ_db"][j].get<double>();
    const double n = central([&](nlohmann::json& p, double e) {
      p["policy"]["b"][j] = p["policy"]["b"][j].get<double>() + e;
    });
    EXPECT_TRUE(near(g, n)) << "b " << j << ": " << g << " vs " << n;
  }
  EXPECT_GT(largest, 1e-3) << "the example's gradient should not vanish";
}

TEST(PilcoCommandTest, LinearPolicyAndUnicycleCostBadInputIsNamed) {
  const nlohmann::json good = Load("general_unicycle_linear.json");  // D 10, F 2, Ep 10
  const std::vector<Case> cases = {
      {[](nlohmann::json* d) { (*d)["policy"]["type"] = "affine"; }, "policy.type: \"rbf\" (the default) or \"linear\""},
      {[](nlohmann::json* d) { (*d)["policy"]["centres"] = {{0.0}}; }, "unknown field 'policy.centres'"},
      {[](nlohmann::json* d) { (*d)["policy"]["w"][1].erase(0); }, "policy.w[1]: has 9 entries, row 0 has 10"},
      {[](nlohmann::json* d) { for (auto& r : (*d)["policy"]["w"]) r.erase(0); }, "policy.w: must be 2 x 10"},
      {[](nlohmann::json* d) { (*d)["policy"]["w"] = nlohmann::json::array(); }, "policy.w: no rows"},
      {[](nlohmann::json* d) { (*d)["policy"]["b"] = {0.0}; }, "policy.b: must have 2 entries"},
      {[](nlohmann::json* d) { (*d)["policy"].erase("b"); }, "missing field 'policy.b'"},
      {[](nlohmann::json* d) { (*d)["policy"]["max_force"] = {10.0}; }, "policy.max_force: must have 2 entries (F, the rows of policy.w)"},
      {[](nlohmann::json* d) { (*d)["policy"]["max_force"] = {10.0, 0.0}; }, "policy.max_force[1]: must be > 0"},
      {[](nlohmann::json* d) { (*d)["cost"]["Q"] = 1.0; }, "unknown field 'cost.Q'"},
      {[](nlohmann::json* d) { (*d)["cost"]["rod_length"] = -0.8; }, "cost.rod_length: must be > 0"},
      {[](nlohmann::json* d) { (*d)["cost"]["wheel_radius"] = "r"; }, "cost.wheel_radius: not a number"},
      {[](nlohmann::json* d) { (*d)["cost"]["width"] = {1.0, -2.0}; }, "cost.width[1]: must be > 0"},
      {[](nlohmann::json* d) { (*d)["cost"]["type"] = "tip"; }, "\"saturating\" (PILCO's lossSat on z) or \"unicycle\""},
      {[](nlohmann::json* d) { (*d)["angle_indices"] = {7}; }, "cost.type \"unicycle\": the state must be the unicycle's GP state of 10 entries"},
  };
  ExpectEachRefused(good, cases);
  // The unicycle cost on a state of another size.
  nlohmann::json d = Load("general_double_pendulum.json");
  d["cost"] = {{"type", "unicycle"}};
  absl::StatusOr<PilcoScenario> s = ParsePilcoScenario(d);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.status().message().find("it has D = 4 and 2 angles"), std::string::npos) << s.status();
}

}  // namespace pilco_command_test
}  // namespace totalgrad::cli
