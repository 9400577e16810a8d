// PILCO policy search: the entry points for a trial (`--method PILCO`).
//
//   Propagate:       predicted state distributions, expected costs, J and
//                    (optionally) dJ/dtheta for given policy parameters.
//   OptimizePolicy:  PILCO's learnPolicy: BFGS with line searches
//                    (pilco-spec.md 6.3) on J(theta), warm-started from the
//                    given parameters.
//   InitialPolicyParameters: PILCO's initial policy (pilco-spec.md 2).
//
// Policy parameters use the RbfPolicy layout [centres row-major (C x Ep),
// log length-scales (Ep), weights (C)] over the policy features of
// angle_features.h (Ep = D + 1 with an angle index, else D); a real state x
// is controlled with force = policy::Saturate(a(StateFeatures(x, a_idx))),
// i.e. policy::RbfPolicy(C, Ep, max_force) with the same parameters
// evaluated on the features.
//
// The dynamics model is a GaussianInputGp: GaussianInputGpFromModel(GpModel)
// for a full GP, or gp::FitcModel's conversion (fitc.h) for a sparse one.
//
// Thread safety: free functions; the model and problem are read only.
#ifndef TOTALGRAD_CORE_PILCO_PILCO_H_
#define TOTALGRAD_CORE_PILCO_PILCO_H_

#include <memory>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/common/rng.h"
#include "core/common/types.h"
#include "core/gp/fitc.h"
#include "core/gp/gp.h"
#include "core/pilco/bfgs.h"
#include "core/gaussian/expected_cost.h"
#include "core/pilco/gp_moments.h"
#include "core/pilco/propagation.h"

namespace totalgrad::pilco {

struct PilcoProblem {
  Vector mu0;                                // D, start mean
  Matrix S0;                                 // D x D, start covariance
  int horizon = 30;                          // H (PILCO's cart-pole: 40)
  std::shared_ptr<const gaussian::GaussianCost> cost;  // must be non-null
  // angle_index, prediction_includes_noise (false), policy_jitter (1e-6),
  // max_force (10), num_basis (C).
  PropagationOptions propagation;

  // InvalidArgument naming the first bad field (also checks consistency
  // with `model` when given).
  absl::Status Validate(const GaussianInputGp* model = nullptr) const;
};

struct PilcoOptions {
  BfgsOptions bfgs;  // 150 line searches x 30 evaluations, as PILCO
};

struct PilcoResult {
  BfgsSummary optimizer;
  Trajectory prediction;        // at the returned parameters (means, covs, cost mean/std)
  double seconds = 0;           // wall time of the optimisation
  std::string BriefReport() const;
};

// Prediction (and dJ/dtheta into *gradient when non-null) for `params`.
// Errors: InvalidArgument (problem/params inconsistent with the model),
// FailedPrecondition / Internal from the moment matching (step and block
// named).
absl::StatusOr<Trajectory> Propagate(const GaussianInputGp& model, const PilcoProblem& problem,
                                     const Vector& params, Vector* gradient = nullptr);

// Minimises J from *params (warm start) and writes the best parameters
// found back. Evaluations that fail numerically are rejected by the line
// search (counted in optimizer.failed_evaluations); only a failure at the
// start point is an error (then *params is unchanged).
absl::StatusOr<PilcoResult> OptimizePolicy(const GaussianInputGp& model,
                                           const PilcoProblem& problem,
                                           const PilcoOptions& options, Vector* params);

// The dynamics model PILCO uses for a data set (pilco-spec.md 4.5): the full
// GP while N <= num_inducing (or num_inducing == 0), else FITC with
// num_inducing shared inducing inputs trained with the hyperparameters fixed.
struct DynamicsModelOptions {
  int num_inducing = 300;            // PILCO: 300; 0 = always the full GP
  int first_fit_iterations = 1500;   // Z from a random subset of the inputs
  int warm_fit_iterations = 500;     // Z warm-started from *inducing
};

struct DynamicsModelReport {
  bool sparse = false;
  gp::FitcTrainingSummary fitc;  // when sparse
  std::string BriefReport() const;
};

// inputs N x (Ep + 1) in feature space (StatesToFeatures + u), targets N x D,
// hyperparameters trained on the full data (gp::TrainHyperparameters).
// *inducing is the warm start (empty the first time) and receives the
// trained inducing inputs; `rng` draws the first random subset. Errors from
// GpModel::Create / FitcModel::Create / TrainInducingInputs.
absl::StatusOr<GaussianInputGp> BuildDynamicsModel(const RowMatrix& inputs,
                                                   const RowMatrix& targets,
                                                   const gp::GpHyperparameters& hyperparameters,
                                                   const DynamicsModelOptions& options,
                                                   RowMatrix* inducing, Rng* rng,
                                                   DynamicsModelReport* report);

// PILCO's initial policy: C centres drawn from the (moment-matched) Gaussian
// of the policy features at time 0, log length-scales 0 for the raw dims and
// log 0.7 for sin and cos, pseudo-targets 0.1 N(0, 1) converted to weights
// (weights = (K_cc + 1e-4 I)^-1 targets). Draws from *rng in that order.
absl::StatusOr<Vector> InitialPolicyParameters(const PilcoProblem& problem, Rng* rng);

}  // namespace totalgrad::pilco

#endif  // TOTALGRAD_CORE_PILCO_PILCO_H_
