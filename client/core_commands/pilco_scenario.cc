// Reading `totalgrad pilco propagate` scenario files (pilco_command.h:
// ParsePilcoScenario): the cart-pole form and the general form of
// docs/pilco.md, every field checked (shape, range, finiteness) and named in
// the error. Running a parsed scenario is in pilco_command.cc.
#include <cmath>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "client/core_commands/pilco_command.h"

namespace totalgrad::cli {
namespace {

using Json = nlohmann::json;

absl::StatusOr<double> Number(const Json& v, const std::string& what) {
  if (!v.is_number()) return absl::InvalidArgumentError(absl::StrCat(what, ": not a number"));
  const double x = v.get<double>();
  if (!std::isfinite(x)) return absl::InvalidArgumentError(absl::StrCat(what, ": not finite"));
  return x;
}

const Json* Field(const Json& obj, const std::string& key) {
  auto it = obj.find(key);
  return it == obj.end() ? nullptr : &*it;
}

absl::StatusOr<const Json*> Required(const Json& obj, const std::string& key,
                                     const std::string& where) {
  const Json* v = Field(obj, key);
  if (v == nullptr) {
    return absl::InvalidArgumentError(absl::StrCat("missing field '", where, key, "'"));
  }
  return v;
}

absl::StatusOr<Vector> ToVector(const Json& v, const std::string& what) {
  if (!v.is_array()) return absl::InvalidArgumentError(absl::StrCat(what, ": not an array"));
  Vector out(v.size());
  for (size_t i = 0; i < v.size(); ++i) {
    absl::StatusOr<double> x = Number(v[i], absl::StrCat(what, "[", i, "]"));
    if (!x.ok()) return x.status();
    out(i) = *x;
  }
  return out;
}

absl::StatusOr<RowMatrix> ToMatrix(const Json& v, const std::string& what) {
  if (!v.is_array()) return absl::InvalidArgumentError(absl::StrCat(what, ": not an array"));
  RowMatrix out;
  for (size_t i = 0; i < v.size(); ++i) {
    absl::StatusOr<Vector> row = ToVector(v[i], absl::StrCat(what, "[", i, "]"));
    if (!row.ok()) return row.status();
    if (i == 0) out.resize(v.size(), row->size());
    if (row->size() != out.cols()) {
      return absl::InvalidArgumentError(absl::StrCat(what, "[", i, "]: has ", row->size(),
                                                     " entries, row 0 has ", out.cols()));
    }
    out.row(i) = row->transpose();
  }
  return out;
}

absl::StatusOr<int> ToIndex(const Json& v, const std::string& what) {
  if (!v.is_number_integer()) {
    return absl::InvalidArgumentError(absl::StrCat(what, ": not an integer"));
  }
  return v.get<int>();
}

#define TG_ASSIGN_OR_RETURN_IMPL(var, expr, tmp) \
  auto tmp = (expr);                             \
  if (!tmp.ok()) return tmp.status();            \
  var = *std::move(tmp)
#define TG_CONCAT_INNER(a, b) a##b
#define TG_CONCAT(a, b) TG_CONCAT_INNER(a, b)
#define TG_ASSIGN_OR_RETURN(var, expr) \
  TG_ASSIGN_OR_RETURN_IMPL(var, expr, TG_CONCAT(status_or_, __LINE__))

// ------------------------------------------------------------ general form

absl::Status OnlyKnownKeys(const Json& obj, const std::set<std::string>& known,
                           const std::string& where) {
  for (auto it = obj.begin(); it != obj.end(); ++it) {
    if (known.count(it.key()) == 0) {
      return absl::InvalidArgumentError(
          absl::StrCat("unknown field '", where, it.key(), "' (general form, docs/pilco.md)"));
    }
  }
  return absl::OkStatus();
}

// A JSON array of integers, strictly increasing, each in [0, bound).
absl::StatusOr<std::vector<int>> IndexList(const Json& v, const std::string& what, int bound,
                                           const std::string& bound_name, bool allow_empty) {
  if (!v.is_array()) return absl::InvalidArgumentError(absl::StrCat(what, ": not an array"));
  if (v.empty() && !allow_empty) return absl::InvalidArgumentError(absl::StrCat(what, ": empty"));
  std::vector<int> out;
  for (size_t k = 0; k < v.size(); ++k) {
    const std::string entry = absl::StrCat(what, "[", k, "]");
    absl::StatusOr<int> i = ToIndex(v[k], entry);
    if (!i.ok()) return i.status();
    if (*i < 0 || *i >= bound) {
      return absl::InvalidArgumentError(absl::StrCat(entry, ": ", *i, " is out of range [0, ", bound,
                                                     ") (", bound_name, ")"));
    }
    if (k > 0 && *i <= out.back()) {
      return absl::InvalidArgumentError(absl::StrCat(
          what, ": indices must be strictly increasing (entry ", k, " is ", *i, " after ",
          out.back(), ")"));
    }
    out.push_back(*i);
  }
  return out;
}

absl::Status Shape(const RowMatrix& m, Eigen::Index rows, Eigen::Index cols,
                   const std::string& what, const std::string& meaning) {
  if (m.rows() != rows || m.cols() != cols) {
    return absl::InvalidArgumentError(absl::StrCat(what, ": must be ", rows, " x ", cols, " (",
                                                   meaning, "), is ", m.rows(), " x ", m.cols()));
  }
  return absl::OkStatus();
}

// A matrix that is either a plain vector (one row) or an array of rows.
absl::StatusOr<RowMatrix> VectorOrMatrix(const Json& v, const std::string& what, bool* was_vector) {
  if (v.is_array() && !v.empty() && v.front().is_array()) {
    *was_vector = false;
    return ToMatrix(v, what);
  }
  *was_vector = true;
  TG_ASSIGN_OR_RETURN(Vector x, ToVector(v, what));
  return RowMatrix(x.transpose());
}
// policy.max_force: F positive bounds (a plain number when F = 1).
absl::StatusOr<Vector> MaxForce(const Json& policy, int f, const std::string& f_from) {
  TG_ASSIGN_OR_RETURN(const Json* mf, Required(policy, "max_force", "policy."));
  Vector max_force;
  if (mf->is_number()) {
    TG_ASSIGN_OR_RETURN(double one, Number(*mf, "policy.max_force"));
    max_force = Vector::Constant(1, one);
  } else {
    TG_ASSIGN_OR_RETURN(max_force, ToVector(*mf, "policy.max_force"));
  }
  if (max_force.size() != f) {
    return absl::InvalidArgumentError(absl::StrCat("policy.max_force: must have ", f,
                                                   " entries (F, ", f_from, "), has ",
                                                   max_force.size()));
  }
  for (int j = 0; j < f; ++j) {
    if (!(max_force(j) > 0)) {
      return absl::InvalidArgumentError(
          absl::StrCat("policy.max_force[", j, "]: must be > 0, is ", max_force(j)));
    }
  }
  return max_force;
}

// The linear policy (PILCO's conlin + gSat): w F x Ep, b F, max_force F.
absl::StatusOr<int> ParseGeneralLinearPolicy(const Json& policy, int ep, PilcoScenario* out) {
  GeneralPilcoScenario& g = out->general;
  if (absl::Status st = OnlyKnownKeys(policy, {"type", "w", "b", "max_force"}, "policy.");
      !st.ok()) {
    return st;
  }
  g.policy_type = "linear";
  TG_ASSIGN_OR_RETURN(const Json* w, Required(policy, "w", "policy."));
  TG_ASSIGN_OR_RETURN(g.linear_w, ToMatrix(*w, "policy.w"));
  const int f = static_cast<int>(g.linear_w.rows());
  if (f == 0) return absl::InvalidArgumentError("policy.w: no rows (F >= 1 controls)");
  if (absl::Status st = Shape(g.linear_w, f, ep, "policy.w", "F x len(policy_inputs)"); !st.ok()) {
    return st;
  }
  TG_ASSIGN_OR_RETURN(const Json* b, Required(policy, "b", "policy."));
  TG_ASSIGN_OR_RETURN(g.linear_b, ToVector(*b, "policy.b"));
  if (g.linear_b.size() != f) {
    return absl::InvalidArgumentError(absl::StrCat(
        "policy.b: must have ", f, " entries (F, the rows of policy.w), has ", g.linear_b.size()));
  }
  TG_ASSIGN_OR_RETURN(g.max_force, MaxForce(policy, f, "the rows of policy.w"));
  return f;
}

// policy: the RBF policy on z(policy_inputs) (its centres, weights or
// PILCO's pseudo-targets, lengthscales and force limits), or with "type":
// "linear" the linear one. Returns F, the number of controls (the columns of
// the weights or targets, the rows of w).
absl::StatusOr<int> ParseGeneralPolicy(const Json& doc, int ep, PilcoScenario* out) {
  PilcoScenario& s = *out;
  GeneralPilcoScenario& g = s.general;
  // The policy fixes F (the columns of targets / weights).
  TG_ASSIGN_OR_RETURN(const Json* policy, Required(doc, "policy", ""));
  if (!policy->is_object()) return absl::InvalidArgumentError("policy: not an object");
  if (const Json* type = Field(*policy, "type"); type != nullptr) {
    if (!type->is_string() ||
        (type->get<std::string>() != "rbf" && type->get<std::string>() != "linear")) {
      return absl::InvalidArgumentError(
          "policy.type: \"rbf\" (the default) or \"linear\" (PILCO's conlin + gSat)");
    }
    if (type->get<std::string>() == "linear") return ParseGeneralLinearPolicy(*policy, ep, out);
  }
  if (absl::Status st = OnlyKnownKeys(*policy,
                                      {"type", "centres", "weights", "targets", "log_lengthscales",
                                       "max_force", "output_variance_jitter"},
                                      "policy.");
      !st.ok()) {
    return st;
  }
  TG_ASSIGN_OR_RETURN(const Json* centres, Required(*policy, "centres", "policy."));
  TG_ASSIGN_OR_RETURN(s.centres, ToMatrix(*centres, "policy.centres"));
  const int c = static_cast<int>(s.centres.rows());
  if (c == 0) return absl::InvalidArgumentError("policy.centres: no rows (C >= 1 centres)");
  if (absl::Status st = Shape(s.centres, c, ep, "policy.centres", "C x len(policy_inputs)");
      !st.ok()) {
    return st;
  }
  const Json* weights = Field(*policy, "weights");
  const Json* targets = Field(*policy, "targets");
  if ((weights == nullptr) == (targets == nullptr)) {
    return absl::InvalidArgumentError(
        "policy: give exactly one of 'weights' (ours) or 'targets' (PILCO's congp)");
  }
  s.has_targets = targets != nullptr;
  const std::string vname = s.has_targets ? "policy.targets" : "policy.weights";
  TG_ASSIGN_OR_RETURN(g.policy_values, VectorOrMatrix(s.has_targets ? *targets : *weights, vname,
                                                      &g.values_given_as_vector));
  if (g.values_given_as_vector) g.policy_values.transposeInPlace();  // C x 1
  if (g.policy_values.rows() != c || g.policy_values.cols() < 1) {
    return absl::InvalidArgumentError(absl::StrCat(
        vname, ": must be C x F (or a C-vector for F = 1) with C = ", c,
        " (the rows of policy.centres), is ", g.policy_values.rows(), " x ",
        g.policy_values.cols()));
  }
  const int f = static_cast<int>(g.policy_values.cols());
  TG_ASSIGN_OR_RETURN(const Json* ll, Required(*policy, "log_lengthscales", "policy."));
  TG_ASSIGN_OR_RETURN(g.log_lengthscales, VectorOrMatrix(*ll, "policy.log_lengthscales",
                                                         &g.lengthscales_given_as_vector));
  if (g.log_lengthscales.cols() != ep ||
      (g.lengthscales_given_as_vector ? false : g.log_lengthscales.rows() != f)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "policy.log_lengthscales: must be ", ep, " numbers (len(policy_inputs), shared) or ", f,
        " x ", ep, " (one row per control), is ", g.log_lengthscales.rows(), " x ",
        g.log_lengthscales.cols()));
  }
  TG_ASSIGN_OR_RETURN(g.max_force, MaxForce(*policy, f, absl::StrCat("the columns of ", vname)));
  if (const Json* j = Field(*policy, "output_variance_jitter"); j != nullptr) {
    TG_ASSIGN_OR_RETURN(s.output_variance_jitter, Number(*j, "policy.output_variance_jitter"));
    if (!(s.output_variance_jitter >= 0)) {
      return absl::InvalidArgumentError("policy.output_variance_jitter: must be >= 0");
    }
  }
  return f;
}

// train_inputs, inducing_inputs, gp_log_hyp and prediction_includes_noise:
// the dynamics GP on [z(dynamics_inputs), u], with N = n training points.
absl::Status ParseGeneralDynamics(const Json& doc, int n, int d, int eq, int f,
                                  PilcoScenario* out) {
  PilcoScenario& s = *out;
  GeneralPilcoScenario& g = s.general;
  TG_ASSIGN_OR_RETURN(const Json* xi, Required(doc, "train_inputs", ""));
  TG_ASSIGN_OR_RETURN(s.train_inputs, ToMatrix(*xi, "train_inputs"));
  if (absl::Status st = Shape(s.train_inputs, n, eq + f, "train_inputs",
                              "N = rows of train_targets, len(dynamics_inputs) + F: [z(dyni), u]");
      !st.ok()) {
    return st;
  }
  if (const Json* zi = Field(doc, "inducing_inputs"); zi != nullptr) {
    TG_ASSIGN_OR_RETURN(g.inducing_inputs, ToMatrix(*zi, "inducing_inputs"));
    if (g.inducing_inputs.rows() == 0) {
      return absl::InvalidArgumentError("inducing_inputs: no rows (M >= 1, or leave it out)");
    }
    if (absl::Status st = Shape(g.inducing_inputs, g.inducing_inputs.rows(), eq + f,
                                "inducing_inputs", "M x (len(dynamics_inputs) + F)");
        !st.ok()) {
      return st;
    }
  }
  TG_ASSIGN_OR_RETURN(const Json* hyp, Required(doc, "gp_log_hyp", ""));
  TG_ASSIGN_OR_RETURN(s.gp_log_hyp, ToMatrix(*hyp, "gp_log_hyp"));
  if (absl::Status st = Shape(s.gp_log_hyp, d, eq + f + 2, "gp_log_hyp",
                              "D x (len(dynamics_inputs) + F + 2): log l, log sf, log sn");
      !st.ok()) {
    return st;
  }
  if (const Json* noise = Field(doc, "prediction_includes_noise"); noise != nullptr) {
    if (!noise->is_boolean()) {
      return absl::InvalidArgumentError("prediction_includes_noise: not a boolean");
    }
    s.prediction_includes_noise = noise->get<bool>();
  }
  return absl::OkStatus();
}

// mu0, S0 and horizon: the start distribution and the prediction length.
absl::Status ParseGeneralStart(const Json& doc, int d, PilcoScenario* out) {
  PilcoScenario& s = *out;
  TG_ASSIGN_OR_RETURN(const Json* mu0, Required(doc, "mu0", ""));
  TG_ASSIGN_OR_RETURN(s.mu0, ToVector(*mu0, "mu0"));
  if (s.mu0.size() != d) {
    return absl::InvalidArgumentError(
        absl::StrCat("mu0: must have ", d, " entries (D, the columns of train_targets), has ",
                     s.mu0.size()));
  }
  TG_ASSIGN_OR_RETURN(const Json* s0, Required(doc, "S0", ""));
  TG_ASSIGN_OR_RETURN(RowMatrix s0m, ToMatrix(*s0, "S0"));
  if (absl::Status st = Shape(s0m, d, d, "S0", "D x D"); !st.ok()) return st;
  if (s0m != s0m.transpose()) return absl::InvalidArgumentError("S0: not symmetric");
  s.s0 = s0m;
  TG_ASSIGN_OR_RETURN(const Json* h, Required(doc, "horizon", ""));
  TG_ASSIGN_OR_RETURN(s.horizon, ToIndex(*h, "horizon"));
  if (s.horizon < 1) return absl::InvalidArgumentError("horizon: must be >= 1");
  return absl::OkStatus();
}

// cost.width: one or more widths, each > 0 (a plain number for one).
absl::StatusOr<std::vector<double>> Widths(const Json& w) {
  std::vector<double> widths;
  if (w.is_number()) {
    TG_ASSIGN_OR_RETURN(double one, Number(w, "cost.width"));
    widths = {one};
  } else {
    TG_ASSIGN_OR_RETURN(Vector ws, ToVector(w, "cost.width"));
    if (ws.size() == 0) return absl::InvalidArgumentError("cost.width: empty list");
    widths.assign(ws.data(), ws.data() + ws.size());
  }
  for (size_t k = 0; k < widths.size(); ++k) {
    if (!(widths[k] > 0)) {
      return absl::InvalidArgumentError(
          absl::StrCat("cost.width[", k, "]: must be > 0, is ", widths[k]));
    }
  }
  return widths;
}

// PILCO's loss_unicycle on the unicycle's GP state (D = 10, no angle through
// sin/cos): the wheel radius, rod length and widths of the cost, each
// optional (defaults: PILCO's 0.22, 0.81, [1]).
absl::Status ParseUnicycleCost(const Json& cost, int d, int a, PilcoScenario* out) {
  tasks::UnicycleCostParams& params = out->general.unicycle_cost;
  if (absl::Status st =
          OnlyKnownKeys(cost, {"type", "wheel_radius", "rod_length", "width"}, "cost.");
      !st.ok()) {
    return st;
  }
  if (d != tasks::kUnicycleCostStateDim || a != 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "cost.type \"unicycle\": the state must be the unicycle's GP state of ",
        tasks::kUnicycleCostStateDim,
        " entries [dtheta, dphi, dpsiw, dpsif, dpsit, xc, yc, theta, phi, psif] with no "
        "angle_indices; it has D = ", d, " and ", a, " angles"));
  }
  out->cost_type = "unicycle";
  for (const auto& [key, value] : {std::pair<const char*, double*>{"wheel_radius",
                                                                   &params.wheel_radius},
                                   {"rod_length", &params.rod_length}}) {
    if (const Json* v = Field(cost, key); v != nullptr) {
      TG_ASSIGN_OR_RETURN(*value, Number(*v, absl::StrCat("cost.", key)));
      if (!(*value > 0)) {
        return absl::InvalidArgumentError(absl::StrCat("cost.", key, ": must be > 0, is ", *value));
      }
    }
  }
  if (const Json* w = Field(cost, "width"); w != nullptr) {
    TG_ASSIGN_OR_RETURN(params.widths, Widths(*w));
  }
  return absl::OkStatus();
}

// cost: PILCO's saturating cost on z (nz = D + 2A entries), with one or more
// widths, or the unicycle's.
absl::Status ParseGeneralCost(const Json& doc, int d, int nz, PilcoScenario* out) {
  PilcoScenario& s = *out;
  GeneralPilcoScenario& g = s.general;
  TG_ASSIGN_OR_RETURN(const Json* cost, Required(doc, "cost", ""));
  if (!cost->is_object()) return absl::InvalidArgumentError("cost: not an object");
  TG_ASSIGN_OR_RETURN(const Json* type, Required(*cost, "type", "cost."));
  if (type->is_string() && type->get<std::string>() == "unicycle") {
    return ParseUnicycleCost(*cost, d, (nz - d) / 2, out);
  }
  if (!type->is_string() || type->get<std::string>() != "saturating") {
    return absl::InvalidArgumentError(
        "cost.type: the general form takes \"saturating\" (PILCO's lossSat on z) or "
        "\"unicycle\" (loss_unicycle)");
  }
  if (absl::Status st = OnlyKnownKeys(*cost, {"type", "target", "Q", "width"}, "cost.");
      !st.ok()) {
    return st;
  }
  s.cost_type = "saturating";
  TG_ASSIGN_OR_RETURN(const Json* t, Required(*cost, "target", "cost."));
  TG_ASSIGN_OR_RETURN(g.cost_target, ToVector(*t, "cost.target"));
  if (g.cost_target.size() != d) {
    return absl::InvalidArgumentError(absl::StrCat("cost.target: must have ", d,
                                                   " entries (a state), has ",
                                                   g.cost_target.size()));
  }
  TG_ASSIGN_OR_RETURN(const Json* q, Required(*cost, "Q", "cost."));
  TG_ASSIGN_OR_RETURN(RowMatrix qm, ToMatrix(*q, "cost.Q"));
  if (absl::Status st = Shape(qm, nz, nz, "cost.Q", "(D + 2A) x (D + 2A), on z"); !st.ok()) {
    return st;
  }
  // Symmetric up to rounding in the file's decimal digits (relative 1e-12);
  // the PSD check is GaussianCost's (it names cost Q).
  if ((qm - qm.transpose()).cwiseAbs().maxCoeff() > 1e-12 * (1.0 + qm.cwiseAbs().maxCoeff())) {
    return absl::InvalidArgumentError("cost.Q: not symmetric");
  }
  g.cost_q = qm;
  TG_ASSIGN_OR_RETURN(const Json* w, Required(*cost, "width", "cost."));
  TG_ASSIGN_OR_RETURN(g.widths, Widths(*w));
  return absl::OkStatus();
}

absl::Status ParseGeneral(const Json& doc, PilcoScenario* out) {
  PilcoScenario& s = *out;
  GeneralPilcoScenario& g = s.general;
  s.is_general = true;
  if (Field(doc, "angle_index") != nullptr) {
    return absl::InvalidArgumentError(
        "angle_index: give angle_indices (general form) or angle_index, not both");
  }
  if (absl::Status st = OnlyKnownKeys(
          doc,
          {"angle_indices", "dynamics_inputs", "policy_inputs", "train_inputs", "train_targets",
           "inducing_inputs", "gp_log_hyp", "prediction_includes_noise", "policy", "mu0", "S0",
           "horizon", "cost"},
          "");
      !st.ok()) {
    return st;
  }
  // D from the targets: every other shape follows from D, A, F.
  TG_ASSIGN_OR_RETURN(const Json* yi, Required(doc, "train_targets", ""));
  TG_ASSIGN_OR_RETURN(s.train_targets, ToMatrix(*yi, "train_targets"));
  const int n = static_cast<int>(s.train_targets.rows());
  const int d = static_cast<int>(s.train_targets.cols());
  if (n == 0 || d == 0) return absl::InvalidArgumentError("train_targets: no rows or no columns");
  TG_ASSIGN_OR_RETURN(const Json* ai, Required(doc, "angle_indices", ""));
  TG_ASSIGN_OR_RETURN(g.angle_indices,
                      IndexList(*ai, "angle_indices", d, "state indices", /*allow_empty=*/true));
  const int nz = d + 2 * static_cast<int>(g.angle_indices.size());
  const std::string z_name = "indices into z = [x, (sin, cos) per angle]";
  TG_ASSIGN_OR_RETURN(const Json* di, Required(doc, "dynamics_inputs", ""));
  TG_ASSIGN_OR_RETURN(g.dynamics_inputs, IndexList(*di, "dynamics_inputs", nz, z_name, false));
  TG_ASSIGN_OR_RETURN(const Json* pi, Required(doc, "policy_inputs", ""));
  TG_ASSIGN_OR_RETURN(g.policy_inputs, IndexList(*pi, "policy_inputs", nz, z_name, false));
  const int eq = static_cast<int>(g.dynamics_inputs.size());
  const int ep = static_cast<int>(g.policy_inputs.size());
  TG_ASSIGN_OR_RETURN(const int f, ParseGeneralPolicy(doc, ep, &s));
  if (absl::Status st = ParseGeneralDynamics(doc, n, d, eq, f, &s); !st.ok()) return st;
  if (absl::Status st = ParseGeneralStart(doc, d, &s); !st.ok()) return st;
  return ParseGeneralCost(doc, d, nz, &s);
}

}  // namespace

absl::StatusOr<PilcoScenario> ParsePilcoScenario(const nlohmann::json& doc) {
  if (!doc.is_object()) return absl::InvalidArgumentError("scenario: not a JSON object");
  PilcoScenario s;
  if (Field(doc, "angle_indices") != nullptr) {
    if (absl::Status st = ParseGeneral(doc, &s); !st.ok()) return st;
    return s;
  }
  TG_ASSIGN_OR_RETURN(const Json* angle, Required(doc, "angle_index", ""));
  if (angle->is_null()) {
    s.angle_index = -1;
  } else {
    TG_ASSIGN_OR_RETURN(s.angle_index, ToIndex(*angle, "angle_index"));
    if (s.angle_index < 0) return absl::InvalidArgumentError("angle_index: must be >= 0 or null");
  }
  TG_ASSIGN_OR_RETURN(const Json* xi, Required(doc, "train_inputs", ""));
  TG_ASSIGN_OR_RETURN(s.train_inputs, ToMatrix(*xi, "train_inputs"));
  TG_ASSIGN_OR_RETURN(const Json* yi, Required(doc, "train_targets", ""));
  TG_ASSIGN_OR_RETURN(s.train_targets, ToMatrix(*yi, "train_targets"));
  TG_ASSIGN_OR_RETURN(const Json* hyp, Required(doc, "gp_log_hyp", ""));
  TG_ASSIGN_OR_RETURN(s.gp_log_hyp, ToMatrix(*hyp, "gp_log_hyp"));
  if (const Json* noise = Field(doc, "prediction_includes_noise"); noise != nullptr) {
    if (!noise->is_boolean()) {
      return absl::InvalidArgumentError("prediction_includes_noise: not a boolean");
    }
    s.prediction_includes_noise = noise->get<bool>();
  }

  TG_ASSIGN_OR_RETURN(const Json* policy, Required(doc, "policy", ""));
  if (!policy->is_object()) return absl::InvalidArgumentError("policy: not an object");
  TG_ASSIGN_OR_RETURN(const Json* centres, Required(*policy, "centres", "policy."));
  TG_ASSIGN_OR_RETURN(s.centres, ToMatrix(*centres, "policy.centres"));
  const Json* weights = Field(*policy, "weights");
  const Json* targets = Field(*policy, "targets");
  if ((weights == nullptr) == (targets == nullptr)) {
    return absl::InvalidArgumentError(
        "policy: give exactly one of 'weights' (ours) or 'targets' (PILCO's congp)");
  }
  if (weights != nullptr) {
    TG_ASSIGN_OR_RETURN(s.weights, ToVector(*weights, "policy.weights"));
  } else {
    TG_ASSIGN_OR_RETURN(s.targets, ToVector(*targets, "policy.targets"));
    s.has_targets = true;
  }
  TG_ASSIGN_OR_RETURN(const Json* ll, Required(*policy, "log_lengthscales", "policy."));
  TG_ASSIGN_OR_RETURN(s.log_lengthscales, ToVector(*ll, "policy.log_lengthscales"));
  TG_ASSIGN_OR_RETURN(const Json* mf, Required(*policy, "max_force", "policy."));
  TG_ASSIGN_OR_RETURN(s.max_force, Number(*mf, "policy.max_force"));
  if (const Json* j = Field(*policy, "output_variance_jitter"); j != nullptr) {
    TG_ASSIGN_OR_RETURN(s.output_variance_jitter, Number(*j, "policy.output_variance_jitter"));
  }

  TG_ASSIGN_OR_RETURN(const Json* mu0, Required(doc, "mu0", ""));
  TG_ASSIGN_OR_RETURN(s.mu0, ToVector(*mu0, "mu0"));
  TG_ASSIGN_OR_RETURN(const Json* s0, Required(doc, "S0", ""));
  TG_ASSIGN_OR_RETURN(RowMatrix s0m, ToMatrix(*s0, "S0"));
  s.s0 = s0m;
  TG_ASSIGN_OR_RETURN(const Json* h, Required(doc, "horizon", ""));
  TG_ASSIGN_OR_RETURN(s.horizon, ToIndex(*h, "horizon"));
  if (s.horizon < 1) return absl::InvalidArgumentError("horizon: must be >= 1");

  TG_ASSIGN_OR_RETURN(const Json* cost, Required(doc, "cost", ""));
  if (!cost->is_object()) return absl::InvalidArgumentError("cost: not an object");
  TG_ASSIGN_OR_RETURN(const Json* type, Required(*cost, "type", "cost."));
  if (!type->is_string()) return absl::InvalidArgumentError("cost.type: not a string");
  s.cost_type = type->get<std::string>();
  if (s.cost_type == "tip") {
    TG_ASSIGN_OR_RETURN(const Json* pi, Required(*cost, "position_index", "cost."));
    TG_ASSIGN_OR_RETURN(s.cost_position_index, ToIndex(*pi, "cost.position_index"));
    TG_ASSIGN_OR_RETURN(const Json* ai, Required(*cost, "angle_index", "cost."));
    TG_ASSIGN_OR_RETURN(s.cost_angle_index, ToIndex(*ai, "cost.angle_index"));
    TG_ASSIGN_OR_RETURN(const Json* pl, Required(*cost, "pendulum_length", "cost."));
    TG_ASSIGN_OR_RETURN(s.pendulum_length, Number(*pl, "cost.pendulum_length"));
    TG_ASSIGN_OR_RETURN(const Json* w, Required(*cost, "width", "cost."));
    TG_ASSIGN_OR_RETURN(s.width, Number(*w, "cost.width"));
    if (const Json* tp = Field(*cost, "target_position"); tp != nullptr) {
      TG_ASSIGN_OR_RETURN(s.target_position, Number(*tp, "cost.target_position"));
    }
  } else if (s.cost_type == "angle") {
    TG_ASSIGN_OR_RETURN(const Json* t, Required(*cost, "target", "cost."));
    TG_ASSIGN_OR_RETURN(s.cost_target, ToVector(*t, "cost.target"));
    TG_ASSIGN_OR_RETURN(const Json* q, Required(*cost, "Q", "cost."));
    if (q->is_array() && !q->empty() && q->front().is_array()) {
      TG_ASSIGN_OR_RETURN(RowMatrix qm, ToMatrix(*q, "cost.Q"));
      s.cost_q = qm;
    } else {
      TG_ASSIGN_OR_RETURN(Vector qd, ToVector(*q, "cost.Q"));
      s.cost_q = qd.asDiagonal();
    }
  } else {
    return absl::InvalidArgumentError(
        absl::StrCat("cost.type: unknown '", s.cost_type, "' (tip or angle)"));
  }
  return s;
}

#undef TG_ASSIGN_OR_RETURN
#undef TG_ASSIGN_OR_RETURN_IMPL
#undef TG_CONCAT
#undef TG_CONCAT_INNER

}  // namespace totalgrad::cli
