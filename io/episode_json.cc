#include "io/episode_json.h"

#include <cmath>

#include "io/record_format.h"

namespace totalgrad::io {
namespace {

nlohmann::json ToJson(const Vector& v) {
  nlohmann::json array = nlohmann::json::array();
  for (Eigen::Index i = 0; i < v.size(); ++i) array.push_back(v(i));
  return array;
}

}  // namespace

std::string EpisodeDetailsJson(const learner::EpisodeResult& result) {
  nlohmann::json details;
  const gp::GpHyperparameters& h = result.hyperparameters;
  if (h.log_lengthscales.size() > 0) {
    nlohmann::json lengthscales = nlohmann::json::array();
    for (Eigen::Index r = 0; r < h.log_lengthscales.rows(); ++r) {
      lengthscales.push_back(ToJson(h.log_lengthscales.row(r).transpose()));
    }
    details["gp"] = {{"log_lengthscales", lengthscales},
                     {"log_signal_std", ToJson(h.log_signal_std)},
                     {"log_noise_std", ToJson(h.log_noise_std)}};
  }
  details["flags"] = {{"non_finite_gradients", result.flags.non_finite_gradients},
                      {"gp_line_search_failures", result.flags.gp_line_search_failures},
                      {"gp_non_finite_evaluations", result.flags.gp_non_finite_evaluations},
                      {"zero_gradient", result.flags.zero_gradient},
                      {"gp_jitter", result.flags.gp_jitter}};
  details["cpu_seconds"] = result.cpu_seconds;
  const learner::EpisodeTiming& t = result.timing;
  details["timing"] = {{"model_cpu", t.model_cpu},
                       {"model_wall", t.model_wall},
                       {"policy_cpu", t.policy_cpu},
                       {"policy_wall", t.policy_wall},
                       {"policy_steps", t.policy_steps},
                       {"prediction_cpu", t.prediction_cpu},
                       {"prediction_wall", t.prediction_wall},
                       {"real_episode_cpu", t.real_episode_cpu},
                       {"real_episode_wall", t.real_episode_wall},
                       {"evaluation_cpu", t.evaluation_cpu},
                       {"evaluation_wall", t.evaluation_wall}};
  if (result.predicted_cost_mean_per_step.size() > 0) {  // PILCO
    details["predicted_cost_mean_per_step"] = ToJson(result.predicted_cost_mean_per_step);
    details["predicted_cost_std_per_step"] = ToJson(result.predicted_cost_std_per_step);
  }
  return details.dump();
}

nlohmann::json EpisodeToJson(const learner::EpisodeResult& result) {
  nlohmann::json j = nlohmann::json::parse(EpisodeDetailsJson(result));
  AppendRecordJson<learner::EpisodeSummary>(learner::EpisodeFields(), result, &j);
  return j;
}

nlohmann::json TrialSummaryJson(const learner::TrialSummary& summary,
                                const learner::TrialOptions& options) {
  nlohmann::json used = nlohmann::json::object();
  for (const auto& [key, value] : learner::TrialOptionPairs(options)) used[key] = value;
  const double held = summary.episodes.empty() ? std::nan("") : summary.episodes.back().held_fraction;
  return {{"success", summary.success},
          {"final_eval_cost", summary.final_eval_cost},
          {"threshold", options.success_threshold},
          {"held_fraction", std::isnan(held) ? nlohmann::json(nullptr) : nlohmann::json(held)},
          {"options", used}};
}

}  // namespace totalgrad::io
