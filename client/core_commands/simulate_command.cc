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
#include "absl/strings/str_join.h"
#include "core/common/check.h"
#include "core/tasks/scene_catalog.h"
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
  std::string scene = "cartpole-swingup";
  std::string start;
  std::string forces;
  std::string dt;  // empty: the scene's
  bool json = false;
};

// The catalog entry of a --scene value (a catalog name, as `trial` takes).
const tasks::SceneDefinition* SimulatedScene(absl::string_view scene) {
  return tasks::FindSceneDefinition(std::string(scene));
}

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
  const tasks::SceneDefinition* definition = SimulatedScene(scene);
  if (definition == nullptr) {
    return absl::InvalidArgumentError(
        absl::StrCat("--scene: ", tasks::UnknownSceneText(std::string(scene))));
  }
  SimulateRequest request;
  request.scene = definition->name;
  const int d = definition->state_dim(), f = definition->control_dim();
  absl::StatusOr<std::vector<double>> start_values = ParseNumberList(start, "--start");
  if (!start_values.ok()) return start_values.status();
  if (static_cast<int>(start_values->size()) != d) {
    return absl::InvalidArgumentError(absl::StrCat("--start: expected ", d, " values ",
                                                   absl::StrJoin(definition->state_names, ","),
                                                   ", got ", start_values->size()));
  }
  request.start = Eigen::Map<const Vector>(start_values->data(), d);

  absl::StatusOr<std::vector<double>> force_values = ParseNumberList(forces, "--forces");
  if (!force_values.ok()) return force_values.status();
  if (force_values->empty()) {
    return absl::InvalidArgumentError("--forces: expected at least one force");
  }
  if (force_values->size() % f != 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "--forces: ", definition->name, " has ", f, " controls (",
        absl::StrJoin(definition->control_names, ","), "); give ", f,
        " values per step, step by step; got ", force_values->size()));
  }
  request.forces = *std::move(force_values);

  if (absl::StripAsciiWhitespace(dt).empty()) {
    request.dt = definition->dt;
    return request;
  }
  absl::StatusOr<double> dt_value = ParseNumber(dt, "--dt", 0);
  if (!dt_value.ok()) return dt_value.status();
  if (!(*dt_value > 0)) {
    return absl::InvalidArgumentError(absl::StrCat("--dt: must be > 0, got ", *dt_value));
  }
  request.dt = *dt_value;
  return request;
}

absl::Status RunSimulation(const SimulateRequest& request, SimulateResult* result) {
  const tasks::SceneDefinition* found = SimulatedScene(request.scene);
  if (found == nullptr) return absl::InvalidArgumentError(absl::StrCat("unknown scene '", request.scene, "'"));
  tasks::SceneDefinition definition = *found;
  definition.dt = request.dt;
  const std::unique_ptr<tasks::Plant> plant = tasks::MakePlant(definition);
  const int f = plant->control_dim();
  if (request.start.size() != plant->state_dim() || request.forces.size() % f != 0) {
    return absl::InvalidArgumentError(absl::StrCat("simulate: ", definition.name, " has ",
                                                   plant->state_dim(), " states and ", f, " controls"));
  }
  result->scene = definition.name;
  result->controls = f;
  result->dt = request.dt;
  result->forces = request.forces;
  result->states.assign(1, request.start);
  result->energy.assign(1, plant->Energy(request.start));
  Vector x = request.start;
  const size_t steps = request.forces.size() / f;
  for (size_t k = 0; k < steps; ++k) {
    const Vector u = Eigen::Map<const Vector>(request.forces.data() + k * f, f);
    Vector next;
    if (absl::Status st = plant->Step(x, u, &next); !st.ok()) {
      return absl::Status(st.code(), absl::StrCat("step ", k, " (t = ", k * request.dt,
                                                  " s): ", st.message()));
    }
    x = next;
    result->states.push_back(x);
    result->energy.push_back(plant->Energy(x));
  }
  return absl::OkStatus();
}

std::string FormatSimulationTable(const SimulateResult& result) {
  const tasks::SceneDefinition* definition = SimulatedScene(result.scene);
  TG_CHECK(definition != nullptr);
  const int steps = static_cast<int>(result.forces.size()) / result.controls;
  std::string out = absl::StrFormat("# %s, dt = %g s, %d control steps\n", definition->name,
                                    result.dt, steps);
  absl::StrAppendFormat(&out, "%5s %9s", "step", "t[s]");
  for (size_t m = 0; m < definition->state_names.size(); ++m) {
    absl::StrAppendFormat(&out, " %16s",
                          absl::StrCat(definition->state_names[m], "[", definition->state_units[m], "]"));
  }
  for (const std::string& name : definition->control_names) absl::StrAppendFormat(&out, " %11s", name);
  absl::StrAppendFormat(&out, " %13s\n", "energy[J]");
  for (size_t k = 0; k < result.states.size(); ++k) {
    const Vector& x = result.states[k];
    absl::StrAppendFormat(&out, "%5d %9.4f", static_cast<int>(k), k * result.dt);
    for (Eigen::Index m = 0; m < x.size(); ++m) absl::StrAppendFormat(&out, " %16.8f", x(m));
    for (int i = 0; i < result.controls; ++i) {
      const size_t at = k * result.controls + i;
      absl::StrAppendFormat(&out, " %11s",
                            at < result.forces.size() ? absl::StrFormat("%.4f", result.forces[at]) : "-");
    }
    absl::StrAppendFormat(&out, " %13.8f\n", result.energy[k]);
  }
  return out;
}

std::string FormatSimulationJson(const SimulateResult& result) {
  // ordered_json keeps the documented key order (plain json sorts keys).
  nlohmann::ordered_json states = nlohmann::ordered_json::array();
  for (const Vector& x : result.states) states.push_back(std::vector<double>(x.data(), x.data() + x.size()));
  nlohmann::ordered_json forces = nlohmann::ordered_json::array();
  if (result.controls == 1) {
    forces = result.forces;
  } else {
    for (size_t k = 0; k + result.controls <= result.forces.size(); k += result.controls)
      forces.push_back(std::vector<double>(result.forces.begin() + k,
                                           result.forces.begin() + k + result.controls));
  }
  nlohmann::ordered_json doc;
  doc["dt"] = result.dt;
  doc["states"] = std::move(states);
  doc["forces"] = std::move(forces);
  doc["energy"] = result.energy;
  return doc.dump() + "\n";
}

void AddSimulateCommand(CLI::App* app, int* exit_code) {
  // The flags live as long as the app: CLI11 writes into them during parse
  // and the callback reads them afterwards.
  auto flags = std::make_shared<SimulateFlags>();
  CLI::App* cmd = app->add_subcommand(
      "simulate", "Integrate a scene's noise-free plant under a given control sequence");
  cmd->add_option("--scene", flags->scene,
                  "Scene whose plant to simulate (a name of `totalgrad scenes`, as `trial` takes)")
      ->capture_default_str();
  cmd->add_option("--start", flags->start,
                  "Start state, D values in the scene's state order (cart-pole: s,beta,s_dot,"
                  "beta_dot in m, rad, m/s, rad/s; beta = 0 hangs down, pi is upright)")
      ->required();
  cmd->add_option("--forces", flags->forces,
                  "Controls step by step, F per step (f_1^1..f_1^F,f_2^1,...), each held for one "
                  "control period (not saturated)")
      ->required();
  cmd->add_option("--dt", flags->dt, "Control period in s (default: the scene's)");
  cmd->add_flag("--json", flags->json, "Print JSON instead of a table");
  cmd->callback([flags, exit_code] { *exit_code = RunSimulateCommand(*flags); });
}

}  // namespace totalgrad::cli
