// `totalgrad bench gradients`: R gradient estimates of one method on a trial
// snapshot's problem, with fixed random-number streams (replicate r draws from
// Stream::kStudy, index 1000 + r), written as JSON. Two runs of it that differ
// only in how the numbers are computed (BLAS kernels, a build, an
// approximation) use common random numbers, so bench/accuracy_gate.py can
// measure the computation's error against the estimator's own Monte Carlo
// error (docs/results/speed.md, "accuracy gate").
#include <algorithm>
#include <fstream>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "client/core_commands/commands.h"
#include "core/common/blas.h"
#include "core/common/thread_pool.h"
#include "core/estimators/estimator.h"
#include "core/learner/trial_options.h"
#include "core/study/frozen_problem.h"
#include "io/snapshot_json.h"

namespace totalgrad::cli {
namespace {

struct BenchGradientsState {
  std::string snapshot_file;
  int episode = 0;
  std::string policy = "before";
  std::string method = "RP";
  int particles = 300;
  int horizon = 0;  // 0 = the snapshot's
  int replicates = 20;
  uint64_t seed = 1;
  int threads = 1;
  std::string variance_tolerance;  // empty: the snapshot's gp_variance_tolerance
  std::string out;
};

constexpr uint64_t kReplicateStreamOffset = 1000;

}  // namespace

void AddBenchGradientsCommand(CLI::App* bench, int* exit_code) {
  auto state = std::make_shared<BenchGradientsState>();
  CLI::App* cmd = bench->add_subcommand(
      "gradients", "R gradient estimates on a trial snapshot with fixed random numbers (JSON)");
  cmd->add_option("--snapshot", state->snapshot_file, "trial snapshot file")->required();
  cmd->add_option("--episode", state->episode, "snapshot episode")->required();
  cmd->add_option("--policy", state->policy, "before or after the episode's optimisation")
      ->check(CLI::IsMember({"before", "after"}));
  cmd->add_option("--method", state->method, "particle estimator (RP, GR, LR, TP, GLR, GTP, GTP+sn, DEL)");
  cmd->add_option("--particles", state->particles, "P (default 300)")->check(CLI::Range(1, 1000000));
  cmd->add_option("--horizon", state->horizon, "H (default: the snapshot's)")->check(CLI::Range(0, 100000));
  cmd->add_option("--replicates", state->replicates, "R (default 20)")->check(CLI::Range(1, 100000));
  cmd->add_option("--seed", state->seed, "random-number seed of the replicates (default 1)");
  cmd->add_option("--threads", state->threads, "threads (default 1)")->check(CLI::Range(1, 256));
  cmd->add_option("--gp-variance-tolerance", state->variance_tolerance,
                  "rebuild the snapshot's GP with this trial option gp_variance_tolerance (low-rank "
                  "predictive variance; 0 = exact; default: the snapshot's own)");
  cmd->add_option("--out", state->out, "write the JSON here instead of stdout");
  cmd->callback([state, exit_code]() {
    auto fail = [exit_code](int code, const std::string& message) {
      std::cerr << "totalgrad bench gradients: " << message << "\n";
      *exit_code = code;
    };
    absl::StatusOr<std::vector<learner::TrialSnapshot>> snapshots =
        io::ReadSnapshotFile(state->snapshot_file);
    if (!snapshots.ok()) return fail(2, std::string(snapshots.status().message()));
    learner::TrialSnapshot* snapshot = nullptr;
    for (auto& s : *snapshots)
      if (s.episode == state->episode) snapshot = &s;
    if (snapshot == nullptr)
      return fail(2, "no snapshot of episode " + std::to_string(state->episode) + " in " +
                         state->snapshot_file);
    if (!state->variance_tolerance.empty()) {
      // A later pair overrides an earlier one of the same key; the option's
      // range is checked like a trial's.
      snapshot->options.emplace_back("gp_variance_tolerance", state->variance_tolerance);
      absl::StatusOr<learner::TrialOptions> parsed = learner::TrialOptionsFromStoredPairs(snapshot->options);
      if (!parsed.ok()) return fail(2, std::string(parsed.status().message()));
      if (absl::Status valid = parsed->Validate(); !valid.ok()) return fail(2, std::string(valid.message()));
    }
    absl::StatusOr<std::unique_ptr<study::FrozenProblem>> frozen = study::FrozenProblemFromSnapshot(
        *snapshot, state->policy == "after" ? study::SnapshotPolicy::kAfter
                                            : study::SnapshotPolicy::kBefore);
    if (!frozen.ok()) return fail(2, std::string(frozen.status().message()));
    if (!(*frozen)->angle_indices.empty()) {
      // The adapters below wrap the raw-state GP and policy only.
      return fail(2, "the snapshot's model and policy are on (sin, cos) angle features; bench "
                     "gradients takes raw-state snapshots (`totalgrad study` takes both)");
    }
    absl::StatusOr<estimators::Method> method = estimators::ParseMethod(state->method);
    if (!method.ok()) return fail(2, std::string(method.status().message()));
    absl::StatusOr<std::unique_ptr<estimators::Estimator>> estimator =
        estimators::MakeEstimator(*method, {});
    if (!estimator.ok()) return fail(2, std::string(estimator.status().message()));
    SetBlasThreads(1);
    std::unique_ptr<ThreadPool> pool;
    if (state->threads > 1) pool = std::make_unique<ThreadPool>(state->threads);
    // The snapshot's model (a full GP on the raw state) and policy behind
    // adapters that use this command's thread pool.
    estimators::GpDynamics dynamics((*frozen)->model, pool.get());
    estimators::RbfParticlePolicy particle_policy((*frozen)->policy, pool.get());
    estimators::Problem problem = (*frozen)->problem;
    problem.dynamics = &dynamics;
    problem.policy = &particle_policy;
    problem.pool = pool.get();
    if (state->horizon > 0) problem.horizon = state->horizon;
    estimators::EstimateOptions options;
    options.particles = state->particles;
    nlohmann::json gradients = nlohmann::json::array(), objectives = nlohmann::json::array();
    int non_finite = 0;
    // This thread's CPU seconds per estimate (plus the pool's), for timing
    // an iteration on a snapshot's problem; the first replicate warms up.
    std::vector<double> cpu_seconds;
    for (int r = 0; r < state->replicates; ++r) {
      Rng rng(state->seed, Stream::kStudy, kReplicateStreamOffset + static_cast<uint64_t>(r));
      estimators::GradientEstimate estimate;
      const double cpu_start = ThreadCpuSeconds() + (pool ? pool->WorkerCpuSeconds() : 0.0);
      const absl::Status st = (*estimator)->Estimate(problem, options, &rng, &estimate);
      const double cpu_end = ThreadCpuSeconds() + (pool ? pool->WorkerCpuSeconds() : 0.0);
      if (r > 0 || state->replicates == 1) cpu_seconds.push_back(cpu_end - cpu_start);
      if (!st.ok()) return fail(1, "replicate " + std::to_string(r) + ": " + std::string(st.message()));
      if (!estimate.finite) ++non_finite;
      gradients.push_back(std::vector<double>(estimate.gradient.data(),
                                              estimate.gradient.data() + estimate.gradient.size()));
      objectives.push_back(estimate.objective);
    }
    std::vector<int> ranks, bound_ranks;
    for (int a = 0; a < (*frozen)->model->num_outputs(); ++a) {
      ranks.push_back((*frozen)->model->rank(a));
      bound_ranks.push_back((*frozen)->model->bound_rank(a));
    }
    nlohmann::json doc = {{"snapshot", state->snapshot_file},
                          {"episode", state->episode},
                          {"policy", state->policy},
                          {"source", (*frozen)->source},
                          {"method", state->method},
                          {"particles", state->particles},
                          {"horizon", problem.horizon},
                          {"replicates", state->replicates},
                          {"seed", state->seed},
                          {"threads", state->threads},
                          {"gp_variance_tolerance", (*frozen)->model->options().variance_rank_tolerance},
                          {"variance_ranks", ranks},
                          {"variance_bound_ranks", bound_ranks},
                          {"cpu_seconds_per_estimate_median", BenchMedian(cpu_seconds)},
                          {"gp_data", (*frozen)->model->num_data()},
                          {"non_finite", non_finite},
                          {"blas", BlasConfig()},
                          {"objectives", objectives},
                          {"gradients", gradients}};
    if (state->out.empty()) {
      std::cout << doc.dump() << std::endl;
    } else {
      std::ofstream file(state->out);
      file << doc.dump() << "\n";
      if (!file) return fail(1, "cannot write " + state->out);
    }
    *exit_code = 0;
  });
}

}  // namespace totalgrad::cli
