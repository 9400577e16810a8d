#include "worker/learner_runner.h"

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "core/learner/checkpoint.h"
#include "core/learner/trial.h"

namespace totalgrad::worker {
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

namespace {

class ObserverAdapter final : public learner::TrialObserver {
 public:
  explicit ObserverAdapter(TrialProgress* progress) : progress_(progress) {}
  void OnEpisode(const learner::EpisodeResult& result) override {
    if (progress_ == nullptr) return;
    EpisodeOutcome e;
    e.episode = result.episode;
    e.real_cost = result.real_cost;
    e.eval_cost_mean = result.eval_cost_mean;
    e.eval_cost_std = result.eval_cost_std;
    e.predicted_cost = result.predicted_cost;
    e.optimisation_seconds = result.optimisation_seconds;
    e.cpu_seconds = result.cpu_seconds;
    e.details_json = EpisodeDetailsJson(result);
    progress_->OnEpisode(e);
  }
  bool ShouldCancel() override { return progress_ != nullptr && progress_->ShouldCancel(); }
  bool WantsCheckpoints() override { return progress_ != nullptr; }
  void OnCheckpoint(const learner::TrialCheckpoint& checkpoint) override {
    progress_->OnCheckpoint(checkpoint.episode, learner::kCheckpointFormatVersion,
                            learner::EncodeCheckpoint(checkpoint));
  }

 private:
  TrialProgress* progress_;
};

absl::StatusOr<learner::TrialOptions> ApplyOptions(const OptionList& options) {
  learner::TrialOptions trial_options;
  for (const auto& [key, value] : options) {
    absl::Status status = learner::SetTrialOption(key, value, &trial_options);
    if (!status.ok()) return status;
  }
  return trial_options;
}

absl::StatusOr<TrialOutcome> RunFrom(const learner::TrialOptions& options,
                                     const learner::TrialCheckpoint* resume_from, int threads,
                                     TrialProgress* progress) {
  ObserverAdapter observer(progress);
  learner::RunOptions run;
  run.threads = threads;
  absl::StatusOr<learner::TrialSummary> summary =
      learner::RunTrial(options, &observer, resume_from, run);
  if (!summary.ok()) return summary.status();
  TrialOutcome outcome;
  outcome.success = summary->success;
  outcome.final_eval_cost = summary->final_eval_cost;
  outcome.episodes = static_cast<int>(summary->episodes.size());
  return outcome;
}

}  // namespace

absl::StatusOr<TrialOutcome> LearnerTrialRunner::Run(const OptionList& options,
                                                     TrialProgress* progress) {
  absl::StatusOr<learner::TrialOptions> trial_options = ApplyOptions(options);
  if (!trial_options.ok()) return trial_options.status();
  return RunFrom(*trial_options, nullptr, threads_, progress);
}

absl::StatusOr<TrialOutcome> LearnerTrialRunner::Resume(const OptionList& options,
                                                        const std::string& checkpoint,
                                                        TrialProgress* progress) {
  absl::StatusOr<learner::TrialOptions> trial_options = ApplyOptions(options);
  if (!trial_options.ok()) return trial_options.status();
  absl::StatusOr<learner::TrialCheckpoint> decoded = learner::DecodeCheckpoint(checkpoint);
  absl::Status usable = decoded.ok() ? learner::CheckResumable(*decoded, *trial_options)
                                     : decoded.status();
  if (!usable.ok()) {
    return absl::FailedPreconditionError(absl::StrCat("cannot resume: ", usable.message()));
  }
  return RunFrom(*trial_options, &*decoded, threads_, progress);
}

}  // namespace totalgrad::worker
