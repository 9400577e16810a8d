// The trial's options as one table composed of the modules' tables: every
// field has a key, and the whole struct round-trips through option pairs and
// checkpoints (snapshots: tests/io/snapshot_json_test.cc; sweep files:
// tests/service/trial_options_sweep_test.cc).
#include "core/learner/trial_options.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <set>
#include <string>

#include "absl/strings/numbers.h"
#include "core/learner/checkpoint.h"
#include "tests/testutil/every_option.h"
#include "tests/testutil/test_base.h"

namespace totalgrad::learner {
namespace trial_options_test {

using ::totalgrad::testing::EveryOptionChanged;
using ::totalgrad::testing::KeysAtDefault;

TEST(TrialOptionTable, KeysAreUniqueAndComposeTheModulesTables) {
  const std::vector<std::string> keys = TrialOptionKeys();
  EXPECT_EQ(std::set<std::string>(keys.begin(), keys.end()).size(), keys.size());
  // Every module's keys appear in the trial's table, each exactly once.
  for (const std::vector<std::string>& module :
       {tasks::SceneOptions::Table().Keys(), tasks::CartPoleParams::Table().Keys(),
        ode::IntegratorOptions::Table().Keys(), OptimizerOptions::Table().Keys(),
        gp::TrainingOptions::Table().Keys(), gp::PenaltyOptions::Table().Keys(),
        estimators::EstimatorOptions::Table().Keys()}) {
    for (const std::string& key : module)
      EXPECT_EQ(std::count(keys.begin(), keys.end(), key), 1) << key;
  }
  // The options the issue found missing have keys now.
  for (const char* key : {"forced_k_lr", "gravity", "gp_penalty_power", "gp_penalty_lengthscale_ratio",
                          "gp_penalty_signal_to_noise", "integrator_relative_tolerance",
                          "integrator_absolute_tolerance", "integrator_initial_step",
                          "integrator_min_step", "integrator_max_steps"})
    EXPECT_TRUE(TrialOptions::Table().Has(key)) << key;
}

// The existing keys and their canonical texts are what stored sweeps,
// snapshots and checkpoints hold: they must not change.
TEST(TrialOptionTable, ExistingKeysAndDefaultTextsAreUnchanged) {
  const std::vector<std::pair<std::string, std::string>> stored = {
      {"scene", "cartpole-swingup"}, {"cost", "angle"}, {"noise_k", "1"}, {"horizon", "30"},
      {"initial_std", "0.10000000000000001"}, {"cart_mass", "0.5"}, {"pole_mass", "0.5"},
      {"pole_length", "0.5"}, {"friction", "0.10000000000000001"}, {"dt", "0.10000000000000001"},
      {"max_force", "10"}, {"method", "RP"}, {"seed", "1"}, {"episodes", "15"},
      {"policy_steps", "600"}, {"particles", "300"}, {"eval_rollouts", "30"}, {"threshold", "15"},
      {"basis_functions", "50"}, {"model_noise_multiplier", "1"},
      {"predicted_cost_particles", "1000"}, {"policy_init_lengthscale", "1"},
      {"policy_centre_std", "1"}, {"learning_rate", "0.00050000000000000001"},
      {"momentum", "0.90000000000000002"}, {"decay", "0.90000000000000002"},
      {"epsilon", "1e-08"}, {"normalisation", "mean_std"}, {"gp_iterations", "300"},
      {"angle_features", "auto"}, {"gp_inducing", "-1"}, {"gp_penalty", "true"},
      {"lr_weights", "biw"}, {"lr_baseline", "biw"}, {"gs_derivative", "sampled"},
      {"sn_noise_multiplier", "25"}};
  const auto pairs = TrialOptionPairs(TrialOptions());
  for (const auto& expected : stored)
    EXPECT_NE(std::find(pairs.begin(), pairs.end(), expected), pairs.end())
        << expected.first << "=" << expected.second;
}

// Every option says what it holds (CLI help, typed export columns, Python),
// and its default text parses as that type.
TEST(TrialOptionTable, EveryFieldHasATypeItsDefaultParsesAs) {
  const auto& table = TrialOptions::Table();
  EXPECT_EQ(table.Find("noise_k")->type, OptionType::kNumber);
  EXPECT_EQ(table.Find("threshold")->type, OptionType::kNumber);
  EXPECT_EQ(table.Find("particles")->type, OptionType::kInteger);
  EXPECT_EQ(table.Find("seed")->type, OptionType::kInteger);
  EXPECT_EQ(table.Find("gp_penalty")->type, OptionType::kBool);
  EXPECT_EQ(table.Find("method")->type, OptionType::kChoice);
  EXPECT_EQ(table.Find("method")->choices.front(), "RP");
  EXPECT_NE(std::find(table.Find("method")->choices.begin(), table.Find("method")->choices.end(),
                      "GTP+sn"),
            table.Find("method")->choices.end());
  EXPECT_EQ(table.Find("normalisation")->type, OptionType::kChoice);
  EXPECT_EQ(table.Find("no_such_key"), nullptr);
  for (const auto& [key, text] : TrialOptionPairs(TrialOptions())) {
    const auto* field = table.Find(key);
    ASSERT_NE(field, nullptr) << key;
    switch (field->type) {
      case OptionType::kNumber: {
        double value;
        EXPECT_TRUE(ParseOptionDouble(key, text, &value).ok()) << key << "=" << text;
        break;
      }
      case OptionType::kInteger: {
        int64_t value;
        EXPECT_TRUE(absl::SimpleAtoi(text, &value)) << key << "=" << text;
        break;
      }
      case OptionType::kBool:
        EXPECT_TRUE(text == "true" || text == "false") << key << "=" << text;
        break;
      case OptionType::kChoice:
        EXPECT_NE(std::find(field->choices.begin(), field->choices.end(), text),
                  field->choices.end())
            << key << "=" << text;
        break;
      case OptionType::kText:
        break;
    }
  }
}

TEST(TrialOptionTable, EveryFieldRoundTripsThroughPairs) {
  const TrialOptions changed = EveryOptionChanged();
  TG_ASSERT_OK(changed.Validate());
  EXPECT_EQ(KeysAtDefault(changed), std::vector<std::string>{})
      << "a key of TrialOptions::Table() keeps its default in EveryOptionChanged()";
  absl::StatusOr<TrialOptions> back = TrialOptionsFromPairs(TrialOptionPairs(changed));
  TG_ASSERT_OK(back.status());
  EXPECT_TRUE(*back == changed) << "a field of TrialOptions is missing from its module's table";
  // And the other way: a default struct is not equal (operator== can fail).
  EXPECT_FALSE(TrialOptions() == changed);
}

// A checkpoint keeps the options as pairs: a decoded checkpoint resumes
// exactly the trial it was taken from, and no other.
TEST(TrialOptionTable, EveryFieldRoundTripsThroughCheckpoints) {
  const TrialOptions changed = EveryOptionChanged();
  TrialCheckpoint checkpoint;
  checkpoint.episode = 0;
  checkpoint.options = TrialOptionPairs(changed);
  checkpoint.episodes.resize(1);
  checkpoint.states.resize(0, 4);
  checkpoint.next_states.resize(0, 4);
  absl::StatusOr<TrialCheckpoint> decoded = DecodeCheckpoint(EncodeCheckpoint(checkpoint));
  TG_ASSERT_OK(decoded.status());
  absl::StatusOr<TrialOptions> back = TrialOptionsFromPairs(decoded->options);
  TG_ASSERT_OK(back.status());
  EXPECT_TRUE(*back == changed);
  TG_EXPECT_OK(CheckResumable(*decoded, changed));
  TrialOptions other = changed;
  other.estimator.forced_k_lr = 0.5;
  const absl::Status refused = CheckResumable(*decoded, other);
  EXPECT_EQ(refused.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(refused.message().find("forced_k_lr"), std::string::npos) << refused;
}

// A checkpoint written before an option existed lists no pair for it: it
// resumes a trial that keeps that option's default, and no other.
TEST(TrialOptionTable, CheckpointsWithoutANewerOptionResumeItsDefault) {
  TrialCheckpoint checkpoint;
  checkpoint.episodes.resize(1);
  for (const auto& pair : TrialOptionPairs(TrialOptions()))
    if (pair.first != "forced_k_lr") checkpoint.options.push_back(pair);
  TG_EXPECT_OK(CheckResumable(checkpoint, TrialOptions()));
  TrialOptions forced;
  forced.estimator.forced_k_lr = 0.0;
  EXPECT_FALSE(CheckResumable(checkpoint, forced).ok());
}

// gp_variance_tolerance's default changed (0 -> 1e-2) after files without
// the key were stored: such stored pairs (checkpoints, job options,
// snapshots) read as 0, the exact variance they were computed with; options
// from a user (flags, sweep files) take today's default.
TEST(TrialOptionTable, StoredPairsWithoutGpVarianceToleranceReadAsExact) {
  std::vector<std::pair<std::string, std::string>> old_pairs;
  for (const auto& pair : TrialOptionPairs(TrialOptions()))
    if (pair.first != "gp_variance_tolerance") old_pairs.push_back(pair);
  ASSERT_EQ(old_pairs.size() + 1, TrialOptionPairs(TrialOptions()).size());
  absl::StatusOr<TrialOptions> stored = TrialOptionsFromStoredPairs(old_pairs);
  TG_ASSERT_OK(stored.status());
  EXPECT_EQ(stored->gp_variance_tolerance, 0.0);
  absl::StatusOr<TrialOptions> fresh = TrialOptionsFromPairs(old_pairs);
  TG_ASSERT_OK(fresh.status());
  EXPECT_EQ(fresh->gp_variance_tolerance, kDefaultGpVarianceTolerance);
  EXPECT_GT(TrialOptions().gp_variance_tolerance, 0.0);
  // Pairs that list the key keep its value either way.
  absl::StatusOr<TrialOptions> listed = TrialOptionsFromStoredPairs(TrialOptionPairs(TrialOptions()));
  TG_ASSERT_OK(listed.status());
  EXPECT_TRUE(*listed == TrialOptions());
  // An old checkpoint resumes the exact trial it came from, not a default one.
  TrialCheckpoint checkpoint;
  checkpoint.episodes.resize(1);
  checkpoint.options = old_pairs;
  TrialOptions exact;
  exact.gp_variance_tolerance = 0;
  TG_EXPECT_OK(CheckResumable(checkpoint, exact));
  const absl::Status refused = CheckResumable(checkpoint, TrialOptions());
  EXPECT_EQ(refused.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(refused.message().find("gp_variance_tolerance"), std::string::npos) << refused;
}

TEST(TrialOptionTable, ErrorsNameTheKeyAndLeaveTheOptionsUnchanged) {
  TrialOptions o;
  absl::Status s = SetTrialOption("gravity", "fast", &o);
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("'gravity'"), std::string::npos) << s;
  EXPECT_EQ(o.scene.plant.gravity, 9.82);
  s = SetTrialOption("normalisation", "adam", &o);
  EXPECT_NE(s.message().find("particle_std, mean_std, rmsprop"), std::string::npos) << s;
  s = SetTrialOption("method", "XYZ", &o);
  EXPECT_NE(s.message().find("option 'method': unknown method 'XYZ'"), std::string::npos) << s;
  s = SetTrialOption("seed", "-1", &o);
  EXPECT_NE(s.message().find("not a non-negative integer"), std::string::npos) << s;
  s = SetTrialOption("gp_penalty", "maybe", &o);
  EXPECT_NE(s.message().find("true/false"), std::string::npos) << s;
  // Issue 29: a typo gets the one close key, not the whole list of keys.
  s = SetTrialOption("particels", "5", &o);
  EXPECT_EQ(s.message(), "unknown option 'particels'; did you mean 'particles'?") << s;
  s = SetTrialOption("zzzzzz", "5", &o);
  EXPECT_NE(s.message().find("unknown option 'zzzzzz'; known: "), std::string::npos) << s;
  EXPECT_NE(s.message().find("particles"), std::string::npos) << s;
  EXPECT_TRUE(o == TrialOptions());
}

// Each module validates its own fields; the message names the key (or, for
// the plant and its integrator, the field as tasks::MakeScene names it).
TEST(TrialOptionTable, ModulesValidateTheirOwnFields) {
  struct Case {
    const char* key;
    const char* value;
    const char* named;
  };
  for (const Case& c : {Case{"gp_penalty_power", "3", "gp_penalty_power"},
                        Case{"gp_penalty_lengthscale_ratio", "1", "gp_penalty_lengthscale_ratio"},
                        Case{"gp_penalty_signal_to_noise", "0.5", "gp_penalty_signal_to_noise"},
                        Case{"sn_noise_multiplier", "-1", "sn_noise_multiplier"},
                        Case{"learning_rate", "0", "learning_rate"},
                        Case{"integrator_max_steps", "0", "max_steps"},
                        Case{"integrator_relative_tolerance", "-1", "relative_tolerance"},
                        Case{"pilco_line_searches", "0", "pilco_line_searches"},
                        Case{"pilco_evaluations_per_line_search", "-2",
                             "pilco_evaluations_per_line_search"}}) {
    TrialOptions o;
    TG_ASSERT_OK(SetTrialOption(c.key, c.value, &o));
    const absl::Status s = o.Validate();
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << c.key;
    EXPECT_NE(s.message().find(c.named), std::string::npos) << c.key << ": " << s;
  }
  // A negative gravity is refused by the option table's range when set by
  // key (issue 28); a struct filled in code is still checked by the scene.
  TrialOptions negative_gravity;
  const absl::Status by_key = SetTrialOption("gravity", "-9.82", &negative_gravity);
  EXPECT_EQ(by_key.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(by_key.message().find("gravity"), std::string::npos) << by_key;
  negative_gravity.scene.plant.gravity = -9.82;
  const absl::Status validated = negative_gravity.Validate();
  EXPECT_EQ(validated.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(validated.message().find("plant.gravity"), std::string::npos) << validated;
}

TEST(TrialOptionTable, AutoFeaturesAndInducingInputsAreResolvedInOnePlace) {
  using estimators::Method;
  EXPECT_TRUE(UsesSinCosFeatures(Method::kPilco, AngleFeatures::kAuto));
  EXPECT_FALSE(UsesSinCosFeatures(Method::kRp, AngleFeatures::kAuto));
  EXPECT_TRUE(UsesSinCosFeatures(Method::kRp, AngleFeatures::kSinCos));
  EXPECT_FALSE(UsesSinCosFeatures(Method::kPilco, AngleFeatures::kRaw));
  TrialOptions o;
  EXPECT_EQ(InducingInputs(o), 0);
  o.method = Method::kPilco;
  EXPECT_EQ(InducingInputs(o), 300);
  o.gp_inducing = 0;
  EXPECT_EQ(InducingInputs(o), 0);
}

// PILCO's BFGS budget: auto is the scene's protocol (PILCO a0b48b7's
// settings_*.m: opt.length, opt.MFEPLS), an explicit value wins.
TEST(TrialOptionTable, PilcoBudgetIsTheScenesProtocolUnlessSet) {
  TrialOptions o;
  EXPECT_EQ(PilcoLineSearches(o), 150);
  EXPECT_EQ(PilcoEvaluationsPerLineSearch(o), 30);
  TG_ASSERT_OK(SetTrialOption("scene", "pendulum", &o));
  EXPECT_EQ(PilcoLineSearches(o), 75);
  TG_ASSERT_OK(SetTrialOption("scene", "pendubot", &o));
  EXPECT_EQ(PilcoLineSearches(o), 150);
  EXPECT_EQ(PilcoEvaluationsPerLineSearch(o), 20);
  TG_ASSERT_OK(SetTrialOption("pilco_line_searches", "7", &o));
  TG_ASSERT_OK(SetTrialOption("pilco_evaluations_per_line_search", "9", &o));
  EXPECT_EQ(PilcoLineSearches(o), 7);
  EXPECT_EQ(PilcoEvaluationsPerLineSearch(o), 9);
}

// Issue 29: a user's options take the scene's own horizon and threshold
// where they do not give them; stored pairs (which list every key they ran
// with) never do, and the cart-pole's are the plain defaults.
TEST(TrialOptionTable, UserOptionsTakeTheScenesHorizonAndThreshold) {
  for (const tasks::SceneDefinition& scene : tasks::SceneCatalog()) {
    absl::StatusOr<TrialOptions> user = TrialOptionsFromPairs({{"scene", scene.name}});
    if (!scene.trials_unavailable.empty()) {  // refused, naming the scene and why
      EXPECT_EQ(user.status().code(), absl::StatusCode::kInvalidArgument) << scene.name;
      EXPECT_NE(user.status().message().find(scene.trials_unavailable), std::string::npos)
          << user.status();
      continue;
    }
    TG_ASSERT_OK(user.status());
    EXPECT_EQ(user->scene.horizon, scene.horizon) << scene.name;
    EXPECT_EQ(user->success_threshold, scene.success_threshold) << scene.name;
    TG_EXPECT_OK(user->Validate());
  }
  absl::StatusOr<TrialOptions> pendulum = TrialOptionsFromPairs({{"scene", "pendulum"}});
  TG_ASSERT_OK(pendulum.status());
  EXPECT_EQ(pendulum->scene.horizon, 40);           // PILCO's settings_pendulum.m: T = 4, dt = 0.1
  EXPECT_EQ(pendulum->success_threshold, 20.0);     // H / 2
  // Given keys win, in either order with the scene.
  absl::StatusOr<TrialOptions> given =
      TrialOptionsFromPairs({{"horizon", "12"}, {"scene", "pendubot"}, {"threshold", "3.5"}});
  TG_ASSERT_OK(given.status());
  EXPECT_EQ(given->scene.horizon, 12);
  EXPECT_EQ(given->success_threshold, 3.5);
  // The cart-pole's scene defaults are TrialOptions{}'s: no stored number moves.
  absl::StatusOr<TrialOptions> cartpole = TrialOptionsFromPairs({});
  TG_ASSERT_OK(cartpole.status());
  EXPECT_TRUE(*cartpole == TrialOptions());
  // Stored pairs are taken as they are.
  std::vector<std::pair<std::string, std::string>> stored;
  for (const auto& pair : TrialOptionPairs(TrialOptions()))
    if (pair.first != "horizon" && pair.first != "threshold") stored.push_back(pair);
  stored.emplace_back("scene", "pendulum");
  absl::StatusOr<TrialOptions> from_store = TrialOptionsFromStoredPairs(stored);
  TG_ASSERT_OK(from_store.status());
  EXPECT_EQ(from_store->scene.horizon, 30);
  EXPECT_EQ(from_store->success_threshold, 15.0);
  EXPECT_EQ(SceneDefaultedKeys(),
            (std::vector<std::string>{"horizon", "threshold", "cost", "policy"}));
  // The unicycle's cost and policy class are its own unless given.
  absl::StatusOr<TrialOptions> unicycle = TrialOptionsFromPairs({{"scene", "unicycle"}});
  TG_ASSERT_OK(unicycle.status());
  EXPECT_EQ(unicycle->scene.cost, "unicycle");
  EXPECT_EQ(unicycle->policy, policy::PolicyClass::kLinear);
  EXPECT_EQ(unicycle->scene.horizon, 67);
  TG_EXPECT_OK(unicycle->Validate());
  absl::StatusOr<TrialOptions> unicycle_rbf =
      TrialOptionsFromPairs({{"policy", "rbf"}, {"scene", "unicycle"}});
  TG_ASSERT_OK(unicycle_rbf.status());
  EXPECT_EQ(unicycle_rbf->policy, policy::PolicyClass::kRbf);
  EXPECT_EQ(pendulum->scene.cost, "angle");
  EXPECT_EQ(pendulum->policy, policy::PolicyClass::kRbf);
}

}  // namespace trial_options_test
}  // namespace totalgrad::learner
