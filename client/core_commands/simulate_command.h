// The logic behind `totalgrad simulate`, split from the CLI11 wiring so that
// tests can call it directly.
//
//   totalgrad simulate --scene NAME --start v1,...,vD
//                      --forces f_1^1..f_1^F,f_2^1,... [--dt DT] [--json]
//
// integrates the noise-free plant of a scene (core/tasks/scene_catalog.h;
// "cartpole" is the cart-pole's plant, as before) with the adaptive
// Dormand-Prince integrator from the start state, holding the controls of
// step k (F values) for one control period dt, and prints the states
// x_0 .. x_K (K = number of steps), one per control step including the
// start, in the scene's state order, with the mechanical energy of each.
// dt defaults to the scene's. Controls are applied as given: no saturation.
//
// Thread safety: free functions, no shared state.
#ifndef TOTALGRAD_CLIENT_CORE_COMMANDS_SIMULATE_COMMAND_H_
#define TOTALGRAD_CLIENT_CORE_COMMANDS_SIMULATE_COMMAND_H_

#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/common/types.h"

namespace totalgrad::cli {

// Parses a comma-separated list of finite decimal numbers ("1, -2.5,3e-1").
// Whitespace around an entry is ignored; an empty list ("") gives no values.
// InvalidArgument names `what` and the offending entry (1-based) when an
// entry is empty, not a complete number, or not finite.
absl::StatusOr<std::vector<double>> ParseNumberList(absl::string_view text, absl::string_view what);

struct SimulateRequest {
  std::string scene = "cartpole-swingup";  // a catalog name
  Vector start = Vector::Zero(4);          // D
  std::vector<double> forces;  // K x F, step by step (f_1^1..f_1^F, f_2^1, ...)
  double dt = 0.1;             // s, control period
};

// Builds a request from the raw option strings. InvalidArgument, naming the
// option, for: an unknown scene ("cartpole" means cartpole-swingup); a start
// that is not exactly D finite numbers; no controls, a non-finite one, or a
// count that is not a multiple of F; dt not a finite number > 0 (empty: the
// scene's dt).
absl::StatusOr<SimulateRequest> ParseSimulateRequest(absl::string_view scene,
                                                     absl::string_view start,
                                                     absl::string_view forces, absl::string_view dt);

struct SimulateResult {
  std::string scene;
  int controls = 1;                  // F
  double dt = 0;
  std::vector<Vector> states;        // K + 1, states[0] is the start
  std::vector<double> forces;        // K x F, step k's acts from states[k] to states[k+1]
  std::vector<double> energy;        // K + 1, the plant's Energy of each state (J)
};

// Integrates the request on the scene's plant with dt replaced. On failure
// (the integrator cannot vouch for a step) returns the plant's status with
// the step number prefixed; *result is then unspecified.
absl::Status RunSimulation(const SimulateRequest& request, SimulateResult* result);

// A fixed-width, human-readable table, one row per state.
std::string FormatSimulationTable(const SimulateResult& result);

// {"dt":..,"states":[[x_1..x_D],...],"forces":[...],"energy":[...]} with the
// forces one number per step for one control, else one list of F per step;
// doubles printed to round-trip precision, followed by a newline.
std::string FormatSimulationJson(const SimulateResult& result);

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_CORE_COMMANDS_SIMULATE_COMMAND_H_
