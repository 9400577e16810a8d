#include "client/core_commands/simulate_command.h"

#include <charconv>
#include <cmath>
#include <iostream>
#include <memory>
#include <string>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "client/core_commands/commands.h"

namespace totalgrad::cli {
namespace {

// One complete decimal number. std::from_chars is locale-independent, unlike
// strtod, so "0.1" means the same on every machine. `index` (1-based) names
// the entry of a list in errors; 0 for a single-valued option.
absl::StatusOr<double> ParseNumber(absl::string_view raw, absl::string_view what, int index) {
  const std::string where =
      index > 0 ? absl::StrCat(what, ": value ", index) : absl::StrCat(what, ":");
  absl::string_view text = absl::StripAsciiWhitespace(raw);
  if (text.empty()) {
    return absl::InvalidArgumentError(absl::StrCat(where, " is empty"));
  }
  absl::string_view digits = text;
  if (digits.front() == '+') digits.remove_prefix(1);  // from_chars rejects a leading '+'
  double value = 0;
  const char* end = digits.data() + digits.size();
  const std::from_chars_result r = std::from_chars(digits.data(), end, value);
  if (r.ec != std::errc() || r.ptr != end) {
    return absl::InvalidArgumentError(
        absl::StrCat(where, " '", text, "' is not a number"));
  }
  if (!std::isfinite(value)) {
    return absl::InvalidArgumentError(
        absl::StrCat(where, " '", text, "' is not finite"));
  }
  return value;
}

struct SimulateFlags {
  std::string scene = "cartpole";
  std::string start;
  std::string forces;
  std::string dt = "0.1";
  bool json = false;
};

int RunSimulateCommand(const SimulateFlags& flags) {
  absl::StatusOr<SimulateRequest> request =
      ParseSimulateRequest(flags.scene, flags.start, flags.forces, flags.dt);
  if (!request.ok()) {
    std::cerr << "simulate: " << request.status().message() << "\n";
    return 2;
  }
  SimulateResult result;
  if (absl::Status st = RunSimulation(*request, &result); !st.ok()) {
    std::cerr << "simulate: integration failed: " << st.message() << "\n";
    return 1;
  }
  std::cout << (flags.json ? FormatSimulationJson(result) : FormatSimulationTable(result));
  std::cout.flush();
  return 0;
}

}  // namespace

absl::StatusOr<std::vector<double>> ParseNumberList(absl::string_view text, absl::string_view what) {
  std::vector<double> values;
  if (absl::StripAsciiWhitespace(text).empty()) return values;
  int index = 1;
  for (absl::string_view entry : absl::StrSplit(text, ',')) {
    absl::StatusOr<double> value = ParseNumber(entry, what, index++);
    if (!value.ok()) return value.status();
    values.push_back(*value);
  }
  return values;
}

absl::StatusOr<SimulateRequest> ParseSimulateRequest(absl::string_view scene,
                                                     absl::string_view start,
                                                     absl::string_view forces,
                                                     absl::string_view dt) {
  if (scene != "cartpole") {
    return absl::InvalidArgumentError(
        absl::StrCat("--scene: unknown scene '", scene, "' (only 'cartpole')"));
  }
  SimulateRequest request;
  absl::StatusOr<std::vector<double>> start_values = ParseNumberList(start, "--start");
  if (!start_values.ok()) return start_values.status();
  if (start_values->size() != tasks::kCartPoleStateDim) {
    return absl::InvalidArgumentError(
        absl::StrCat("--start: expected 4 values s,beta,s_dot,beta_dot, got ",
                     start_values->size()));
  }
  for (int m = 0; m < tasks::kCartPoleStateDim; ++m) request.start(m) = (*start_values)[m];

  absl::StatusOr<std::vector<double>> force_values = ParseNumberList(forces, "--forces");
  if (!force_values.ok()) return force_values.status();
  if (force_values->empty()) {
    return absl::InvalidArgumentError("--forces: expected at least one force");
  }
  request.forces = *std::move(force_values);

  absl::StatusOr<double> dt_value = ParseNumber(dt, "--dt", 0);
  if (!dt_value.ok()) return dt_value.status();
  if (!(*dt_value > 0)) {
    return absl::InvalidArgumentError(absl::StrCat("--dt: must be > 0, got ", *dt_value));
  }
  request.dt = *dt_value;
  return request;
}

absl::Status RunSimulation(const SimulateRequest& request, SimulateResult* result) {
  tasks::CartPoleParams params;
  params.dt = request.dt;
  const tasks::CartPole plant(params);
  result->dt = request.dt;
  result->forces = request.forces;
  result->states.assign(1, request.start);
  result->energy.assign(1, plant.Energy(request.start));
  tasks::State x = request.start;
  for (size_t k = 0; k < request.forces.size(); ++k) {
    tasks::State next;
    if (absl::Status st = plant.Step(x, request.forces[k], &next); !st.ok()) {
      return absl::Status(st.code(), absl::StrCat("step ", k, " (t = ", k * request.dt,
                                                  " s): ", st.message()));
    }
    x = next;
    result->states.push_back(x);
    result->energy.push_back(plant.Energy(x));
  }
  return absl::OkStatus();
}

std::string FormatSimulationTable(const SimulateResult& result) {
  std::string out = absl::StrFormat(
      "# cart-pole, dt = %g s, %d control steps; beta = 0 hanging, pi upright\n",
      result.dt, static_cast<int>(result.forces.size()));
  absl::StrAppendFormat(&out, "%5s %9s %13s %13s %13s %16s %11s %13s\n", "step", "t[s]", "s[m]",
                        "beta[rad]", "s_dot[m/s]", "beta_dot[rad/s]", "force[N]", "energy[J]");
  for (size_t k = 0; k < result.states.size(); ++k) {
    const tasks::State& x = result.states[k];
    const std::string force =
        k < result.forces.size() ? absl::StrFormat("%.4f", result.forces[k]) : "-";
    absl::StrAppendFormat(&out, "%5d %9.4f %13.8f %13.8f %13.8f %16.8f %11s %13.8f\n",
                          static_cast<int>(k), k * result.dt, x(0), x(1), x(2), x(3), force,
                          result.energy[k]);
  }
  return out;
}

std::string FormatSimulationJson(const SimulateResult& result) {
  // ordered_json keeps the documented key order (plain json sorts keys).
  nlohmann::ordered_json states = nlohmann::ordered_json::array();
  for (const tasks::State& x : result.states) states.push_back({x(0), x(1), x(2), x(3)});
  nlohmann::ordered_json doc;
  doc["dt"] = result.dt;
  doc["states"] = std::move(states);
  doc["forces"] = result.forces;
  doc["energy"] = result.energy;
  return doc.dump() + "\n";
}

void AddSimulateCommand(CLI::App* app, int* exit_code) {
  // The flags live as long as the app: CLI11 writes into them during parse
  // and the callback reads them afterwards.
  auto flags = std::make_shared<SimulateFlags>();
  CLI::App* cmd = app->add_subcommand(
      "simulate", "Integrate the noise-free cart-pole plant under a given force sequence");
  cmd->add_option("--scene", flags->scene, "Plant to simulate (only 'cartpole')")
      ->capture_default_str();
  cmd->add_option("--start", flags->start,
                  "Start state s,beta,s_dot,beta_dot (m, rad, m/s, rad/s; beta = 0 hangs down, "
                  "pi is upright)")
      ->required();
  cmd->add_option("--forces", flags->forces,
                  "Forces f1,f2,... in N, each held for one control period (not saturated)")
      ->required();
  cmd->add_option("--dt", flags->dt, "Control period in s")->capture_default_str();
  cmd->add_flag("--json", flags->json, "Print JSON instead of a table");
  cmd->callback([flags, exit_code] { *exit_code = RunSimulateCommand(*flags); });
}

}  // namespace totalgrad::cli
