// The logic behind `totalgrad simulate`, split from the CLI11 wiring so that
// tests can call it directly.
//
//   totalgrad simulate --scene cartpole --start s,beta,s_dot,beta_dot
//                      --forces f1,f2,... [--dt 0.1] [--json]
//
// integrates the noise-free cart-pole plant (PILCO constants, adaptive
// Dormand-Prince) from the start state, holding force f_k for one control
// period dt at step k, and prints the states x_0 .. x_K (K = number of
// forces), one per control step including the start, with the mechanical
// energy of each. State order and angle convention as in core/tasks/cartpole.h
// (beta = 0 hanging, beta = pi upright). Forces are applied as given: no
// saturation.
//
// Thread safety: free functions, no shared state.
#ifndef TOTALGRAD_CLIENT_CORE_COMMANDS_SIMULATE_COMMAND_H_
#define TOTALGRAD_CLIENT_CORE_COMMANDS_SIMULATE_COMMAND_H_

#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/tasks/cartpole.h"

namespace totalgrad::cli {

// Parses a comma-separated list of finite decimal numbers ("1, -2.5,3e-1").
// Whitespace around an entry is ignored; an empty list ("") gives no values.
// InvalidArgument names `what` and the offending entry (1-based) when an
// entry is empty, not a complete number, or not finite.
absl::StatusOr<std::vector<double>> ParseNumberList(absl::string_view text, absl::string_view what);

struct SimulateRequest {
  tasks::State start = tasks::State::Zero();
  std::vector<double> forces;  // N, one per control step
  double dt = 0.1;             // s, control period
};

// Builds a request from the raw option strings. InvalidArgument, naming the
// option, for: a scene other than "cartpole"; a start that is not exactly 4
// finite numbers; no forces or a non-finite force; dt not a finite number
// > 0.
absl::StatusOr<SimulateRequest> ParseSimulateRequest(absl::string_view scene,
                                                     absl::string_view start,
                                                     absl::string_view forces, absl::string_view dt);

struct SimulateResult {
  double dt = 0;
  std::vector<tasks::State> states;  // K + 1, states[0] is the start
  std::vector<double> forces;        // K, forces[k] acts from states[k] to states[k+1]
  std::vector<double> energy;        // K + 1, CartPole::Energy of each state (J)
};

// Integrates the request on the default plant with dt replaced. On failure
// (the integrator cannot vouch for a step) returns the plant's status with
// the step number prefixed; *result is then unspecified.
absl::Status RunSimulation(const SimulateRequest& request, SimulateResult* result);

// A fixed-width, human-readable table, one row per state.
std::string FormatSimulationTable(const SimulateResult& result);

// {"dt":..,"states":[[s,beta,s_dot,beta_dot],...],"forces":[...],"energy":[...]}
// with doubles printed to round-trip precision, followed by a newline.
std::string FormatSimulationJson(const SimulateResult& result);

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_CORE_COMMANDS_SIMULATE_COMMAND_H_
