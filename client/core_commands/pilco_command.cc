// Running `totalgrad pilco propagate` (pilco_command.h: RunPilcoPropagate
// and the command): PILCO's propagation of a parsed scenario and dJ/dtheta
// as JSON. Reading the scenario file is in pilco_scenario.cc.
#include "client/core_commands/pilco_command.h"

#include <cmath>
#include <fstream>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "client/core_commands/commands.h"
#include "core/gp/fitc.h"
#include "core/gp/gp.h"
#include "core/gaussian/expected_cost.h"
#include "core/pilco/gp_moments.h"
#include "core/pilco/policy_moments.h"
#include "core/pilco/propagation.h"
#include "core/tasks/unicycle.h"

namespace totalgrad::cli {
namespace {

using Json = nlohmann::json;

Json MatrixJson(const Matrix& m) {
  Json rows = Json::array();
  for (Eigen::Index r = 0; r < m.rows(); ++r) {
    Json row = Json::array();
    for (Eigen::Index c = 0; c < m.cols(); ++c) row.push_back(m(r, c));
    rows.push_back(std::move(row));
  }
  return rows;
}

Json VectorJson(const Vector& v) {
  Json out = Json::array();
  for (Eigen::Index i = 0; i < v.size(); ++i) out.push_back(v(i));
  return out;
}

// The augmented target z_t = [x_t, sin x_t,a1, cos x_t,a1, ...].
Vector AugmentedTarget(const Vector& target, const std::vector<int>& angles) {
  const int d = static_cast<int>(target.size());
  Vector z(d + 2 * angles.size());
  z.head(d) = target;
  for (size_t k = 0; k < angles.size(); ++k) {
    z(d + 2 * k) = std::sin(target(angles[k]));
    z(d + 2 * k + 1) = std::cos(target(angles[k]));
  }
  return z;
}

// What PropagateAndWrite returns: the policy's parameters with weights (the
// given ones, or those of the given pseudo-targets) and dJ with respect to
// the parameters as given.
struct Propagated {
  Vector params;
  Vector grad_given;
};

// Runs PILCO's propagation of both forms from the policy parameters as the
// file gave them (`given`: weights, or pseudo-targets when s.has_targets, in
// RbfPolicy's layout) and writes the trajectory ("mean", "cov", "cost_mean",
// "cost_std", "J") into *out.
absl::StatusOr<Propagated> PropagateAndWrite(const pilco::Propagator& prop, const gaussian::GaussianCost& cost,
                                         const PilcoScenario& s, const Vector& given,
                                         nlohmann::ordered_json* out) {
  Vector params = given;
  if (s.has_targets) {
    if (absl::Status st = pilco::PseudoTargetsToWeights(prop.policy_shape(), given, &params);
        !st.ok()) {
      return st;
    }
  }
  pilco::Trajectory tr;
  Vector grad;
  if (absl::Status st = pilco::PredictTrajectory(prop, cost, params, s.mu0, s.s0, s.horizon,
                                                 &tr, &grad);
      !st.ok()) {
    return st;
  }
  Vector grad_given = grad;
  if (s.has_targets) {
    if (absl::Status st =
            pilco::PseudoTargetsBackward(prop.policy_shape(), given, grad, &grad_given);
        !st.ok()) {
      return st;
    }
  }
  Json means = Json::array(), covs = Json::array();
  for (size_t t = 0; t < tr.means.size(); ++t) {
    means.push_back(VectorJson(tr.means[t]));
    covs.push_back(MatrixJson(tr.covs[t]));
  }
  (*out)["mean"] = std::move(means);
  (*out)["cov"] = std::move(covs);
  (*out)["cost_mean"] = VectorJson(tr.cost_mean);
  (*out)["cost_std"] = VectorJson(tr.cost_std);
  (*out)["J"] = tr.total_cost;
  return Propagated{std::move(params), std::move(grad_given)};
}

// The general form's dynamics GP: the full GP, or FITC as PILCO's gp1 with
// the file's inducing inputs and hyperparameters.
absl::StatusOr<pilco::GaussianInputGp> GeneralDynamics(const PilcoScenario& s) {
  const GeneralPilcoScenario& g = s.general;
  absl::StatusOr<pilco::GaussianInputGp> gp;
  if (g.inducing_inputs.rows() == 0) {
    gp = pilco::GaussianInputGpFromData(s.train_inputs, s.train_targets, s.gp_log_hyp);
  } else {
    // FITC as PILCO's gp1, with the file's inducing inputs and hyperparameters.
    gp::GpHyperparameters hyp;
    const int e = static_cast<int>(s.gp_log_hyp.cols()) - 2;
    hyp.log_lengthscales = s.gp_log_hyp.leftCols(e);
    hyp.log_signal_std = s.gp_log_hyp.col(e);
    hyp.log_noise_std = s.gp_log_hyp.col(e + 1);
    absl::StatusOr<gp::FitcModel> fitc =
        gp::FitcModel::Create(s.train_inputs, s.train_targets, hyp, g.inducing_inputs);
    if (!fitc.ok()) return fitc.status();
    gp = pilco::GaussianInputGpFromFitc(*fitc);
  }
  return gp;
}

absl::StatusOr<gaussian::GaussianCost> GeneralCost(const PilcoScenario& s) {
  const GeneralPilcoScenario& g = s.general;
  if (s.cost_type == "unicycle") return tasks::UnicycleCost(g.unicycle_cost);
  const int d = static_cast<int>(s.train_targets.cols());
  return gaussian::GaussianCost::Saturating(d, g.angle_indices, g.cost_q,
                                            AugmentedTarget(g.cost_target, g.angle_indices),
                                            g.widths);
}

// The linear policy's run: parameters [W column-major, b] in, dJ_dw (F x
// Ep, as the file's w) and dJ_db out.
absl::StatusOr<nlohmann::ordered_json> RunGeneralLinear(const PilcoScenario& s,
                                                        const pilco::GaussianInputGp& gp,
                                                        pilco::PropagationOptions options,
                                                        const gaussian::GaussianCost& cost) {
  const GeneralPilcoScenario& g = s.general;
  const int f = static_cast<int>(g.linear_w.rows()), ep = static_cast<int>(g.linear_w.cols());
  options.policy_class = pilco::PolicyClass::kLinear;
  if (absl::Status st = pilco::Propagator::Validate(gp, options); !st.ok()) return st;
  const pilco::Propagator prop(&gp, options);
  Vector given(prop.num_parameters());
  const Matrix w = g.linear_w;  // column-major, as PILCO's unwrap
  given << Eigen::Map<const Vector>(w.data(), f * ep), g.linear_b;
  nlohmann::ordered_json out;
  absl::StatusOr<Propagated> propagated = PropagateAndWrite(prop, cost, s, given, &out);
  if (!propagated.ok()) return propagated.status();
  const Vector& grad = propagated->grad_given;
  out["dJ_dw"] = MatrixJson(Eigen::Map<const Matrix>(grad.data(), f, ep));
  out["dJ_db"] = VectorJson(grad.tail(f));
  return out;
}

absl::StatusOr<nlohmann::ordered_json> RunGeneral(const PilcoScenario& s) {
  const GeneralPilcoScenario& g = s.general;
  absl::StatusOr<pilco::GaussianInputGp> gp = GeneralDynamics(s);
  if (!gp.ok()) return gp.status();
  absl::StatusOr<gaussian::GaussianCost> cost = GeneralCost(s);
  if (!cost.ok()) return cost.status();

  pilco::PropagationOptions options;
  // One angle keeps the one-angle option (today's form's code and bits).
  if (g.angle_indices.size() == 1) {
    options.angle_index = g.angle_indices[0];
  } else {
    options.angle_indices = g.angle_indices;
  }
  options.policy_inputs = g.policy_inputs;
  options.dynamics_inputs = g.dynamics_inputs;
  options.prediction_includes_noise = s.prediction_includes_noise;
  if (g.max_force.size() == 1) {
    options.max_force = g.max_force(0);
  } else {
    options.max_controls = g.max_force;
  }
  if (g.policy_type == "linear") return RunGeneralLinear(s, *gp, options, *cost);

  const int c = static_cast<int>(s.centres.rows());
  const int ep = static_cast<int>(g.policy_inputs.size());
  const int f = static_cast<int>(g.policy_values.cols());
  // F x Ep rows with F >= 2: PILCO's per-output policy hyperparameters.
  const bool per_control = !g.lengthscales_given_as_vector && f > 1;
  const int ll_rows = per_control ? f : 1;
  options.policy_jitter = s.output_variance_jitter;
  options.num_basis = c;
  options.policy_lengthscale_per_control = per_control;
  if (absl::Status st = pilco::Propagator::Validate(*gp, options); !st.ok()) return st;
  const pilco::Propagator prop(&*gp, options);

  // [centres row-major, log l (1 or F rows, row-major), values C x F
  // row-major] (RbfPolicy's layout; RbfPolicyShape::lengthscale_per_control).
  Vector given(prop.num_parameters());
  given << Eigen::Map<const Vector>(s.centres.data(), c * ep),
      Eigen::Map<const Vector>(g.log_lengthscales.data(), ll_rows * ep),
      Eigen::Map<const Vector>(g.policy_values.data(), c * f);
  nlohmann::ordered_json out;
  absl::StatusOr<Propagated> propagated = PropagateAndWrite(prop, *cost, s, given, &out);
  if (!propagated.ok()) return propagated.status();
  const Vector& params = propagated->params;
  const Vector& grad_given = propagated->grad_given;
  out["dJ_dcentres"] = MatrixJson(Eigen::Map<const RowMatrix>(grad_given.data(), c, ep));
  // Values and their gradient in the shape the file gave them.
  auto values_json = [&](const Vector& v) -> Json {
    if (g.values_given_as_vector) return VectorJson(v);
    return MatrixJson(Eigen::Map<const RowMatrix>(v.data(), c, f));
  };
  const Vector grad_values = grad_given.tail(c * f);  // after centres and log l
  if (s.has_targets) {
    out["dJ_dtargets"] = values_json(grad_values);
    out["weights"] = values_json(params.tail(c * f));
  } else {
    out["dJ_dweights"] = values_json(grad_values);
  }
  const Vector grad_ll = grad_given.segment(c * ep, ll_rows * ep);
  if (g.lengthscales_given_as_vector) {
    out["dJ_dlog_lengthscales"] = VectorJson(grad_ll);
  } else {
    out["dJ_dlog_lengthscales"] = MatrixJson(Eigen::Map<const RowMatrix>(grad_ll.data(), ll_rows, ep));
  }
  return out;
}

int RunPropagateFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) {
    std::cerr << "pilco propagate: cannot open '" << path << "'\n";
    return 2;
  }
  Json doc = Json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) {
    std::cerr << "pilco propagate: '" << path << "' is not valid JSON\n";
    return 2;
  }
  absl::StatusOr<PilcoScenario> scenario = ParsePilcoScenario(doc);
  if (!scenario.ok()) {
    std::cerr << "pilco propagate: " << scenario.status().message() << "\n";
    return 2;
  }
  absl::StatusOr<nlohmann::ordered_json> out = RunPilcoPropagate(*scenario);
  if (!out.ok()) {
    std::cerr << "pilco propagate: " << out.status().message() << "\n";
    return out.status().code() == absl::StatusCode::kInvalidArgument ? 2 : 1;
  }
  std::cout << out->dump() << "\n";
  std::cout.flush();
  return 0;
}

}  // namespace
absl::StatusOr<nlohmann::ordered_json> RunPilcoPropagate(const PilcoScenario& s) {
  if (s.is_general) return RunGeneral(s);
  const int d = static_cast<int>(s.train_targets.cols());
  const int n = static_cast<int>(s.train_inputs.rows());
  if (n == 0) return absl::InvalidArgumentError("train_inputs: no rows");
  if (s.mu0.size() != d) {
    return absl::InvalidArgumentError(
        absl::StrCat("mu0: has ", s.mu0.size(), " entries, train_targets has ", d, " columns"));
  }
  if (s.s0.rows() != d || s.s0.cols() != d) {
    return absl::InvalidArgumentError(absl::StrCat("S0: must be ", d, " x ", d));
  }
  if (s.angle_index >= d) {
    return absl::InvalidArgumentError(
        absl::StrCat("angle_index: ", s.angle_index, " is not a state index (state dim ", d, ")"));
  }
  const int ep = s.angle_index >= 0 ? d + 1 : d;
  if (s.train_inputs.cols() != ep + 1) {
    return absl::InvalidArgumentError(absl::StrCat(
        "train_inputs: rows must have ", ep + 1, " entries (",
        s.angle_index >= 0 ? "the other state dims, sin, cos, u" : "state, u", "), have ",
        s.train_inputs.cols()));
  }
  const int c = static_cast<int>(s.centres.rows());
  if (c == 0 || s.centres.cols() != ep) {
    return absl::InvalidArgumentError(
        absl::StrCat("policy.centres: must be C rows of ", ep, " entries (policy inputs)"));
  }
  const Vector& w = s.has_targets ? s.targets : s.weights;
  if (w.size() != c) {
    return absl::InvalidArgumentError(absl::StrCat("policy.", s.has_targets ? "targets" : "weights",
                                                   ": must have ", c, " entries (one per centre)"));
  }
  if (s.log_lengthscales.size() != ep) {
    return absl::InvalidArgumentError(
        absl::StrCat("policy.log_lengthscales: must have ", ep, " entries"));
  }
  if (!(s.max_force > 0)) return absl::InvalidArgumentError("policy.max_force: must be > 0");
  if (!(s.output_variance_jitter >= 0)) {
    return absl::InvalidArgumentError("policy.output_variance_jitter: must be >= 0");
  }

  absl::StatusOr<pilco::GaussianInputGp> gp =
      pilco::GaussianInputGpFromData(s.train_inputs, s.train_targets, s.gp_log_hyp);
  if (!gp.ok()) return gp.status();

  pilco::PropagationOptions options;
  options.angle_index = s.angle_index;
  options.prediction_includes_noise = s.prediction_includes_noise;
  options.policy_jitter = s.output_variance_jitter;
  options.max_force = s.max_force;
  options.num_basis = c;
  if (absl::Status st = pilco::Propagator::Validate(*gp, options); !st.ok()) return st;
  const pilco::Propagator prop(&*gp, options);

  absl::StatusOr<gaussian::GaussianCost> cost =
      s.cost_type == "tip"
          ? gaussian::GaussianCost::Tip(d, s.cost_position_index, s.cost_angle_index,
                                     s.pendulum_length, s.width, s.target_position)
          : gaussian::GaussianCost::Angle(s.cost_target, s.cost_q);
  if (!cost.ok()) return cost.status();

  Vector given(prop.num_parameters());
  given << Eigen::Map<const Vector>(s.centres.data(), c * ep), s.log_lengthscales, w;
  nlohmann::ordered_json out;
  absl::StatusOr<Propagated> propagated = PropagateAndWrite(prop, *cost, s, given, &out);
  if (!propagated.ok()) return propagated.status();
  const Vector& params = propagated->params;
  const Vector& grad_given = propagated->grad_given;
  const RowMatrix dc = Eigen::Map<const RowMatrix>(grad_given.data(), c, ep);
  out["dJ_dcentres"] = MatrixJson(dc);
  if (s.has_targets) {
    out["dJ_dtargets"] = VectorJson(grad_given.tail(c));
    out["weights"] = VectorJson(params.tail(c));
  } else {
    out["dJ_dweights"] = VectorJson(grad_given.tail(c));
  }
  out["dJ_dlog_lengthscales"] = VectorJson(grad_given.segment(c * ep, ep));
  return out;
}

void AddPilcoCommand(CLI::App* app, int* exit_code) {
  CLI::App* pilco = app->add_subcommand("pilco", "PILCO's analytic moment-matching tools");
  pilco->require_subcommand(1);
  auto path = std::make_shared<std::string>();
  CLI::App* propagate = pilco->add_subcommand(
      "propagate",
      "Predict a scenario's state distributions, expected costs, J and dJ/dtheta by moment "
      "matching; prints JSON (format: docs/pilco.md)");
  propagate->add_option("FILE", *path, "Scenario JSON file")->required();
  propagate->callback([path, exit_code] { *exit_code = RunPropagateFile(*path); });
}

}  // namespace totalgrad::cli
