// `totalgrad bench iteration`: seconds per gradient iteration at a given size,
// and in the same run the seconds the unavoidable matrix products alone take
// (gemm_bound_seconds: per step and output one (P x N) * (N x N) product).
// With --gp-inducing M (< N) the rollout runs on a sparse GP (FITC, M
// inducing inputs: a random subset of the data, untrained, which does not
// change the cost) and the bound is the (P x M) * (M x M) products.
#include <time.h>

#include <algorithm>
#include <chrono>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"

#include "client/core_commands/bench_dump_command.h"
#include "client/core_commands/commands.h"
#include "core/common/blas.h"
#include "core/common/thread_pool.h"
#include "core/estimators/estimator.h"
#include "core/estimators/particle_system.h"
#include "core/estimators/synthetic_problem.h"
#include "core/gp/fitc.h"
#include "core/gp/training.h"
#include "core/learner/problem_builder.h"
#include "core/learner/trial_options.h"
#include "core/gaussian/angle_features.h"
#include "core/policy/rbf_policy.h"
#include "core/study/frozen_problem.h"
#include "core/tasks/scene.h"

namespace totalgrad::cli {
namespace {

struct BenchState {
  int particles = 300;
  int data = 450;
  int horizon = 30;
  int threads = 1;       // the trial's thread pool (RunOptions::threads)
  int blas_threads = 1;  // OpenBLAS's own threads inside each product
  int repeats = 7;
  int inducing = 0;  // 0 = full GP
  double variance_tolerance = 0;  // gp::GpModelOptions::variance_rank_tolerance
  std::string method = "RP";
  std::string scene;  // empty: the synthetic cart-pole problem
};

// A frozen problem on a scene of the catalog, for timing an iteration there:
// the study's synthetic scene problem (study::MakeSceneSyntheticProblem: N
// random transitions of the scene's plant, the GP on the scene's features
// with PILCO's initial hyperparameters, a random RBF policy), seed 1.
struct SceneBenchProblem {
  tasks::Scene scene;
  study::SceneSyntheticProblem built;
};

absl::StatusOr<std::unique_ptr<SceneBenchProblem>> MakeSceneBenchProblem(const std::string& name,
                                                                         int data, int horizon,
                                                                         double variance_tolerance,
                                                                         ThreadPool* pool) {
  tasks::SceneOptions options;
  options.scene = name;
  options.horizon = horizon;
  absl::StatusOr<tasks::Scene> scene = tasks::MakeScene(options);
  if (!scene.ok()) return scene.status();
  auto out = std::make_unique<SceneBenchProblem>();
  out->scene = *std::move(scene);
  study::SceneSyntheticOptions synthetic;
  synthetic.data = data;
  synthetic.horizon = horizon;
  synthetic.basis_functions = learner::TrialOptions{}.basis_functions;
  synthetic.variance_rank_tolerance = variance_tolerance;
  absl::StatusOr<study::SceneSyntheticProblem> built =
      study::MakeSceneSyntheticProblem(out->scene, synthetic, pool);
  if (!built.ok()) return built.status();
  out->built = *std::move(built);
  return out;
}


struct Timing {
  double wall = 0;
  double cpu = 0;  // this thread's CPU time: robust on a shared, loaded machine
};

// With one BLAS thread every flop runs on the calling thread, so its CPU time
// is the cost of the work whatever else the machine is doing.
// With a pool, its worker threads' CPU time counts too.
template <typename F>
Timing TimeOnce(const ThreadPool* pool, F&& f) {
  auto cpu = [pool] { return ThreadCpuSeconds() + (pool != nullptr ? pool->WorkerCpuSeconds() : 0.0); };
  const auto start = std::chrono::steady_clock::now();
  const double cpu_start = cpu();
  f();
  return {std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
          cpu() - cpu_start};
}

// The problem an iteration is timed on, and the objects its pointers (model,
// policy, dynamics) refer to.
struct IterationProblem {
  estimators::Problem p;
  const gp::GpModel* full_model = nullptr;
  std::unique_ptr<estimators::SyntheticProblem> synthetic;
  std::unique_ptr<SceneBenchProblem> on_scene;
  std::unique_ptr<estimators::GpDynamics> full_dynamics;
  std::unique_ptr<estimators::RbfParticlePolicy> particle_policy;
  std::unique_ptr<gp::FitcModel> sparse;
  std::unique_ptr<estimators::FitcDynamics> sparse_dynamics;
};

// The synthetic cart-pole problem, or one on --scene, its model and policy
// using `pool` as a trial's do. Returns the exit code: 0, or 1/2 after a
// message on stderr.
int MakeIterationProblem(const BenchState& state, ThreadPool* pool, IterationProblem* out) {
  estimators::Problem& p = out->p;
  const gp::GpModel*& full_model = out->full_model;
  std::unique_ptr<estimators::SyntheticProblem>& synthetic = out->synthetic;
  std::unique_ptr<SceneBenchProblem>& on_scene = out->on_scene;
  std::unique_ptr<estimators::GpDynamics>& full_dynamics = out->full_dynamics;
  std::unique_ptr<estimators::RbfParticlePolicy>& particle_policy = out->particle_policy;
  if (state.scene.empty()) {
    estimators::SyntheticProblemOptions options;
    options.data = state.data;
    options.horizon = state.horizon;
    options.variance_rank_tolerance = state.variance_tolerance;
    auto problem = estimators::MakeSyntheticProblem(options);
    if (!problem.ok()) {
      std::cerr << "totalgrad bench: " << problem.status().message() << "\n";
      return 1;
    }
    synthetic = *std::move(problem);
    full_model = synthetic->model.get();
    // The synthetic problem's model and policy behind adapters that use the
    // iteration's thread pool, as a trial's ModelProblem gives them its pool.
    full_dynamics = std::make_unique<estimators::GpDynamics>(full_model, pool);
    particle_policy = std::make_unique<estimators::RbfParticlePolicy>(synthetic->policy.get(), pool);
    p = synthetic->problem;
    p.dynamics = full_dynamics.get();
    p.policy = particle_policy.get();
    p.pool = pool;
  } else {
    auto problem = MakeSceneBenchProblem(state.scene, state.data, state.horizon,
                                         state.variance_tolerance, pool);
    if (!problem.ok()) {
      std::cerr << "totalgrad bench: " << problem.status().message() << "\n";
      return 2;
    }
    on_scene = *std::move(problem);
    full_model = on_scene->built.model->full_model();
    p = on_scene->built.model->problem();
  }
  return 0;
}

// --gp-inducing M: the rollout runs on a sparse GP (FITC) on M random
// inputs of the full model. Returns the exit code: 0, or 1/2 after a message.
int UseSparseGp(const BenchState& state, ThreadPool* pool, IterationProblem* out) {
  estimators::Problem& p = out->p;
  std::unique_ptr<gp::FitcModel>& sparse = out->sparse;
  std::unique_ptr<estimators::FitcDynamics>& sparse_dynamics = out->sparse_dynamics;
  const bool on_scene = out->on_scene != nullptr;
  const gp::GpModel* full_model = out->full_model;
  if (state.inducing > 0) {
    if (on_scene) {
      std::cerr << "totalgrad bench: --gp-inducing with --scene is not supported yet\n";
      return 2;
    }
    const gp::GpModel& full = *full_model;
    Rng inducing_rng(1, Stream::kGpInit);
    absl::StatusOr<gp::FitcModel> fitc = gp::FitcModel::Create(
        full.inputs(), full.targets(), full.hyperparameters(),
        gp::RandomSubsetOfInputs(full.inputs(), state.inducing, &inducing_rng));
    if (!fitc.ok()) {
      std::cerr << "totalgrad bench: " << fitc.status().message() << "\n";
      return 1;
    }
    sparse = std::make_unique<gp::FitcModel>(*std::move(fitc));
    sparse_dynamics = std::make_unique<estimators::FitcDynamics>(sparse.get(), pool);
    p.dynamics = sparse_dynamics.get();
  }
  return 0;
}

// `bench iteration`: times the iteration and the gemm bound in alternation
// and prints the JSON. Returns the exit code.
int RunBenchIteration(const BenchState& state) {
  SetBlasThreads(state.blas_threads);
  std::unique_ptr<ThreadPool> pool;
  if (state.threads > 1) pool = std::make_unique<ThreadPool>(state.threads);
  IterationProblem problem;
  if (const int code = MakeIterationProblem(state, pool.get(), &problem); code != 0) return code;
  estimators::Problem& p = problem.p;
  const gp::GpModel* full_model = problem.full_model;
  absl::StatusOr<estimators::Method> method = estimators::ParseMethod(state.method);
  absl::StatusOr<std::unique_ptr<estimators::Estimator>> estimator =
      method.ok() ? estimators::MakeEstimator(*method, {}) : method.status();
  if (!estimator.ok()) {
    std::cerr << "totalgrad bench: " << estimator.status().message() << "\n";
    return 2;
  }
  if (state.inducing >= state.data) {
    std::cerr << "totalgrad bench: --gp-inducing must be < --data (FITC is used once N > M)\n";
    return 2;
  }
  if (const int code = UseSparseGp(state, pool.get(), &problem); code != 0) return code;
  const std::unique_ptr<gp::FitcModel>& sparse = problem.sparse;
  estimators::EstimateOptions eo;
  eo.particles = state.particles;
  estimators::GradientEstimate estimate;
  // The bound: horizon x outputs products of (P x N) by (N x N), as Predict
  // does (with FITC: (P x M) by (M x M)).
  const gp::GpModel& full = *full_model;
  const int n = full.num_data(), outputs = full.num_outputs();
  const int support = sparse ? sparse->num_inducing() : n;
  // One P x N operand and the N x N weights per output, as Predict reads
  // them: the D weight matrices together exceed the L2 cache, so reusing
  // one of them would time a cache-hot product that Predict never runs.
  std::vector<Matrix> kstar, kinv;
  for (int a = 0; a < outputs; ++a) {
    kstar.push_back(Matrix::Random(state.particles, support));
    kinv.push_back(sparse ? sparse->variance_weights(a) : full.k_inverse(a));
  }
  Matrix product(state.particles, support);
  // Iteration and bound are timed in alternation, one of each per repeat,
  // so that a load change on a shared machine hits both; the ratio of each
  // pair and the ratio of the minima are the numbers robust to it.
  std::vector<double> iteration_times, iteration_cpu, gemm_times, gemm_cpu, paired_ratio;
  for (int r = 0; r < state.repeats + 1; ++r) {
    Rng rng(1, Stream::kStudy, 100 + r);
    const Timing it_time = TimeOnce(pool.get(), [&] {
      absl::Status st = (*estimator)->Estimate(p, eo, &rng, &estimate);
      (void)st;
    });
    const Timing gemm_time = TimeOnce(nullptr, [&] {
      for (int t = 0; t < state.horizon; ++t) {
        for (int a = 0; a < outputs; ++a) product.noalias() = kstar[a] * kinv[a];
      }
    });
    if (r == 0) continue;  // the first round warms caches and allocations
    iteration_times.push_back(it_time.wall);
    iteration_cpu.push_back(it_time.cpu);
    gemm_times.push_back(gemm_time.wall);
    gemm_cpu.push_back(gemm_time.cpu);
    paired_ratio.push_back(it_time.cpu / gemm_time.cpu);
  }
  const double iteration = BenchMedian(iteration_times), bound = BenchMedian(gemm_times);
  const double iteration_cpu_s = BenchMedian(iteration_cpu), bound_cpu = BenchMedian(gemm_cpu);
  const double min_iteration_cpu = *std::min_element(iteration_cpu.begin(), iteration_cpu.end());
  const double min_bound_cpu = *std::min_element(gemm_cpu.begin(), gemm_cpu.end());
  std::vector<int> ranks, bound_ranks;
  for (int a = 0; a < outputs; ++a) {
    ranks.push_back(full.rank(a));
    bound_ranks.push_back(full.bound_rank(a));
  }
  nlohmann::json j = {{"method", state.method},
                      {"scene", state.scene.empty() ? std::string("synthetic cart-pole") : state.scene},
                      {"gp_inputs", full.num_inputs()},
                      {"particles", state.particles},
                      {"data", n},
                      {"gp_inducing", state.inducing},
                      {"gp_variance_tolerance", state.variance_tolerance},
                      {"variance_ranks", ranks},
                      {"variance_bound_ranks", bound_ranks},
                      {"horizon", state.horizon},
                      {"threads", state.threads},
                      {"blas_threads", state.blas_threads},
                      {"repeats", state.repeats},
                      {"seconds_per_iteration", iteration},
                      {"gemm_bound_seconds", bound},
                      {"ratio", iteration / bound},
                      {"cpu_seconds_per_iteration", iteration_cpu_s},
                      {"gemm_bound_cpu_seconds", bound_cpu},
                      {"cpu_ratio", iteration_cpu_s / bound_cpu},
                      {"paired_cpu_ratio_median", BenchMedian(paired_ratio)},
                      {"min_cpu_seconds_per_iteration", min_iteration_cpu},
                      {"min_gemm_bound_cpu_seconds", min_bound_cpu},
                      {"min_cpu_ratio", min_iteration_cpu / min_bound_cpu},
                      {"blas", BlasConfig()},
                      {"gradient_finite", estimate.finite}};
  std::cout << j.dump(2) << std::endl;
  return 0;
}

}  // namespace

void AddBenchCommand(CLI::App* app, int* exit_code) {
  auto state = std::make_shared<BenchState>();
  CLI::App* bench = app->add_subcommand("bench", "Performance measurements (JSON output)");
  bench->require_subcommand(1);
  AddBenchTrialCommand(bench, exit_code);
  AddBenchEstimateCommand(bench, exit_code);
  AddBenchGradientsCommand(bench, exit_code);
  AddBenchDumpIterationCommand(bench, exit_code);
  CLI::App* it = bench->add_subcommand("iteration", "Seconds per gradient iteration vs the gemm bound");
  it->add_option("--particles", state->particles, "P")->check(CLI::PositiveNumber);
  it->add_option("--data", state->data, "N, GP training points")->check(CLI::Range(2, 100000));
  it->add_option("--horizon", state->horizon, "H, steps")->check(CLI::PositiveNumber);
  it->add_option("--threads", state->threads,
                 "threads of the iteration, as a trial's --threads uses them (default 1)")
      ->check(CLI::PositiveNumber);
  it->add_option("--blas-threads", state->blas_threads,
                 "OpenBLAS threads inside each product (default 1; trials always use 1)")
      ->check(CLI::PositiveNumber);
  it->add_option("--repeats", state->repeats, "timed repetitions (median reported)")->check(CLI::PositiveNumber);
  it->add_option("--method", state->method, "estimator");
  it->add_option("--scene", state->scene,
                 "time the iteration on this scene (`totalgrad scenes`; a GP on N random "
                 "transitions of its plant, its features) instead of the synthetic cart-pole problem");
  it->add_option("--gp-inducing", state->inducing,
                 "sparse GP (FITC) with M < N inducing inputs (0 = full GP)")
      ->check(CLI::NonNegativeNumber);
  it->add_option("--gp-variance-tolerance", state->variance_tolerance,
                 "the full GP's low-rank predictive variance with this bound on its relative "
                 "error (the trial option gp_variance_tolerance; 0 = exact, default)");
  it->callback([state, exit_code]() { *exit_code = RunBenchIteration(*state); });
}

}  // namespace totalgrad::cli
