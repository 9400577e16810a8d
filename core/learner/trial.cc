// RunTrial: the episode loop. What a method does with the data is its
// learner's (policy_learner.h); how problems are assembled is
// problem_builder.h's; options are trial_options.h's.
#include "core/learner/trial.h"

#include <chrono>
#include <memory>

#include "absl/strings/str_cat.h"
#include "core/common/blas.h"
#include "core/common/rng.h"
#include "core/common/thread_pool.h"
#include "core/learner/checkpoint.h"
#include "core/learner/evaluation.h"
#include "core/learner/phase_clock.h"
#include "core/learner/policy_learner.h"
#include "core/learner/problem_builder.h"

namespace totalgrad::learner {
namespace {

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

// The stream index of episode 0's random rollout j >= 1 (rollout 0 keeps
// index 0, the learned episodes' e, and evaluation's its own stream): far
// above any episode number.
constexpr uint64_t kRandomRolloutIndexBase = uint64_t{1} << 40;

// Episode 0: random exploration, scene.random_episodes real episodes (1 but
// on the unicycle, PILCO's J = 10), each control uniform in
// +-random_control_fraction x its bound; their data are appended to `data`
// in order. The episode's real cost is their mean cost, its trajectory the
// first's.
absl::StatusOr<EpisodeResult> RandomEpisode(const tasks::Scene& scene, uint64_t seed,
                                            ThreadPool* pool, Transitions& data) {
  PhaseClock clock(pool);
  Rng action_rng(seed, Stream::kExplorationAction);
  // Each control uniform in its bounds, drawn in control order (one stream
  // through all the rollouts).
  const tasks::MultiController random_controller = [&](const Vector&) {
    Vector u(scene.control_dim());
    for (int j = 0; j < scene.control_dim(); ++j) {
      const double bound = scene.random_control_fraction * scene.max_control(j);
      u(j) = action_rng.Uniform(-bound, bound);
    }
    return u;
  };
  EpisodeResult result;
  result.episode = 0;
  double cost_sum = 0;
  for (int r = 0; r < scene.random_episodes; ++r) {
    const uint64_t index = r == 0 ? 0 : kRandomRolloutIndexBase + static_cast<uint64_t>(r);
    Rng start_rng(seed, Stream::kInitialState, index);
    Rng noise_rng(seed, Stream::kObservationNoise, index);
    tasks::Episode episode;
    const absl::Status status =
        tasks::RunEpisode(scene, random_controller, &start_rng, &noise_rng, &episode);
    if (!status.ok()) {
      return absl::InternalError(absl::StrCat(
          "episode 0", scene.random_episodes > 1 ? absl::StrCat(" (random rollout ", r, ")") : "",
          ": ", status.message()));
    }
    data.Append(episode);
    cost_sum += episode.total_cost;
    if (r == 0) result.trajectories.real = TrajectoryOfEpisode(episode);
  }
  result.real_cost = cost_sum / scene.random_episodes;  // exact for one rollout
  clock.Lap(&result.timing.real_episode_cpu, &result.timing.real_episode_wall);
  result.cpu_seconds = result.timing.total_cpu();
  return result;
}

// 3-5 of learned episode e: one real episode with the new policy (its data
// appended to `data`), the evaluation on independent real episodes, and
// after the last episode the rollout verdict of the final policy; their
// costs and times into `result`.
absl::Status RealEpisodeAndEvaluation(const TrialOptions& options, const tasks::Scene& scene,
                                      const tasks::MultiController& policy_controller,
                                      uint64_t seed, int e, PhaseClock& clock, Transitions& data,
                                      EpisodeResult& result) {
  absl::Status status;
  // 3. One real episode with the new policy; its data are added.
  {
    Rng start_rng(seed, Stream::kInitialState, e), noise_rng(seed, Stream::kObservationNoise, e);
    tasks::Episode episode;
    status = tasks::RunEpisode(scene, policy_controller, &start_rng, &noise_rng, &episode);
    if (!status.ok()) return absl::InternalError(absl::StrCat("episode ", e, ": ", status.message()));
    data.Append(episode);
    result.real_cost = episode.total_cost;
    result.trajectories.real = TrajectoryOfEpisode(episode);
  }
  clock.Lap(&result.timing.real_episode_cpu, &result.timing.real_episode_wall);

  // 4. Evaluate the policy on independent real episodes (not added to the data).
  {
    absl::StatusOr<PolicyEvaluation> evaluation =
        EvaluateController(scene, policy_controller, seed, e, options.eval_rollouts);
    if (!evaluation.ok())
      return absl::InternalError(absl::StrCat("episode ", e, " evaluation: ", evaluation.status().message()));
    result.eval_cost_mean = evaluation->mean;
    result.eval_cost_std = evaluation->std;
  }
  // 5. After the last episode, the rollout verdict of the final policy
  //    (its own evaluation streams: the first eval_rollouts rollouts are
  //    the evaluation above, so no number above depends on it).
  if (e == options.episodes && options.verdict_rollouts > 0) {
    std::vector<tasks::Episode> rollouts;
    absl::StatusOr<RolloutClassification> classification = ClassifyController(
        scene, policy_controller, seed, e, options.verdict_rollouts, options.verdict_distance,
        VerdictHoldSteps(options, scene), &rollouts);
    if (!classification.ok())
      return absl::InternalError(absl::StrCat("episode ", e, " rollout verdict: ",
                                              classification.status().message()));
    result.held_fraction = classification->held_fraction();
    result.trajectories.verdict_rollouts.reserve(rollouts.size());
    for (const tasks::Episode& rollout : rollouts)
      result.trajectories.verdict_rollouts.push_back(TrajectoryOfEpisode(rollout));
  }
  clock.Lap(&result.timing.evaluation_cpu, &result.timing.evaluation_wall);
  return absl::OkStatus();
}

// What a checkpoint and a snapshot after episode e both carry: the episode,
// the trial's options and the data so far.
template <typename TrialRecord>
void FillEpisodeData(int e, const TrialOptions& options, const Transitions& data,
                     TrialRecord* record) {
  record->episode = e;
  record->options = TrialOptionPairs(options);
  record->states = data.states;
  record->forces = data.forces;
  record->next_states = data.next_states;
}

}  // namespace

absl::StatusOr<TrialSummary> RunTrial(const TrialOptions& options, TrialObserver* observer,
                                      const RunOptions& run) {
  return RunTrial(options, observer, nullptr, run);
}

absl::StatusOr<TrialSummary> RunTrial(const TrialOptions& options, TrialObserver* observer,
                                      const TrialCheckpoint* resume_from, const RunOptions& run) {
  absl::Status status = options.Validate();
  if (!status.ok()) return status;
  if (run.threads < 1) return absl::InvalidArgumentError("threads must be >= 1");
  if (resume_from != nullptr) {
    status = CheckResumable(*resume_from, options);
    if (!status.ok()) return status;
  }
  std::unique_ptr<ThreadPool> pool;
  if (run.threads > 1) pool = std::make_unique<ThreadPool>(run.threads);
  // Results must not depend on how many threads the BLAS would use on this
  // machine (a multi-threaded gemm sums in another order): one thread.
  SetBlasThreads(1);
  absl::StatusOr<tasks::Scene> scene_or = tasks::MakeScene(options.scene);
  if (!scene_or.ok()) return scene_or.status();
  const tasks::Scene& scene = *scene_or;
  const uint64_t seed = options.seed;

  absl::StatusOr<std::unique_ptr<PolicyLearner>> made = MakePolicyLearner(options, scene, pool.get());
  if (!made.ok()) return made.status();
  const std::unique_ptr<PolicyLearner> learner = *std::move(made);
  const tasks::MultiController policy_controller = learner->Controller();

  Transitions data;
  TrialSummary summary;
  const bool checkpoints = observer != nullptr && observer->WantsCheckpoints();
  // After episode e: everything the next episode reads (checkpoint.h).
  const auto emit_checkpoint = [&](int e) {
    TrialCheckpoint c;
    FillEpisodeData(e, options, data, &c);
    c.episodes = summary.episodes;
    learner->SaveState(&c);
    observer->OnCheckpoint(c);
  };
  int first_episode = 1;
  if (resume_from != nullptr) {
    // Resume: the data, warm starts and results of episodes 0..k as they were.
    data.states = resume_from->states;
    data.forces = resume_from->forces;
    data.next_states = resume_from->next_states;
    status = learner->RestoreState(*resume_from);
    if (!status.ok()) return status;
    summary.episodes = resume_from->episodes;
    if (observer != nullptr)
      for (const EpisodeResult& result : summary.episodes) observer->OnEpisode(result);
    first_episode = resume_from->episode + 1;
  }

  // Episode 0: random exploration (unless resuming).
  if (resume_from == nullptr) {
    absl::StatusOr<EpisodeResult> random = RandomEpisode(scene, seed, pool.get(), data);
    if (!random.ok()) return random.status();
    const EpisodeResult& result = *random;
    summary.episodes.push_back(result);
    if (observer != nullptr) observer->OnEpisode(result);
    if (checkpoints) emit_checkpoint(0);
  }

  for (int e = first_episode; e <= options.episodes; ++e) {
    EpisodeResult result;
    result.episode = e;
    const auto start_time = std::chrono::steady_clock::now();
    PhaseClock clock(pool.get());
    // 1-2. Fit the model on all data so far and optimise the policy.
    const bool snapshot = observer != nullptr && observer->WantsSnapshot(e);
    const Vector policy_before = snapshot ? learner->Parameters() : Vector();
    status = learner->Improve(data, e, observer, &clock, &result);
    if (!status.ok()) return status;
    result.optimisation_seconds = Seconds(start_time);
    if (snapshot) {
      TrialSnapshot s;
      FillEpisodeData(e, options, data, &s);
      s.hyperparameters = result.hyperparameters;
      s.policy_parameters_before = policy_before;
      s.policy_parameters = result.policy_parameters;
      observer->OnSnapshot(s);
    }
    clock.Restart();  // the snapshot copy above is not the trial's work

    status = RealEpisodeAndEvaluation(options, scene, policy_controller, seed, e, clock, data,
                                      result);
    if (!status.ok()) return status;
    result.cpu_seconds = result.timing.total_cpu();
    summary.episodes.push_back(result);
    if (observer != nullptr) observer->OnEpisode(result);
    if (checkpoints) emit_checkpoint(e);
  }
  summary.final_eval_cost = summary.episodes.back().eval_cost_mean;
  summary.success = summary.final_eval_cost < options.success_threshold;
  return summary;
}

}  // namespace totalgrad::learner
