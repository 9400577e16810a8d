// `totalgrad pilco propagate FILE.json`: PILCO's moment-matching prediction of
// a scenario (GP data and hyperparameters, policy, start distribution, cost)
// and the gradient of J with respect to the policy parameters, as JSON, so
// that anyone can compare our numbers with the original PILCO's. The file
// format is documented in docs/pilco.md; examples in docs/pilco-examples/.
//
// The parsing and running are exposed for in-process tests.
#ifndef TOTALGRAD_CLIENT_CORE_COMMANDS_PILCO_COMMAND_H_
#define TOTALGRAD_CLIENT_CORE_COMMANDS_PILCO_COMMAND_H_

#include <string>

#include <nlohmann/json.hpp>

#include "absl/status/statusor.h"
#include "core/common/types.h"

namespace totalgrad::cli {

struct PilcoScenario {
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
  std::string cost_type;  // "tip" or "angle"
  int cost_position_index = 0;
  int cost_angle_index = 1;
  double pendulum_length = 0.5;
  double width = 0.25;
  double target_position = 0.0;
  Vector cost_target;
  Matrix cost_q;
};

// InvalidArgument naming the field (and entry) that is missing, has the wrong
// type or shape, or is not finite.
absl::StatusOr<PilcoScenario> ParsePilcoScenario(const nlohmann::json& doc);

// Runs the prediction and gradient. InvalidArgument for inconsistent
// dimensions; FailedPrecondition when a factorisation fails (GP kernel
// matrix, non-PSD covariance), naming it; Internal for non-finite results.
absl::StatusOr<nlohmann::ordered_json> RunPilcoPropagate(const PilcoScenario& scenario);

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_CORE_COMMANDS_PILCO_COMMAND_H_
