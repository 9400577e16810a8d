// Particle gradient estimators of dJ/dtheta, J the expected episode cost of
// the policy under the learned model (paper sections 2-5).
//
// An estimator runs the forward pass it needs (estimators/rollout.h) and a
// backward pass that sends per-node messages. Every estimate comes with the
// per-particle gradients' sample variance, which the paper's optimiser uses to
// normalise its step.
//
// Thread safety: an Estimator may keep scratch space; use one per thread.
#ifndef TOTALGRAD_CORE_ESTIMATORS_ESTIMATOR_H_
#define TOTALGRAD_CORE_ESTIMATORS_ESTIMATOR_H_

#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "core/common/rng.h"
#include "core/estimators/rollout.h"

namespace totalgrad::estimators {

struct GradientEstimate {
  double objective = 0;            // J estimated by the forward pass
  Vector gradient;                 // n, estimate of dJ/dtheta
  // Per-particle gradients g^(i) (their mean is `gradient`): P x n. Filled
  // only when the caller asks for them (EstimateOptions).
  RowMatrix per_particle;
  Vector per_particle_variance;    // n, sample variance of g^(i) over particles
  bool finite = true;              // false: some value was non-finite; do not use
};

struct EstimateOptions {
  int particles = 300;
  bool keep_per_particle = false;  // keep the P x n matrix in the estimate
};

class Estimator {
 public:
  virtual ~Estimator() = default;
  virtual std::string Name() const = 0;
  // One estimate for `problem` with fresh random numbers from *rng.
  // Errors: InvalidArgument for an inconsistent problem.
  virtual absl::Status Estimate(const Problem& problem, const EstimateOptions& options, Rng* rng,
                                GradientEstimate* estimate) = 0;
};

// Options shared by the estimator family (method-specific knobs live here so
// one key=value space configures every method).
struct EstimatorOptions {};

// The particle methods available by name ("RP", ...). PILCO is not a
// particle method and is handled by the learner.
std::vector<std::string> ParticleMethods();

// InvalidArgument naming an unknown method.
absl::StatusOr<std::unique_ptr<Estimator>> MakeEstimator(const std::string& name,
                                                         const EstimatorOptions& options);

// Sample variance over rows of a P x n matrix (0 when P == 1).
Vector ColumnSampleVariance(const RowMatrix& per_particle);

}  // namespace totalgrad::estimators

#endif  // TOTALGRAD_CORE_ESTIMATORS_ESTIMATOR_H_
