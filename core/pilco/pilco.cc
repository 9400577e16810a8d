#include "core/pilco/pilco.h"

#include <chrono>
#include <cmath>
#include <utility>

#include <Eigen/Eigenvalues>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "core/pilco/policy_moments.h"
#include "core/policy/linear_policy.h"
#include "core/gaussian/trig.h"

namespace totalgrad::pilco {

absl::Status PilcoProblem::Validate(const GaussianInputGp* model) const {
  const int d = static_cast<int>(mu0.size());
  if (d < 1) return absl::InvalidArgumentError("mu0 is empty");
  if (S0.rows() != d || S0.cols() != d) {
    return absl::InvalidArgumentError(absl::StrCat("S0 must be ", d, " x ", d));
  }
  if (!mu0.allFinite() || !S0.allFinite()) {
    return absl::InvalidArgumentError("mu0 or S0 not finite");
  }
  if (horizon < 1) return absl::InvalidArgumentError("horizon must be >= 1");
  if (cost == nullptr) return absl::InvalidArgumentError("cost is null");
  if (cost->state_dim() != d) {
    return absl::InvalidArgumentError(
        absl::StrCat("cost is for state dim ", cost->state_dim(), ", mu0 has ", d));
  }
  if (model != nullptr) {
    if (model->num_outputs() != d) {
      return absl::InvalidArgumentError(absl::StrCat("dynamics GP has ", model->num_outputs(),
                                                     " outputs, state dim is ", d));
    }
    return Propagator::Validate(*model, propagation);
  }
  return absl::OkStatus();
}

std::string PilcoResult::BriefReport() const {
  return absl::StrFormat("%s; predicted J %.6g; %.3f s", optimizer.BriefReport(),
                         prediction.total_cost, seconds);
}

absl::StatusOr<Trajectory> Propagate(const GaussianInputGp& model, const PilcoProblem& problem,
                                     const Vector& params, Vector* gradient) {
  if (absl::Status st = problem.Validate(&model); !st.ok()) return st;
  const Propagator prop(&model, problem.propagation);
  Trajectory tr;
  if (absl::Status st = PredictTrajectory(prop, *problem.cost, params, problem.mu0, problem.S0,
                                          problem.horizon, &tr, gradient);
      !st.ok()) {
    return st;
  }
  return tr;
}

namespace {

// The end of an optimisation whose answer is the policy parameters x: the
// prediction at x into result->prediction, x into *params, the time since
// `start` into result->seconds.
absl::Status FinishAt(const Propagator& prop, const PilcoProblem& problem,
                      std::chrono::steady_clock::time_point start, Vector x, PilcoResult* result,
                      Vector* params) {
  if (absl::Status st = PredictTrajectory(prop, *problem.cost, x, problem.mu0, problem.S0,
                                          problem.horizon, &result->prediction, nullptr);
      !st.ok()) {
    return st;
  }
  *params = std::move(x);
  result->seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return absl::OkStatus();
}

// The linear policy's parameters [W, b] are well scaled as they are (no
// pseudo-targets): BFGS on J(W, b) directly, as PILCO's learnPolicy on
// conlin's policy.p.
absl::StatusOr<PilcoResult> OptimizeLinearPolicy(
    const Propagator& prop, const PilcoProblem& problem, const PilcoOptions& options,
    std::chrono::steady_clock::time_point start, Vector* params) {
  const Objective objective = [&](const Vector& theta, double* f, Vector* g) {
    Trajectory tr;
    if (!PredictTrajectory(prop, *problem.cost, theta, problem.mu0, problem.S0, problem.horizon,
                           &tr, g)
             .ok()) {
      return false;
    }
    *f = tr.total_cost;
    return true;
  };
  PilcoResult result;
  Vector theta = *params;
  result.optimizer = MinimizeBfgs(objective, options.bfgs, &theta);
  if (result.optimizer.termination == BfgsSummary::Termination::kInitialEvaluationFailed) {
    return absl::InternalError("PILCO: the initial policy could not be evaluated");
  }
  if (absl::Status st = FinishAt(prop, problem, start, std::move(theta), &result, params);
      !st.ok()) {
    return st;
  }
  return result;
}

}  // namespace

absl::StatusOr<PilcoResult> OptimizePolicy(const GaussianInputGp& model,
                                           const PilcoProblem& problem,
                                           const PilcoOptions& options, Vector* params) {
  if (absl::Status st = problem.Validate(&model); !st.ok()) return st;
  const Propagator prop(&model, problem.propagation);
  if (params->size() != prop.num_parameters()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "policy has ", params->size(), " parameters, expected ", prop.num_parameters()));
  }
  const auto start = std::chrono::steady_clock::now();
  // Check the start point explicitly so that its error is reported.
  {
    Trajectory tr;
    if (absl::Status st = PredictTrajectory(prop, *problem.cost, *params, problem.mu0,
                                            problem.S0, problem.horizon, &tr, nullptr);
        !st.ok()) {
      return absl::Status(st.code(), absl::StrCat("at the initial policy: ", st.message()));
    }
  }
  // As PILCO's learnPolicy (minimize over policy.p), the optimiser moves the
  // pseudo-inputs (centres), the log length-scales and the pseudo-targets y;
  // the weights w = (K_cc + 1e-4 I)^-1 y follow. Optimising the weights
  // directly is badly scaled: centres drawn from a narrow start
  // distribution make K_cc nearly singular, the weights run to thousands,
  // and one step of the centres then sends the policy's output variance so
  // high that the saturation's moments underflow to an exactly zero
  // gradient (the pendulum stopped after one line search).
  if (problem.propagation.policy_class == PolicyClass::kLinear) {
    return OptimizeLinearPolicy(prop, problem, options, start, params);
  }
  const RbfPolicyShape& shape = prop.policy_shape();
  Vector y;
  if (absl::Status st = WeightsToPseudoTargets(shape, *params, &y); !st.ok()) return st;
  const Objective objective = [&](const Vector& pilco_params, double* f, Vector* g) {
    Vector weights;
    if (!PseudoTargetsToWeights(shape, pilco_params, &weights).ok()) return false;
    Trajectory tr;
    Vector weights_gradient;
    if (!PredictTrajectory(prop, *problem.cost, weights, problem.mu0, problem.S0,
                           problem.horizon, &tr, g != nullptr ? &weights_gradient : nullptr)
             .ok()) {
      return false;
    }
    if (g != nullptr &&
        !PseudoTargetsBackward(shape, pilco_params, weights_gradient, g).ok()) {
      return false;
    }
    *f = tr.total_cost;
    return true;
  };
  PilcoResult result;
  result.optimizer = MinimizeBfgs(objective, options.bfgs, &y);
  if (result.optimizer.termination == BfgsSummary::Termination::kInitialEvaluationFailed) {
    return absl::InternalError("PILCO: the initial policy could not be evaluated");
  }
  Vector x;
  if (absl::Status st = PseudoTargetsToWeights(shape, y, &x); !st.ok()) return st;
  if (absl::Status st = FinishAt(prop, problem, start, std::move(x), &result, params); !st.ok()) {
    return st;
  }
  return result;
}

std::string DynamicsModelReport::BriefReport() const {
  return sparse ? fitc.BriefReport() : std::string("full GP");
}

absl::StatusOr<GaussianInputGp> BuildDynamicsModel(const RowMatrix& inputs,
                                                   const RowMatrix& targets,
                                                   const gp::GpHyperparameters& hyperparameters,
                                                   const DynamicsModelOptions& options,
                                                   RowMatrix* inducing, Rng* rng,
                                                   DynamicsModelReport* report) {
  DynamicsModelReport local;
  DynamicsModelReport& rep = report != nullptr ? *report : local;
  const int n = static_cast<int>(inputs.rows());
  if (options.num_inducing <= 0 || n <= options.num_inducing) {
    rep.sparse = false;
    absl::StatusOr<gp::GpModel> model = gp::GpModel::Create(inputs, targets, hyperparameters);
    if (!model.ok()) return model.status();
    return GaussianInputGpFromModel(*model);
  }
  rep.sparse = true;
  gp::FitcFitOptions fit;
  fit.num_inducing = options.num_inducing;
  fit.first_fit_iterations = options.first_fit_iterations;
  fit.warm_fit_iterations = options.warm_fit_iterations;
  absl::StatusOr<gp::FitcModel> model =
      gp::FitFitcModel(inputs, targets, hyperparameters, fit, inducing, rng, &rep.fitc);
  if (!model.ok()) return model.status();
  return GaussianInputGpFromFitc(*model);
}

absl::StatusOr<Vector> InitialPolicyParameters(const PilcoProblem& problem, Rng* rng) {
  if (absl::Status st = problem.Validate(); !st.ok()) return st;
  const int d = static_cast<int>(problem.mu0.size());
  const std::vector<int> angles = problem.propagation.Angles();
  for (size_t k = 0; k < angles.size(); ++k) {
    if (angles[k] < 0 || angles[k] >= d || (k > 0 && angles[k] <= angles[k - 1]))
      return absl::InvalidArgumentError("angle indices out of range or not increasing");
  }
  if (problem.propagation.policy_class == PolicyClass::kLinear) {
    // PILCO's conlin start: W ~ 1e-2 N(0, 1) column by column, b = 0, on the
    // policy inputs (the non-angle dims, then (sin, cos) per angle).
    const int f = problem.propagation.max_controls.size() >= 2
                      ? static_cast<int>(problem.propagation.max_controls.size())
                      : 1;
    const int ep = problem.propagation.policy_inputs.empty()
                       ? d + static_cast<int>(angles.size())
                       : static_cast<int>(problem.propagation.policy_inputs.size());
    policy::LinearPolicy linear(ep, f >= 2 ? problem.propagation.max_controls
                                           : Vector::Constant(1, problem.propagation.max_force));
    linear.Initialize(policy::kLinearPolicyInitStd, rng);
    return linear.parameters();
  }
  const int c = problem.propagation.num_basis;
  if (c < 1) return absl::InvalidArgumentError("num_basis must be >= 1");
  Vector y_mean;
  Matrix y_cov;
  // The policy's inputs in y: the non-angle dims, then (sin, cos) per angle
  // (as Propagator's).
  std::vector<int> index;
  if (!angles.empty()) {
    gaussian::AugmentWithTrig(problem.mu0, problem.S0, angles, &y_mean, &y_cov);
    size_t next = 0;
    for (int i = 0; i < d; ++i) {
      if (next < angles.size() && angles[next] == i) ++next;
      else index.push_back(i);
    }
    for (int k = 0; k < 2 * static_cast<int>(angles.size()); ++k) index.push_back(d + k);
  } else {
    y_mean = problem.mu0;
    y_cov = problem.S0;
    for (int i = 0; i < d; ++i) index.push_back(i);
  }
  const int ep = static_cast<int>(index.size());
  Vector pm(ep);
  Matrix ps(ep, ep);
  for (int i = 0; i < ep; ++i) {
    pm(i) = y_mean(index[i]);
    for (int j = 0; j < ep; ++j) ps(i, j) = y_cov(index[i], index[j]);
  }
  Eigen::SelfAdjointEigenSolver<Matrix> eig(ps);
  const Matrix l = eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal();
  RbfPolicyShape shape;
  shape.num_basis = c;
  shape.input_dim = ep;
  shape.max_controls = problem.propagation.max_controls;  // F >= 2: C x F pseudo-targets
  Vector pilco(shape.num_parameters());
  for (int k = 0; k < c; ++k) {
    Vector z(ep);
    for (int i = 0; i < ep; ++i) z(i) = rng->Normal();
    pilco.segment(k * ep, ep) = pm + l * z;
  }
  pilco.segment(c * ep, ep).setZero();
  // The (sin, cos) inputs' length-scales start at 0.7 (log), the others at 1.
  if (!angles.empty()) {
    const int trig = 2 * static_cast<int>(angles.size());
    pilco.segment(c * ep + ep - trig, trig).setConstant(std::log(0.7));
  }
  // Pseudo-targets ~ N(0, 0.1^2), row by row (C x F; one control: C).
  for (int k = 0; k < c * shape.num_controls(); ++k) pilco(c * ep + ep + k) = 0.1 * rng->Normal();
  Vector params;
  if (absl::Status st = PseudoTargetsToWeights(shape, pilco, &params); !st.ok()) return st;
  return params;
}

}  // namespace totalgrad::pilco
