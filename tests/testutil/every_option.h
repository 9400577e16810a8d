// A TrialOptions value with every field of every module's option table set to
// a valid value other than its default, for the round-trip tests of the
// options through option pairs, checkpoints, trial snapshots
// (tests/core/learner/trial_options_test.cc, tests/io/snapshot_json_test.cc)
// and sweep files (tests/service/trial_options_sweep_test.cc). The tests
// check that no key of TrialOptions::Table() is left at its default here, so
// a field added to a table without a value here fails them; and that the
// round trip gives back the whole struct (operator==), so a field added to a
// struct without a key in its table fails them too.
#ifndef TOTALGRAD_TESTS_TESTUTIL_EVERY_OPTION_H_
#define TOTALGRAD_TESTS_TESTUTIL_EVERY_OPTION_H_

#include <string>
#include <vector>

#include "core/learner/trial_options.h"

namespace totalgrad::testing {

inline learner::TrialOptions EveryOptionChanged() {
  learner::TrialOptions o;
  tasks::SceneOptions& s = o.scene;
  s.scene = "cartpole-balance";
  s.cost = "tip";
  s.noise_k = 0.25;
  s.horizon = 17;
  s.initial_std = 0.05;
  s.plant.cart_mass = 0.7;
  s.plant.pole_mass = 0.3;
  s.plant.pole_length = 0.6;
  s.plant.friction = 0.2;
  s.plant.gravity = 9.81;
  s.plant.dt = 0.05;
  s.plant.max_force = 12.5;
  s.plant.integrator.relative_tolerance = 1e-9;
  s.plant.integrator.absolute_tolerance = 1.0 / 3.0 * 1e-9;  // no short decimal form
  s.plant.integrator.initial_step = 2e-3;
  s.plant.integrator.min_step = 1e-13;
  s.plant.integrator.max_steps = 100000;
  o.method = estimators::Method::kGtp;
  o.seed = 42;
  o.episodes = 3;
  o.policy_steps = 7;
  o.particles = 11;
  o.eval_rollouts = 4;
  o.success_threshold = 12.5;
  o.basis_functions = 9;
  o.model_noise_multiplier = 2.0;
  o.predicted_cost_particles = 33;
  o.policy_init_lengthscale = 0.7;
  o.policy_centre_std = 0.9;
  o.optimizer.learning_rate = 1.0 / 3.0 * 1e-3;
  o.optimizer.momentum = 0.8;
  o.optimizer.decay = 0.95;
  o.optimizer.epsilon = 1e-7;
  o.optimizer.normalisation = learner::Normalisation::kParticleStd;
  o.gp_training.max_iterations = 50;
  o.gp_training.penalty.enabled = false;
  o.gp_training.penalty.lengthscale_ratio = 50.0;
  o.gp_training.penalty.signal_to_noise = 500.0;
  o.gp_training.penalty.power = 20;
  o.angle_features = learner::AngleFeatures::kSinCos;
  o.gp_inducing = 100;
  o.gp_variance_tolerance = 1e-4;
  o.verdict_rollouts = 7;
  o.verdict_distance = 0.3;
  o.verdict_hold_seconds = 0.5;
  o.pilco_line_searches = 40;
  o.pilco_evaluations_per_line_search = 12;
  o.policy = policy::PolicyClass::kLinear;
  o.estimator.lr_weights = estimators::LrWeights::kPlain;
  o.estimator.lr_baseline = estimators::LrBaseline::kLeaveOneOut;
  o.estimator.gs_derivative = estimators::GsDerivative::kExact;
  o.estimator.sn_noise_multiplier = 16.0;
  o.estimator.forced_k_lr = 0.25;
  return o;
}

// The keys whose canonical text in `options` is the default's.
inline std::vector<std::string> KeysAtDefault(const learner::TrialOptions& options) {
  const auto pairs = learner::TrialOptionPairs(options);
  const auto defaults = learner::TrialOptionPairs(learner::TrialOptions());
  std::vector<std::string> keys;
  for (size_t i = 0; i < pairs.size(); ++i)
    if (pairs[i] == defaults[i]) keys.push_back(pairs[i].first);
  return keys;
}

}  // namespace totalgrad::testing

#endif  // TOTALGRAD_TESTS_TESTUTIL_EVERY_OPTION_H_
