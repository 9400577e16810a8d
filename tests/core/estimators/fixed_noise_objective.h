// The particle objective as a deterministic function of the policy
// parameters, for finite-difference checks of the RP gradient: shared by the
// tests of the full-GP and the FITC rollouts.
#ifndef TOTALGRAD_TESTS_CORE_ESTIMATORS_FIXED_NOISE_OBJECTIVE_H_
#define TOTALGRAD_TESTS_CORE_ESTIMATORS_FIXED_NOISE_OBJECTIVE_H_

#include <gtest/gtest.h>

#include "core/common/rng.h"
#include "core/common/types.h"
#include "core/estimators/rollout.h"
#include "core/policy/rbf_policy.h"

namespace totalgrad::estimators::testing {

// J(theta) of `base` with its policy's parameters replaced by theta and the
// random numbers of seed `noise_seed` held fixed (P = particles).
inline double FixedNoiseObjective(const Problem& base, const Vector& theta, uint64_t noise_seed,
                                  int particles) {
  policy::RbfPolicy policy = *base.policy;
  policy.set_parameters(theta);
  Problem problem = base;
  problem.policy = &policy;
  Rng rng(noise_seed, Stream::kParticleNoise);
  Rollout rollout;
  EXPECT_TRUE(SimulateParticles(problem, particles, {}, &rng, &rollout).ok());
  return rollout.objective;
}

}  // namespace totalgrad::estimators::testing

#endif  // TOTALGRAD_TESTS_CORE_ESTIMATORS_FIXED_NOISE_OBJECTIVE_H_
