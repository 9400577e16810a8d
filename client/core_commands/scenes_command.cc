#include <iostream>
#include <memory>

#include <CLI/CLI.hpp>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "client/core_commands/commands.h"
#include "client/core_commands/scenes_format.h"

namespace totalgrad::cli {
namespace {

// The particles of a default trial, for the memory estimate.
constexpr int kDefaultParticles = 300;

std::vector<double> ToStd(const Vector& v) { return std::vector<double>(v.data(), v.data() + v.size()); }

std::string Join(const Vector& v) {
  return absl::StrJoin(ToStd(v), ", ", [](std::string* out, double x) { absl::StrAppend(out, absl::StrFormat("%g", x)); });
}

nlohmann::ordered_json MatrixRows(const Matrix& m) {
  nlohmann::ordered_json rows = nlohmann::ordered_json::array();
  for (Eigen::Index r = 0; r < m.rows(); ++r) rows.push_back(ToStd(m.row(r).transpose()));
  return rows;
}

const char* PlantName(tasks::PlantKind kind) {
  switch (kind) {
    case tasks::PlantKind::kPendulum: return "pendulum";
    case tasks::PlantKind::kCartPole: return "cart-pole";
    case tasks::PlantKind::kCartDoublePendulum: return "cart-double-pendulum";
    case tasks::PlantKind::kDoublePendulum: return "double-pendulum";
    case tasks::PlantKind::kUnicycle: return "unicycle";
  }
  return "";
}

}  // namespace

nlohmann::ordered_json ScenesToJson(const std::vector<tasks::SceneDefinition>& scenes) {
  nlohmann::ordered_json out = nlohmann::ordered_json::array();
  for (const tasks::SceneDefinition& s : scenes) {
    nlohmann::ordered_json j;
    j["name"] = s.name;
    j["summary"] = s.summary;
    j["plant"] = PlantName(s.plant);
    j["state_dim"] = s.state_dim();
    j["control_dim"] = s.control_dim();
    j["state_names"] = s.state_names;
    j["state_units"] = s.state_units;
    j["control_names"] = s.control_names;
    j["max_control"] = ToStd(s.max_control);
    j["dt"] = s.dt;
    j["horizon"] = s.horizon;
    j["success_threshold"] = s.success_threshold;
    j["mu0"] = ToStd(s.mu0);
    j["start_std"] = ToStd(s.start_std);
    j["measurement_noise_std"] = ToStd(s.measurement_noise_std);
    j["target"] = ToStd(s.target);
    j["angle_indices"] = s.angle_indices;
    j["dynamics_inputs"] = s.dynamics_inputs;
    j["policy_inputs"] = s.policy_inputs;
    if (s.learner_mu0.size() > 0) {
      j["learner_state"] = {{"names", s.learner_state_names},
                            {"mu0", ToStd(s.learner_mu0)},
                            {"start_std", ToStd(s.learner_start_std)}};
    }
    j["gp"] = {{"inputs", static_cast<int>(s.dynamics_inputs.size()) + s.control_dim()},
               {"outputs", s.learner_state_dim()},
               {"model", absl::StrCat("full GP; FITC with ", s.inducing_inputs,
                                      " inducing inputs once N > ", s.inducing_inputs)},
               {"inducing_inputs", s.inducing_inputs}};
    j["cost"] = s.cost_kind;
    if (s.cost_kind == "unicycle") {
      j["unicycle_cost"] = {{"wheel_radius", s.unicycle_cost.wheel_radius},
                            {"rod_length", s.unicycle_cost.rod_length},
                            {"widths", s.unicycle_cost.widths}};
    } else {
      j["saturating_cost"] = {{"Q", MatrixRows(s.saturating_cost.q)},
                              {"widths", s.saturating_cost.widths},
                              {"target_z", ToStd(tasks::AugmentState(s.target, s.angle_indices))}};
    }
    if (!s.full_state.empty()) {
      const tasks::FullStateIndexSets& f = s.full_state;
      j["full_state"] = {{"names", f.names},
                         {"integrated", f.integrated},
                         {"augmented", f.augmented},
                         {"controls", f.controls},
                         {"predicted", f.predicted},
                         {"dynamics_inputs", f.dynamics_inputs},
                         {"policy_inputs", f.policy_inputs}};
    }
    j["policy"] = s.policy_class;
    j["trials"] = s.trials_unavailable.empty() ? "yes" : s.trials_unavailable;
    j["studies"] = !s.trials_unavailable.empty()    ? s.trials_unavailable
                   : !s.studies_unavailable.empty() ? s.studies_unavailable
                                                    : "yes";
    j["default_cost"] = s.default_cost;
    j["angle_cost"] = {{"Q_diagonal", ToStd(s.angle_cost_q)}, {"target", ToStd(s.target)}};
    j["protocol"] = {{"basis_functions", s.basis_functions},
                     {"learned_episodes", s.learned_episodes},
                     {"line_searches", s.line_searches},
                     {"evaluations_per_line_search", s.evaluations_per_line_search},
                     {"random_episodes", s.random_episodes},
                     {"random_control_fraction", s.random_control_fraction}};
    j["peak_trial_bytes"] = tasks::PeakTrialBytes(s, kDefaultParticles);
    j["source"] = s.source;
    out.push_back(std::move(j));
  }
  return out;
}

std::string ScenesText(const std::vector<tasks::SceneDefinition>& scenes) {
  std::string out;
  for (const tasks::SceneDefinition& s : scenes) {
    absl::StrAppend(&out, s.name, ": ", s.summary, "\n");
    absl::StrAppend(&out, "  D = ", s.state_dim(), " [", absl::StrJoin(s.state_names, ", "), "], F = ",
                    s.control_dim(), " [", absl::StrJoin(s.control_names, ", "), "] |u| <= [",
                    Join(s.max_control), "], dt = ", s.dt, " s, H = ", s.horizon, "\n");
    absl::StrAppend(&out, "  trial defaults: horizon ", s.horizon, ", threshold ", s.success_threshold,
                    " (success: the last evaluation's mean episode cost below it)\n");
    if (s.learner_mu0.size() > 0) {
      absl::StrAppend(&out, "  the learner sees ", s.learner_state_dim(), " [",
                      absl::StrJoin(s.learner_state_names, ", "), "], start N([",
                      Join(s.learner_mu0), "], diag([", Join(s.learner_start_std), "])^2)\n");
    }
    if (s.trials_unavailable.empty()) {
      absl::StrAppend(&out, "  angles ", absl::StrJoin(s.angle_indices, ","), "; GP inputs z[",
                      absl::StrJoin(s.dynamics_inputs, ","), "] + u, policy inputs z[",
                      absl::StrJoin(s.policy_inputs, ","), "]; FITC M = ", s.inducing_inputs,
                      " once N > M\n");
    } else {
      absl::StrAppend(&out, "  FITC M = ", s.inducing_inputs, " once N > M\n");
    }
    if (!s.full_state.empty()) {
      const tasks::FullStateIndexSets& f = s.full_state;
      const auto names = [&f](const std::vector<int>& indices, const std::vector<int>* of) {
        std::vector<std::string> out;
        for (int i : indices) out.push_back(f.names[of == nullptr ? i : (*of)[i]]);
        return absl::StrJoin(out, ",");
      };
      absl::StrAppend(&out, "  full state (", f.names.size(), "): integrated [",
                      names(f.integrated, nullptr), "], augmented [", names(f.augmented, nullptr),
                      "], controls [", names(f.controls, nullptr), "]; GP predicts [",
                      names(f.predicted, nullptr), "] from [",
                      names(f.dynamics_inputs, &f.predicted), "] + u; policy reads [",
                      names(f.policy_inputs, &f.predicted), "]\n");
    }
    absl::StrAppend(&out, "  start N([", Join(s.mu0), "], diag([", Join(s.start_std),
                    "])^2), noise std [", Join(s.measurement_noise_std), "], target [",
                    Join(s.target), "]\n");
    if (s.cost_kind == "unicycle") {
      absl::StrAppend(&out, "  cost loss_unicycle: wheel radius ", s.unicycle_cost.wheel_radius,
                      " m, rod length ", s.unicycle_cost.rod_length, " m, widths [",
                      absl::StrJoin(s.unicycle_cost.widths, ", "), "]\n");
    } else {
      absl::StrAppend(&out, "  saturating cost widths [",
                      absl::StrJoin(s.saturating_cost.widths, ", "), "]; angle cost Q = diag([",
                      Join(s.angle_cost_q), "])\n");
    }
    const std::string policy = s.policy_class == "linear"
                                   ? std::string("a linear policy")
                                   : absl::StrCat(s.basis_functions, " RBF centres");
    const std::string random =
        s.random_episodes == 1 && s.random_control_fraction == 1.0
            ? std::string()
            : absl::StrCat(s.random_episodes, " random rollouts at ", s.random_control_fraction,
                           " x |u| max, ");
    absl::StrAppend(&out, "  PILCO protocol: ", policy, ", ", random,
                    s.learned_episodes, " episodes, ", s.line_searches, " line searches x ",
                    s.evaluations_per_line_search, " evaluations; peak memory per trial ~",
                    absl::StrFormat("%.0f", tasks::PeakTrialBytes(s, kDefaultParticles) / 1e6), " MB\n");
    absl::StrAppend(&out, "  source: ", s.source, "\n");
    if (!s.trials_unavailable.empty()) {
      absl::StrAppend(&out, "  trials: not yet: ", s.trials_unavailable, "\n");
    } else if (!s.studies_unavailable.empty()) {
      absl::StrAppend(&out, "  studies: not yet: ", s.studies_unavailable, "\n");
    }
  }
  return out;
}

void AddScenesCommand(CLI::App* app, int* exit_code) {
  auto json = std::make_shared<bool>(false);
  CLI::App* cmd = app->add_subcommand("scenes", "List the scenes (plants, index sets, costs, defaults)");
  cmd->add_flag("--json", *json, "print JSON instead of text");
  cmd->callback([json, exit_code] {
    if (*json) {
      std::cout << ScenesToJson(tasks::SceneCatalog()).dump(2) << "\n";
    } else {
      std::cout << ScenesText(tasks::SceneCatalog());
    }
    *exit_code = 0;
  });
}

}  // namespace totalgrad::cli
