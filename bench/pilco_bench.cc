// Seconds per PILCO objective evaluation, J alone and J + dJ/dtheta, on
// cart-pole data (PILCO's setting: sin/cos inputs, tip cost, 10 RBF centres),
// for N training points with the full GP and with FITC (M inducing inputs).
//
//   pilco_bench --benchmark_format=json
//
// Arguments: {N, M (0 = full GP), horizon, centres}. One thread (BLAS too).
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>

#include "core/common/blas.h"
#include "core/common/rng.h"
#include "core/gp/fitc.h"
#include "core/gaussian/angle_features.h"
#include "core/pilco/pilco.h"
#include "core/tasks/cartpole.h"

namespace totalgrad::pilco {
namespace {

struct Setup {
  GaussianInputGp model;
  PilcoProblem problem;
  Vector params;
};

Setup MakeSetup(int n, int m, int horizon, int centres) {
  SetBlasThreads(1);
  std::mt19937_64 gen(1);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> uniform(-10, 10);
  const tasks::CartPole plant;
  RowMatrix states(n, 4), y(n, 4);
  Vector u(n);
  for (int i = 0; i < n; ++i) {
    tasks::State s(0.5 * normal(gen), 2.0 * normal(gen), normal(gen), 3.0 * normal(gen));
    u(i) = uniform(gen);
    tasks::State next;
    if (!plant.Step(s, u(i), &next).ok()) std::abort();
    states.row(i) = s.transpose();
    y.row(i) = (next - s).transpose();
  }
  RowMatrix features;
  gaussian::StatesToFeatures(states, 1, &features);
  RowMatrix x(n, 6);
  x << features, u;
  gp::GpHyperparameters hyp;
  hyp.log_lengthscales.resize(4, 6);
  hyp.log_signal_std.resize(4);
  hyp.log_noise_std.resize(4);
  RowMatrix log_hyp(4, 8);
  for (int a = 0; a < 4; ++a) {
    for (int j = 0; j < 6; ++j) {
      const double mean = x.col(j).mean();
      hyp.log_lengthscales(a, j) =
          std::log(std::sqrt((x.col(j).array() - mean).square().sum() / (n - 1)));
    }
    const double mean = y.col(a).mean();
    const double sd = std::sqrt((y.col(a).array() - mean).square().sum() / (n - 1));
    hyp.log_signal_std(a) = std::log(sd);
    hyp.log_noise_std(a) = std::log(sd / 10);
    log_hyp.row(a) << hyp.log_lengthscales.row(a), hyp.log_signal_std(a), hyp.log_noise_std(a);
  }
  Setup setup;
  if (m > 0) {
    Rng rng(2, Stream::kGpInit);
    auto fitc = gp::FitcModel::Create(x, y, hyp, gp::RandomSubsetOfInputs(x, m, &rng));
    if (!fitc.ok()) std::abort();
    setup.model = GaussianInputGpFromFitc(*fitc);
  } else {
    auto full = GaussianInputGpFromData(x, y, log_hyp);
    if (!full.ok()) std::abort();
    setup.model = *full;
  }
  setup.problem.mu0 = Vector::Zero(4);
  setup.problem.S0 = 0.01 * Matrix::Identity(4, 4);
  setup.problem.horizon = horizon;
  setup.problem.cost = std::make_shared<gaussian::GaussianCost>(*gaussian::GaussianCost::Tip(4, 0, 1, 0.5, 0.25));
  setup.problem.propagation.angle_index = 1;
  setup.problem.propagation.num_basis = centres;
  Rng rng(3, Stream::kPolicyInit);
  auto params = InitialPolicyParameters(setup.problem, &rng);
  if (!params.ok()) std::abort();
  setup.params = *params;
  return setup;
}

void BM_PilcoJ(benchmark::State& state) {
  const Setup s = MakeSetup(state.range(0), state.range(1), state.range(2), state.range(3));
  for (auto _ : state) {
    auto tr = Propagate(s.model, s.problem, s.params, nullptr);
    benchmark::DoNotOptimize(tr);
  }
}

void BM_PilcoJAndGradient(benchmark::State& state) {
  const Setup s = MakeSetup(state.range(0), state.range(1), state.range(2), state.range(3));
  Vector grad;
  for (auto _ : state) {
    auto tr = Propagate(s.model, s.problem, s.params, &grad);
    benchmark::DoNotOptimize(tr);
    benchmark::DoNotOptimize(grad.data());
  }
}

// One FITC NLML + gradient (inducing-input training step) at {N, M}.
void BM_FitcNlmlAndGradient(benchmark::State& state) {
  SetBlasThreads(1);
  const int n = state.range(0), m = state.range(1);
  std::mt19937_64 gen(4);
  std::normal_distribution<double> normal;
  RowMatrix x(n, 6), y(n, 4);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < 6; ++j) x(i, j) = normal(gen);
    for (int a = 0; a < 4; ++a) y(i, a) = std::sin(x(i, a)) + 0.1 * normal(gen);
  }
  gp::GpHyperparameters hyp;
  hyp.log_lengthscales = RowMatrix::Zero(4, 6);
  hyp.log_signal_std = Vector::Zero(4);
  hyp.log_noise_std = Vector::Constant(4, std::log(0.1));
  Rng rng(5, Stream::kGpInit);
  const RowMatrix z = gp::RandomSubsetOfInputs(x, m, &rng);
  double value;
  RowMatrix grad;
  for (auto _ : state) {
    if (!gp::FitcNlml(x, y, hyp, z, &value, &grad)) std::abort();
    benchmark::DoNotOptimize(value);
  }
}
BENCHMARK(BM_FitcNlmlAndGradient)->Args({450, 300})->Unit(benchmark::kMillisecond)->UseRealTime();

// {N, M, H, C}: the measurement (N = 450, H = 30) with the full GP
// and FITC with M = 300; PILCO's policy size C = 10 and the paper's C = 50.
#define PILCO_ARGS                                                                     \
  Args({450, 0, 30, 10})->Args({450, 300, 30, 10})->Args({450, 0, 30, 50})->Args(      \
      {450, 300, 30, 50})->Args({150, 0, 30, 10})->Unit(benchmark::kMillisecond)->UseRealTime()

BENCHMARK(BM_PilcoJ)->PILCO_ARGS;
BENCHMARK(BM_PilcoJAndGradient)->PILCO_ARGS;

}  // namespace
}  // namespace totalgrad::pilco

BENCHMARK_MAIN();
