// `totalgrad pilco propagate`: the shipped examples run, the output has the
// documented shape, the gradient blocks match finite differences of J through
// the file format, and bad input is named.
#include "client/core_commands/pilco_command.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "tests/testutil/testutil.h"

namespace totalgrad::cli {
namespace {

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

TEST(PilcoCommandTest, BadInputIsNamed) {
  const nlohmann::json good = Load("balance_raw_angle.json");
  struct Case {
    std::function<void(nlohmann::json*)> mutate;
    std::string want;
  };
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
  for (const Case& c : cases) {
    nlohmann::json d = good;
    c.mutate(&d);
    absl::StatusOr<PilcoScenario> s = ParsePilcoScenario(d);
    ASSERT_FALSE(s.ok()) << c.want;
    EXPECT_EQ(s.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_NE(s.status().message().find(c.want), std::string::npos) << s.status();
  }
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

}  // namespace
}  // namespace totalgrad::cli
