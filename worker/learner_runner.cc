#include "worker/learner_runner.h"

#include "absl/strings/str_cat.h"
#include "core/learner/checkpoint.h"
#include "core/learner/cost_model.h"
#include "core/learner/trial.h"
#include "io/episode_json.h"

namespace totalgrad::worker {
namespace {

class ObserverAdapter final : public learner::TrialObserver {
 public:
  explicit ObserverAdapter(JobProgress* progress) : progress_(progress) {}
  void OnEpisode(const learner::EpisodeResult& result) override {
    if (progress_ == nullptr) return;
    EpisodeOutcome e;
    static_cast<learner::EpisodeSummary&>(e) = result;  // the record, whole
    e.details_json = io::EpisodeDetailsJson(result);
    progress_->OnEpisode(e);
  }
  bool ShouldCancel() override { return progress_ != nullptr && progress_->ShouldCancel(); }
  bool WantsCheckpoints() override { return progress_ != nullptr; }
  void OnCheckpoint(const learner::TrialCheckpoint& checkpoint) override {
    progress_->OnCheckpoint(checkpoint.episode, learner::kCheckpointFormatVersion,
                            learner::EncodeCheckpoint(checkpoint));
  }

 private:
  JobProgress* progress_;
};

// A job's options are stored pairs: one stored before a key existed reads
// as the value it was submitted with (learner::TrialOptionsFromStoredPairs).
absl::StatusOr<learner::TrialOptions> ApplyOptions(const OptionPairs& options) {
  return learner::TrialOptionsFromStoredPairs(options);
}

absl::StatusOr<JobOutcome> RunFrom(const learner::TrialOptions& options,
                                   const learner::TrialCheckpoint* resume_from, int threads,
                                   JobProgress* progress) {
  ObserverAdapter observer(progress);
  learner::RunOptions run;
  run.threads = threads;
  absl::StatusOr<learner::TrialSummary> summary =
      learner::RunTrial(options, &observer, resume_from, run);
  if (!summary.ok()) return summary.status();
  JobOutcome outcome;
  outcome.success = summary->success;
  outcome.final_eval_cost = summary->final_eval_cost;
  outcome.episodes = static_cast<int>(summary->episodes.size());
  return outcome;
}

}  // namespace

std::optional<double> LearnerTrialRunner::EstimateCpuSeconds(const JobInput& job) const {
  absl::StatusOr<learner::TrialOptions> trial_options = ApplyOptions(job.options);
  if (!trial_options.ok() || !trial_options->Validate().ok()) return std::nullopt;
  return learner::EstimateTrialCost(*trial_options).total_cpu();
}

absl::StatusOr<JobOutcome> LearnerTrialRunner::Run(const JobInput& job, JobProgress* progress) {
  absl::StatusOr<learner::TrialOptions> trial_options = ApplyOptions(job.options);
  if (!trial_options.ok()) return trial_options.status();
  if (job.resume_from.empty()) return RunFrom(*trial_options, nullptr, threads_, progress);
  absl::StatusOr<learner::TrialCheckpoint> decoded = learner::DecodeCheckpoint(job.resume_from);
  absl::Status usable = decoded.ok() ? learner::CheckResumable(*decoded, *trial_options)
                                     : decoded.status();
  if (!usable.ok()) {
    return absl::FailedPreconditionError(absl::StrCat("cannot resume: ", usable.message()));
  }
  return RunFrom(*trial_options, &*decoded, threads_, progress);
}

}  // namespace totalgrad::worker
