// GP dynamics model benchmarks (run with --benchmark_format=json).
//
// BM_Predict is the hot path of a policy-learning trial: P = 300 particles,
// E = 5 inputs, D = 4 outputs, N training points, with and without the input
// Jacobians. BM_GemmBound is the unavoidable part of it, the four
// (P x N) * (N x N) products, so BM_Predict / BM_GemmBound is the overhead of
// everything else. The BLAS runs on one thread, as in a worker slot.
#include <benchmark/benchmark.h>

#include <cmath>
#include <vector>

#include "core/common/blas.h"
#include "core/common/rng.h"
#include "core/common/types.h"
#include "core/gp/gp.h"
#include "core/gp/training.h"

namespace totalgrad::gp {
namespace {

constexpr int kParticles = 300;
constexpr int kInputs = 5;
constexpr int kOutputs = 4;

// Cart-pole-like data: smooth targets of 5 inputs plus noise.
void MakeData(int n, RowMatrix* inputs, RowMatrix* targets) {
  Rng rng(42, Stream::kStudy, static_cast<uint64_t>(n));
  inputs->resize(n, kInputs);
  rng.FillNormal(inputs);
  targets->resize(n, kOutputs);
  for (int i = 0; i < n; ++i) {
    const auto x = inputs->row(i);
    (*targets)(i, 0) = 0.1 * x(1) + 0.01 * rng.Normal();
    (*targets)(i, 1) = 0.3 * std::sin(x(3)) + 0.1 * x(4) + 0.01 * rng.Normal();
    (*targets)(i, 2) = 0.5 * std::sin(x(3)) * x(2) + 0.2 * x(4) + 0.01 * rng.Normal();
    (*targets)(i, 3) = 0.1 * x(2) + 0.01 * rng.Normal();
  }
}

GpHyperparameters BenchHyperparameters() {
  GpHyperparameters hyp;
  hyp.log_lengthscales = RowMatrix::Constant(kOutputs, kInputs, std::log(1.5));
  hyp.log_signal_std = Vector::Constant(kOutputs, std::log(0.5));
  hyp.log_noise_std = Vector::Constant(kOutputs, std::log(0.01));
  return hyp;
}

GpModel MakeModel(int n) {
  RowMatrix inputs, targets;
  MakeData(n, &inputs, &targets);
  absl::StatusOr<GpModel> model = GpModel::Create(inputs, targets, BenchHyperparameters());
  if (!model.ok()) std::abort();
  return *std::move(model);
}

RowMatrix MakeQueries() {
  Rng rng(7, Stream::kStudy);
  RowMatrix z(kParticles, kInputs);
  rng.FillNormal(&z);
  return z;
}

// Args: N, jacobians (0/1).
void BM_Predict(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const bool jacobians = state.range(1) != 0;
  const GpModel model = MakeModel(n);
  const RowMatrix z = MakeQueries();
  const PredictOptions options{25.0};
  RowMatrix mean, variance, dmean, dvar;
  for (auto _ : state) {
    model.Predict(z, options, &mean, &variance, jacobians ? &dmean : nullptr,
                  jacobians ? &dvar : nullptr);
    benchmark::DoNotOptimize(variance.data());
    benchmark::ClobberMemory();
  }
  state.counters["gemm_GFLOPs"] = benchmark::Counter(
      2.0 * kOutputs * kParticles * static_cast<double>(n) * n * 1e-9,
      benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_Predict)
    ->ArgsProduct({{30, 120, 240, 450}, {0, 1}})
    ->ArgNames({"N", "jac"})
    ->Unit(benchmark::kMicrosecond);

// Mean only (variance == nullptr): no N x N work at all.
void BM_PredictMeanOnly(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const GpModel model = MakeModel(n);
  const RowMatrix z = MakeQueries();
  RowMatrix mean;
  for (auto _ : state) {
    model.Predict(z, PredictOptions{}, &mean, nullptr, nullptr, nullptr);
    benchmark::DoNotOptimize(mean.data());
    benchmark::ClobberMemory();
  }
}
BENCHMARK(BM_PredictMeanOnly)->Arg(30)->Arg(120)->Arg(240)->Arg(450)->ArgName("N")->Unit(
    benchmark::kMicrosecond);

// The lower bound: the four (P x N) * (N x N) products alone, with the same
// storage orders as Predict.
void BM_GemmBound(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const Matrix kstar = Matrix::Random(kParticles, n);
  std::vector<Matrix> kinv;
  for (int a = 0; a < kOutputs; ++a) kinv.push_back(Matrix::Random(n, n));
  Matrix product(kParticles, n);
  for (auto _ : state) {
    for (int a = 0; a < kOutputs; ++a) {
      product.noalias() = kstar * kinv[a];
      benchmark::DoNotOptimize(product.data());
    }
    benchmark::ClobberMemory();
  }
  state.counters["gemm_GFLOPs"] = benchmark::Counter(
      2.0 * kOutputs * kParticles * static_cast<double>(n) * n * 1e-9,
      benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_GemmBound)->Arg(30)->Arg(120)->Arg(240)->Arg(450)->ArgName("N")->Unit(
    benchmark::kMicrosecond);

// One training-loss evaluation (value + gradient) of one output: the unit of
// TrainHyperparameters' cost.
void BM_PenalisedNlml(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  RowMatrix inputs, targets;
  MakeData(n, &inputs, &targets);
  const Vector target = targets.col(2);
  const Vector input_std = Vector::Ones(kInputs);
  const Vector packed = BenchHyperparameters().Packed(2);
  double value = 0;
  Vector gradient;
  for (auto _ : state) {
    if (!PenalisedNlml(inputs, target, input_std, packed, PenaltyOptions{}, &value, &gradient)) {
      state.SkipWithError("PenalisedNlml failed");
      break;
    }
    benchmark::DoNotOptimize(value);
  }
}
BENCHMARK(BM_PenalisedNlml)->Arg(120)->Arg(450)->ArgName("N")->Unit(benchmark::kMillisecond);

// Full training of the 4 outputs from PILCO's initialisation (cold start).
void BM_TrainHyperparameters(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  RowMatrix inputs, targets;
  MakeData(n, &inputs, &targets);
  int iterations = 0, evaluations_failed = 0;
  for (auto _ : state) {
    GpHyperparameters hyp = InitialHyperparameters(inputs, targets);
    absl::StatusOr<TrainingSummary> summary =
        TrainHyperparameters(inputs, targets, TrainingOptions{}, &hyp);
    if (!summary.ok()) {
      state.SkipWithError("training failed");
      break;
    }
    iterations = 0;
    for (int it : summary->iterations) iterations += it;
    evaluations_failed = summary->non_finite_evaluations;
  }
  state.counters["lbfgs_iterations"] = iterations;
  state.counters["non_finite"] = evaluations_failed;
}
BENCHMARK(BM_TrainHyperparameters)->Arg(450)->ArgName("N")->Iterations(1)->Unit(
    benchmark::kSecond);

}  // namespace
}  // namespace totalgrad::gp

int main(int argc, char** argv) {
  // One BLAS thread, as in a worker slot (core/common/blas.h).
  totalgrad::SetBlasThreads(1);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
