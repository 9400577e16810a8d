// The seam between the worker runtime and the code that runs jobs: one
// runner interface for every job kind, in the core's types (no protos, no
// gRPC), so the runtime's networking is tested with fakes and the runners
// without a coordinator. A worker holds one runner per kind it runs
// (worker.h, JobRunners); the real ones are LearnerTrialRunner
// (learner_runner.h, over learner::RunTrial) and CoreStudyRunner
// (study_runner.h, over study::RunStudy).
//
// A job's rows reach the coordinator one of two ways, whatever its kind:
// streamed while it runs (JobProgress::OnEpisode, a trial's episodes, each
// followed by a checkpoint), or returned whole in the JobOutcome when it
// ends (a study's cells and reference gradients: it reports nothing while
// it runs). The records are the core's own (core/learner/episode_record.h,
// core/study/study_records.h: header only, so the runtime links no
// numerical code); the runtime converts them to the wire by their field
// tables (runtime/record_proto.h).
#ifndef TOTALGRAD_WORKER_JOB_RUNNER_H_
#define TOTALGRAD_WORKER_JOB_RUNNER_H_

#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "core/common/option_pairs.h"
#include "core/learner/episode_record.h"
#include "core/study/study_records.h"

namespace totalgrad::worker {


// One finished episode: its record (learner::EpisodeSummary, the core's own;
// NaN: no value, e.g. the evaluation of episode 0) and the trial's details.
struct EpisodeOutcome : learner::EpisodeSummary {
  std::string details_json;  // JSON object: hyperparameters, numerical flags
};

// What a lease asks a runner to do; each kind reads what it needs.
struct JobInput {
  // Trials: options applied in order to the default options.
  OptionPairs options;
  // Studies: the self-contained spec (the study file's JSON with its
  // snapshot inlined; io/study_file.h).
  std::string spec_json;
  // A checkpoint of an earlier attempt of this job written by this build
  // (JobProgress::OnCheckpoint data) to resume from; empty: start from the
  // beginning. Only kinds that keep checkpoints get one.
  std::string resume_from;
};

// How a job ended, when it ran to the end.
struct JobOutcome {
  // The verdict (trials): the last evaluation mean below the success
  // threshold, that mean, and how many episodes went through OnEpisode.
  bool success = false;
  double final_eval_cost = learner::EpisodeSummary::kNaN;
  int episodes = 0;
  // Rows returned at the end (studies), each keyed by its position.
  std::vector<study::CellResult> study_cells;
  std::vector<study::ReferenceGradient> study_references;
};

class JobProgress {
 public:
  virtual ~JobProgress() = default;
  // Called once per finished episode, in order, on the job's thread.
  virtual void OnEpisode(const EpisodeOutcome& episode) = 0;
  // Polled often; true asks the job to stop (it then returns Cancelled).
  virtual bool ShouldCancel() = 0;
  // Called after each finished episode, right after OnEpisode, with the
  // trial's state in the versioned checkpoint encoding of
  // core/learner/checkpoint.h: what a later attempt resumes from. Default:
  // ignored.
  virtual void OnCheckpoint(int episode, int format_version, std::string data) {}
};

class JobRunner {
 public:
  virtual ~JobRunner() = default;
  // Runs one job. With `job.resume_from` set, the restored episodes are
  // reported again, then the job continues as if never interrupted; if the
  // checkpoint cannot be used the runner returns FailedPrecondition starting
  // "cannot resume" before reporting anything (the caller then starts over
  // without it). Must be safe to call from several threads at once (one job
  // each). Errors: InvalidArgument (options or spec), Cancelled
  // (ShouldCancel), or the job's own failure (Internal, FailedPrecondition,
  // ...), named.
  virtual absl::StatusOr<JobOutcome> Run(const JobInput& job, JobProgress* progress) = 0;
  // CPU seconds the job is expected to take on the cost model's reference
  // machine (core/learner/cost_model.h), from its options alone; nullopt
  // where the kind has no model (or the options cannot be read: Run will
  // say why). A worker with a walltime gives back a job it cannot finish.
  virtual std::optional<double> EstimateCpuSeconds(const JobInput& job) const {
    return std::nullopt;
  }
};

}  // namespace totalgrad::worker

#endif  // TOTALGRAD_WORKER_JOB_RUNNER_H_
