// `totalgrad pilco propagate FILE.json`: PILCO's moment-matching prediction of
// a scenario (GP data and hyperparameters, policy, start distribution, cost)
// and the gradient of J with respect to the policy parameters, as JSON, so
// that anyone can compare our numbers with the original PILCO's. The file
// format is documented in docs/pilco.md; examples in docs/pilco-examples/.
//
// The parsing (pilco_scenario.cc) and running (pilco_command.cc) are exposed
// for in-process tests.
#ifndef TOTALGRAD_CLIENT_CORE_COMMANDS_PILCO_COMMAND_H_
#define TOTALGRAD_CLIENT_CORE_COMMANDS_PILCO_COMMAND_H_

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/status/statusor.h"
#include "core/common/types.h"
#include "core/tasks/unicycle.h"

namespace totalgrad::cli {

// The general form (a file with "angle_indices"; docs/pilco.md), in PILCO's
// conventions: z = [x, sin x_a1, cos x_a1, ...] (D + 2A), index sets into z,
// F controls, FITC when inducing inputs are given, lossSat on z.
struct GeneralPilcoScenario {
  std::vector<int> angle_indices;    // strictly increasing state indices
  std::vector<int> dynamics_inputs;  // Eq indices into z, strictly increasing
  std::vector<int> policy_inputs;    // Ep indices into z, strictly increasing
  RowMatrix inducing_inputs;         // M x (Eq + F); empty: full GP
  // "rbf" (policy_values, log_lengthscales and the scenario's centres) or
  // "linear" (linear_w, linear_b: PILCO's conlin + gSat).
  std::string policy_type = "rbf";
  RowMatrix linear_w;                // F x Ep
  Vector linear_b;                   // F
  RowMatrix policy_values;           // C x F: weights, or PILCO's pseudo-targets
  bool values_given_as_vector = false;  // a plain C-vector (F = 1)
  RowMatrix log_lengthscales;        // 1 x Ep (shared) or F x Ep (per control)
  bool lengthscales_given_as_vector = false;
  Vector max_force;                  // F, each > 0
  // cost_type (PilcoScenario) "saturating": lossSat on z.
  Vector cost_target;                // D
  Matrix cost_q;                     // (D + 2A) x (D + 2A), symmetric PSD
  std::vector<double> widths;        // >= 1, each > 0
  // cost_type "unicycle": loss_unicycle on the unicycle's 10-entry GP state.
  tasks::UnicycleCostParams unicycle_cost;
};

struct PilcoScenario {
  bool is_general = false;  // the file has "angle_indices": `general` holds the rest
  GeneralPilcoScenario general;
  int angle_index = -1;  // -1 for null
  RowMatrix train_inputs;
  RowMatrix train_targets;
  RowMatrix gp_log_hyp;
  bool prediction_includes_noise = false;
  RowMatrix centres;
  Vector weights;      // set when the file gives "weights"
  Vector targets;      // set when the file gives PILCO's pseudo-"targets"
  bool has_targets = false;
  Vector log_lengthscales;
  double max_force = 10.0;
  double output_variance_jitter = 1e-6;
  Vector mu0;
  Matrix s0;
  int horizon = 0;
  // Cost.
  std::string cost_type;  // "tip" or "angle"; general form: "saturating" or "unicycle"
  int cost_position_index = 0;
  int cost_angle_index = 1;
  double pendulum_length = 0.5;
  double width = 0.25;
  double target_position = 0.0;
  Vector cost_target;
  Matrix cost_q;
};

// InvalidArgument naming the field (and entry) that is missing, has the wrong
// type or shape, or is not finite. The general form (a file with
// "angle_indices") is validated completely here: shapes against D (the
// columns of train_targets), A, F (the columns of policy targets / weights),
// index sets strictly increasing and in range, Q symmetric, every number
// finite, and unknown keys refused.
absl::StatusOr<PilcoScenario> ParsePilcoScenario(const nlohmann::json& doc);

// Runs the prediction and gradient. InvalidArgument for inconsistent
// dimensions; FailedPrecondition when a factorisation fails (GP kernel
// matrix, non-PSD covariance), naming it; Internal for non-finite results.
absl::StatusOr<nlohmann::ordered_json> RunPilcoPropagate(const PilcoScenario& scenario);

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_CORE_COMMANDS_PILCO_COMMAND_H_
