#include "client/core_commands/trial_format.h"

#include <cmath>

namespace totalgrad::cli {
namespace {
nlohmann::json Number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }
}  // namespace

nlohmann::json EpisodeToJson(const learner::EpisodeResult& result) {
  nlohmann::json j;
  j["episode"] = result.episode;
  j["real_cost"] = Number(result.real_cost);
  j["eval_cost_mean"] = Number(result.eval_cost_mean);
  j["eval_cost_std"] = Number(result.eval_cost_std);
  j["predicted_cost"] = Number(result.predicted_cost);
  j["seconds"] = result.optimisation_seconds;
  j["cpu_seconds"] = result.cpu_seconds;
  const learner::EpisodeTiming& t = result.timing;
  j["timing"] = {{"model_cpu", t.model_cpu},           {"model_wall", t.model_wall},
                 {"policy_cpu", t.policy_cpu},         {"policy_wall", t.policy_wall},
                 {"policy_steps", t.policy_steps},     {"prediction_cpu", t.prediction_cpu},
                 {"prediction_wall", t.prediction_wall}, {"real_episode_cpu", t.real_episode_cpu},
                 {"real_episode_wall", t.real_episode_wall}, {"evaluation_cpu", t.evaluation_cpu},
                 {"evaluation_wall", t.evaluation_wall}};
  j["flags"] = {{"non_finite_gradients", result.flags.non_finite_gradients},
                {"gp_line_search_failures", result.flags.gp_line_search_failures},
                {"gp_non_finite_evaluations", result.flags.gp_non_finite_evaluations},
                {"zero_gradient", result.flags.zero_gradient},
                {"gp_jitter", result.flags.gp_jitter}};
  // The GP as the service stores it (details_json, docs/results_schema.md):
  // an object of arrays, log_lengthscales D x E (one row per output).
  const auto& h = result.hyperparameters;
  if (h.num_outputs() > 0) {
    nlohmann::json lengthscales = nlohmann::json::array();
    for (int a = 0; a < h.num_outputs(); ++a) {
      lengthscales.push_back(std::vector<double>(h.log_lengthscales.row(a).data(),
                                                 h.log_lengthscales.row(a).data() + h.num_inputs()));
    }
    j["gp"] = {{"log_lengthscales", lengthscales},
               {"log_signal_std", std::vector<double>(h.log_signal_std.data(),
                                                      h.log_signal_std.data() + h.num_outputs())},
               {"log_noise_std", std::vector<double>(h.log_noise_std.data(),
                                                     h.log_noise_std.data() + h.num_outputs())}};
  }
  // PILCO: the model's predicted cost mean and std at each step t = 1..H.
  if (result.predicted_cost_mean_per_step.size() > 0) {
    nlohmann::json mean = nlohmann::json::array(), stddev = nlohmann::json::array();
    for (double v : result.predicted_cost_mean_per_step) mean.push_back(Number(v));
    for (double v : result.predicted_cost_std_per_step) stddev.push_back(Number(v));
    j["predicted_cost_mean_per_step"] = mean;
    j["predicted_cost_std_per_step"] = stddev;
  }
  return j;
}

std::string FlagsText(const learner::EpisodeFlags& flags) {
  std::string text;
  auto add = [&text](const std::string& s) { text += (text.empty() ? "" : ",") + s; };
  if (flags.non_finite_gradients > 0) add("nonfinite_grad=" + std::to_string(flags.non_finite_gradients));
  if (flags.gp_line_search_failures > 0) add("gp_ls_fail=" + std::to_string(flags.gp_line_search_failures));
  if (flags.gp_non_finite_evaluations > 0) add("gp_nonfinite=" + std::to_string(flags.gp_non_finite_evaluations));
  if (flags.zero_gradient) add("zero_grad");
  if (flags.gp_jitter) add("gp_jitter");
  return text.empty() ? "-" : text;
}

}  // namespace totalgrad::cli
