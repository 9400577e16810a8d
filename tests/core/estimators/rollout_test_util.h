// Helpers shared by the rollout tests of the full-GP, FITC and sin/cos
// feature models: a small synthetic cart-pole problem, and the particle
// objective as a deterministic function of the policy parameters (for
// finite-difference checks of the RP gradient).
#ifndef TOTALGRAD_TESTS_CORE_ESTIMATORS_ROLLOUT_TEST_UTIL_H_
#define TOTALGRAD_TESTS_CORE_ESTIMATORS_ROLLOUT_TEST_UTIL_H_

#include <gtest/gtest.h>

#include "core/common/rng.h"
#include <memory>
#include <string>

#include "core/common/types.h"
#include "core/estimators/rollout.h"
#include "core/estimators/synthetic_problem.h"
#include "core/policy/rbf_policy.h"

namespace totalgrad::estimators::testing {

// The synthetic cart-pole problem at test size: GP on 40 transitions, H = 8,
// 10 RBF basis functions, seed 3, the given cost ("angle" or "tip").
inline std::unique_ptr<SyntheticProblem> SmallSyntheticProblem(const std::string& cost) {
  SyntheticProblemOptions o;
  o.data = 40;
  o.horizon = 8;
  o.basis_functions = 10;
  o.cost = cost;
  o.seed = 3;
  auto p = MakeSyntheticProblem(o);
  EXPECT_TRUE(p.ok()) << p.status();
  return p.ok() ? *std::move(p) : nullptr;
}

// J(theta) of `base` with its policy replaced by `rbf` at parameters theta
// and the random numbers of seed `noise_seed` held fixed (P = particles).
inline double FixedNoiseObjective(const Problem& base, const policy::RbfPolicy& rbf,
                                  const Vector& theta, uint64_t noise_seed, int particles) {
  policy::RbfPolicy policy = rbf;
  policy.set_parameters(theta);
  const RbfParticlePolicy adapter(&policy);
  Problem problem = base;
  problem.policy = &adapter;
  Rng rng(noise_seed, Stream::kParticleNoise);
  Rollout rollout;
  EXPECT_TRUE(SimulateParticles(problem, particles, {}, &rng, &rollout).ok());
  return rollout.objective;
}

}  // namespace totalgrad::estimators::testing

#endif  // TOTALGRAD_TESTS_CORE_ESTIMATORS_ROLLOUT_TEST_UTIL_H_
