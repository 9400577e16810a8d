#include "client/core_commands/simulate_command.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "client/core_commands/commands.h"
#include "tests/client/core_commands/run_command.h"
#include "core/tasks/cartpole.h"
#include "core/tasks/scene.h"
#include "core/tasks/scene_catalog.h"
#include "core/tasks/unicycle.h"
#include "absl/strings/str_cat.h"
#include "tests/testutil/testutil.h"

namespace totalgrad::cli {
namespace simulate_command_test {

TEST(ParseNumberListTest, ParsesCompleteFiniteNumbers) {
  absl::StatusOr<std::vector<double>> v = ParseNumberList(" 1, -2.5,+3e-1 ,0 ", "--x");
  TG_ASSERT_OK(v.status());
  EXPECT_EQ(*v, (std::vector<double>{1.0, -2.5, 0.3, 0.0}));
  v = ParseNumberList("", "--x");
  TG_ASSERT_OK(v.status());
  EXPECT_TRUE(v->empty());
}

TEST(ParseNumberListTest, ErrorsNameOptionAndEntry) {
  struct Case {
    std::string text, want;
  };
  for (const Case& c : std::vector<Case>{{"1,abc,3", "value 2 'abc' is not a number"},
                                         {"1,,3", "value 2 is empty"},
                                         {"1.5x", "value 1 '1.5x' is not a number"},
                                         {"1,nan", "value 2 'nan' is not finite"},
                                         {"inf", "value 1 'inf' is not finite"},
                                         {"1e999", "value 1 '1e999'"},
                                         {"1,", "value 2 is empty"}}) {
    const absl::StatusOr<std::vector<double>> v = ParseNumberList(c.text, "--forces");
    EXPECT_EQ(v.status().code(), absl::StatusCode::kInvalidArgument) << c.text;
    EXPECT_NE(v.status().message().find("--forces"), std::string::npos) << v.status();
    EXPECT_NE(v.status().message().find(c.want), std::string::npos) << v.status();
  }
}

TEST(ParseSimulateRequestTest, ValidatesEveryOption) {
  absl::StatusOr<SimulateRequest> r = ParseSimulateRequest("cartpole-swingup", "0,3.1,0,0", "1,-2", "0.05");
  TG_ASSERT_OK(r.status());
  EXPECT_EQ(r->start(1), 3.1);
  EXPECT_EQ(r->forces, (std::vector<double>{1.0, -2.0}));
  EXPECT_EQ(r->dt, 0.05);
  struct Case {
    std::string scene, start, forces, dt, want;
  };
  for (const Case& c : std::vector<Case>{
           {"acrobot", "0,0,0,0", "1", "0.1", "--scene"},
           // `trial` refuses "cartpole" too; both name the two cart-pole scenes.
           {"cartpole", "0,0,0,0", "1", "0.1",
            "--scene: unknown scene 'cartpole' (did you mean cartpole-swingup or cartpole-balance?"},
           {"cartpole-swingup", "0,0,0", "1", "0.1", "expected 4 values"},
           {"cartpole-swingup", "0,0,0,0,0", "1", "0.1", "got 5"},
           {"cartpole-swingup", "0,0,x,0", "1", "0.1", "--start: value 3"},
           {"cartpole-swingup", "0,0,0,0", "", "0.1", "--forces: expected at least one"},
           {"cartpole-swingup", "0,0,0,0", "1,inf", "0.1", "--forces: value 2"},
           {"cartpole-swingup", "0,0,0,0", "1", "0", "--dt: must be > 0"},
           {"cartpole-swingup", "0,0,0,0", "1", "-0.1", "--dt"},
           {"cartpole-swingup", "0,0,0,0", "1", "fast", "--dt: 'fast' is not a number"},
           {"cartpole-swingup", "0,0,0,0", "1", "nan", "--dt: 'nan' is not finite"}}) {
    r = ParseSimulateRequest(c.scene, c.start, c.forces, c.dt);
    EXPECT_EQ(r.status().code(), absl::StatusCode::kInvalidArgument) << c.want;
    EXPECT_NE(r.status().message().find(c.want), std::string::npos)
        << "want '" << c.want << "' in " << r.status();
  }
}

TEST(RunSimulationTest, StatesFollowThePlant) {
  SimulateRequest request;
  request.start << 0.1, 0.2, 0.3, 0.4;
  request.forces = {10.0, -10.0, 0.0};
  SimulateResult result;
  TG_ASSERT_OK(RunSimulation(request, &result));
  ASSERT_EQ(result.states.size(), 4u);
  ASSERT_EQ(result.energy.size(), 4u);
  EXPECT_EQ(result.states[0], request.start);
  const tasks::CartPole plant;
  tasks::State x = request.start;
  for (size_t k = 0; k < request.forces.size(); ++k) {
    tasks::State next;
    TG_ASSERT_OK(plant.Step(x, request.forces[k], &next));
    EXPECT_EQ(result.states[k + 1], next) << "step " << k;
    EXPECT_EQ(result.energy[k + 1], plant.Energy(next));
    x = next;
  }
}

// The double pendulum's two torques: --forces holds F = 2 values per step,
// step by step, each step's pair applied together; the JSON lists them per
// step; a count that is not a multiple of F is refused, naming the controls.
TEST(RunSimulationTest, TwoControlsAreAppliedStepByStep) {
  absl::StatusOr<SimulateRequest> r =
      ParseSimulateRequest("double-pendulum", "0,0,3.14,3.14", "1,-1,0.5,0.5", "");
  TG_ASSERT_OK(r.status());
  SimulateResult result;
  TG_ASSERT_OK(RunSimulation(*r, &result));
  EXPECT_EQ(result.controls, 2);
  ASSERT_EQ(result.states.size(), 3u);
  tasks::SceneOptions options;
  options.scene = "double-pendulum";
  absl::StatusOr<tasks::Scene> scene = tasks::MakeScene(options);
  TG_ASSERT_OK(scene.status());
  EXPECT_EQ(result.dt, 0.1);  // the scene's
  Vector x = r->start;
  const std::vector<Vector> torques = {(Vector(2) << 1.0, -1.0).finished(),
                                       (Vector(2) << 0.5, 0.5).finished()};
  for (size_t k = 0; k < torques.size(); ++k) {
    Vector next;
    TG_ASSERT_OK(scene->plant->Step(x, torques[k], &next));
    EXPECT_EQ(result.states[k + 1], next) << "step " << k;
    x = next;
  }
  // Swapping a step's torques changes the result: the pair is not summed.
  absl::StatusOr<SimulateRequest> swapped =
      ParseSimulateRequest("double-pendulum", "0,0,3.14,3.14", "-1,1,0.5,0.5", "");
  TG_ASSERT_OK(swapped.status());
  SimulateResult other;
  TG_ASSERT_OK(RunSimulation(*swapped, &other));
  EXPECT_NE(other.states[1], result.states[1]);

  const nlohmann::json doc = nlohmann::json::parse(FormatSimulationJson(result));
  EXPECT_EQ(doc.at("forces"), nlohmann::json::parse("[[1.0,-1.0],[0.5,0.5]]"));
  EXPECT_EQ(doc.at("states")[2][3].get<double>(), result.states[2](3));

  const absl::StatusOr<SimulateRequest> odd =
      ParseSimulateRequest("double-pendulum", "0,0,3.14,3.14", "1,-1,0.5", "");
  EXPECT_EQ(odd.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(odd.status().message().find("2 controls"), std::string::npos) << odd.status();
}

TEST(RunSimulationTest, IntegratorFailureNamesTheStep) {
  // A force of 1e300 N makes the accelerations overflow to infinity.
  SimulateRequest request;
  request.forces = {1.0, 1e300};
  SimulateResult result;
  const absl::Status st = RunSimulation(request, &result);
  EXPECT_FALSE(st.ok());
  EXPECT_NE(st.message().find("step 1"), std::string::npos) << st;
}

TEST(FormatTest, JsonRoundTripsAndTableHasOneRowPerState) {
  SimulateRequest request;
  request.start << 0.0, 3.0, 0.0, 0.0;
  request.forces = {2.0, 2.0};
  SimulateResult result;
  TG_ASSERT_OK(RunSimulation(request, &result));

  const nlohmann::json doc = nlohmann::json::parse(FormatSimulationJson(result));
  EXPECT_EQ(doc.at("dt").get<double>(), 0.1);
  ASSERT_EQ(doc.at("states").size(), 3u);
  for (size_t k = 0; k < 3; ++k) {
    for (int m = 0; m < 4; ++m) {
      EXPECT_EQ(doc["states"][k][m].get<double>(), result.states[k](m));  // exact round trip
    }
    EXPECT_EQ(doc["energy"][k].get<double>(), result.energy[k]);
  }
  EXPECT_EQ(doc.at("forces").get<std::vector<double>>(), result.forces);
  // Keys in the documented order.
  const std::string json = FormatSimulationJson(result);
  EXPECT_EQ(json.rfind("{\"dt\":", 0), 0u) << json;
  EXPECT_LT(json.find("\"states\""), json.find("\"forces\"")) << json;
  EXPECT_LT(json.find("\"forces\""), json.find("\"energy\"")) << json;

  const std::string table = FormatSimulationTable(result);
  int lines = 0;
  for (char ch : table) lines += ch == '\n';
  EXPECT_EQ(lines, 2 + 3);  // comment, header, one row per state
  EXPECT_NE(table.find("energy"), std::string::npos);
}

using testing_support::CommandRun;
using testing_support::RunCommand;

TEST(SimulateCommandTest, PrintsJson) {
  const CommandRun run = RunCommand(
      {"simulate", "--scene", "cartpole-swingup", "--start", "0,0,0,0", "--forces", "10,10", "--json"});
  EXPECT_EQ(run.exit_code, 0) << run.err;
  EXPECT_TRUE(run.err.empty()) << run.err;
  const nlohmann::json doc = nlohmann::json::parse(run.out);
  ASSERT_EQ(doc.at("states").size(), 3u);
  // PILCO convention: pushing right from hanging moves the cart right.
  EXPECT_GT(doc["states"][2][0].get<double>(), 0.0);
}

// The unicycle (issue 30, item 1): 12 ODE values in PILCO's odei order, two
// torques a step; 30 steps print 31 rows, the plant's own steps bit for bit,
// integrated on through the fall (the constraint is the task's, not the
// plant's): a small roll with no torque falls past pi/2 within the 4.5 s.
TEST(SimulateCommandTest, TheUnicycleFallsAndIsIntegratedThroughTheFall) {
  std::string forces;
  for (int k = 0; k < 30; ++k) absl::StrAppend(&forces, k > 0 ? "," : "", "0,0");
  const CommandRun run = RunCommand({"simulate", "--scene", "unicycle", "--start",
                                     "0,0,0,0,0,0,0,0.05,0,0,0.02,0", "--forces", forces, "--json"});
  EXPECT_EQ(run.exit_code, 0) << run.err;
  const nlohmann::json doc = nlohmann::json::parse(run.out);
  ASSERT_EQ(doc.at("states").size(), 31u);
  ASSERT_EQ(doc["states"][0].size(), 12u);
  EXPECT_EQ(doc.at("dt").get<double>(), 0.15);
  const tasks::SceneDefinition& definition = *tasks::FindSceneDefinition("unicycle");
  const std::unique_ptr<tasks::Plant> plant = tasks::MakePlant(definition);
  Vector x(12);
  x << 0, 0, 0, 0, 0, 0, 0, 0.05, 0, 0, 0.02, 0;
  int fallen_at = -1;
  for (int k = 0; k < 30; ++k) {
    Vector next;
    TG_ASSERT_OK(plant->Step(x, Vector::Zero(2), &next));
    for (int i = 0; i < 12; ++i) {
      ASSERT_EQ(doc["states"][k + 1][i].get<double>(), next(i)) << "step " << k << " entry " << i;
    }
    x = next;
    const bool fallen = std::abs(x(tasks::Unicycle::kRoll)) > M_PI / 2 ||
                        std::abs(x(tasks::Unicycle::kPitch)) > M_PI / 2;
    if (fallen && fallen_at < 0) fallen_at = k + 1;
  }
  EXPECT_GT(fallen_at, 0) << "did not fall in 30 steps";
  EXPECT_LT(fallen_at, 30) << "integrated on after the fall";
  // A wrong count names the two controls.
  const CommandRun odd = RunCommand({"simulate", "--scene", "unicycle", "--start",
                                     "0,0,0,0,0,0,0,0,0,0,0,0", "--forces", "1,2,3", "--json"});
  EXPECT_EQ(odd.exit_code, 2);
  EXPECT_NE(odd.err.find("turntable,wheel"), std::string::npos) << odd.err;
}

TEST(SimulateCommandTest, NegativeNumbersAndDtAreAccepted) {
  const CommandRun run = RunCommand(
      {"simulate", "--start", "-1,3.1,0,0", "--forces", "-2.5", "--dt", "0.05", "--json"});
  EXPECT_EQ(run.exit_code, 0) << run.err;
  const nlohmann::json doc = nlohmann::json::parse(run.out);
  EXPECT_EQ(doc.at("dt").get<double>(), 0.05);
  EXPECT_EQ(doc["states"][0][0].get<double>(), -1.0);
}

TEST(SimulateCommandTest, PrintsTable) {
  const CommandRun run = RunCommand({"simulate", "--start", "0,0,0,0", "--forces", "1,2,3"});
  EXPECT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.out.find("beta"), std::string::npos) << run.out;
}

TEST(SimulateCommandTest, BadInputExitsTwoNamingTheProblem) {
  CommandRun run = RunCommand({"simulate", "--start", "0,0,0", "--forces", "1"});
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.err.find("--start"), std::string::npos) << run.err;
  EXPECT_TRUE(run.out.empty()) << run.out;
  run = RunCommand({"simulate", "--start", "0,0,0,0", "--forces", "1,x"});
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.err.find("'x' is not a number"), std::string::npos) << run.err;
  run = RunCommand({"simulate", "--start", "0,0,0,0"});  // --forces missing: CLI11's error
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.err.find("--forces"), std::string::npos) << run.err;
}

TEST(SimulateCommandTest, IntegrationFailureExitsOne) {
  const CommandRun run = RunCommand({"simulate", "--start", "0,0,0,0", "--forces", "1e300"});
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("integration failed"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("step 0"), std::string::npos) << run.err;
  EXPECT_TRUE(run.out.empty()) << run.out;
}

}  // namespace simulate_command_test
}  // namespace totalgrad::cli
