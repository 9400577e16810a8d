// RP: the reparameterisation (pathwise) gradient, backpropagation through
// time with every random number held fixed (pipps-spec.md 5.1). Given fixed
// random numbers the estimate is a deterministic function of the policy
// parameters, so finite differences can check it.
#ifndef TOTALGRAD_CORE_ESTIMATORS_RP_H_
#define TOTALGRAD_CORE_ESTIMATORS_RP_H_

#include "core/estimators/estimator.h"

namespace totalgrad::estimators {

// Reverse-mode pass over a rollout recorded with jacobians. Writes the
// gradient and, when per_particle is non-null, the P x n matrix of per-particle
// contributions (each row already carries the 1/P of the mean; rows sum to
// the gradient). Either output may be null.
void RpBackward(const Problem& problem, const Rollout& rollout, Vector* gradient,
                RowMatrix* per_particle);

class RpEstimator final : public Estimator {
 public:
  std::string Name() const override { return "RP"; }
  absl::Status Estimate(const Problem& problem, const EstimateOptions& options, Rng* rng,
                        GradientEstimate* estimate) override;

 private:
  Rollout rollout_;  // reused between calls to avoid reallocations
};

}  // namespace totalgrad::estimators

#endif  // TOTALGRAD_CORE_ESTIMATORS_RP_H_
