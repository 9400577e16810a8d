// The curse-of-chaos study (PIPPS; docs/results/estimators.md): at a fixed
// model and policy, the variance of the RP, LR and TP gradient estimates over
// the horizon.
//
// Model: a GP fitted (hyperparameters trained) to N one-step transitions of
// the real cart-pole from random states and forces (SyntheticProblem). Policy:
// the RBF policy after `policy_steps` steps of the paper's optimiser with RP
// gradients on that model (horizon 30), so that the particles swing towards
// the unstable upright state where the dynamics are chaotic. Then, per
// horizon H, R independent replicates of one forward pass of P particles each;
// the three backward passes run on the same rollout (common random numbers).
//
// Output, one JSON object per (H, method) on stdout:
//   total_variance   trace of the sample covariance of the R estimates
//   mean_norm        |mean of the R estimates|
//   particle_variance trace(per-particle sample variance) / P averaged over
//                    replicates (the variance the optimiser sees, per estimate)
//   non_finite       replicates with a non-finite estimate (excluded)
//   mean_k_lr        TP only: k_LR averaged over steps and replicates
//   backward_seconds mean wall time of the backward pass
// Not a google/benchmark program: it has its own main.
//
// Usage: gradient_variance_bench [--horizons 10,30,60,100] [--particles 300]
//   [--replicates 30] [--data 450] [--train-iterations 30] [--policy-steps 200]
//   [--policy-particles 100] [--cost angle] [--scene cartpole-swingup] [--seed 1]
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <string>
#include <vector>

#include "core/common/blas.h"
#include "core/estimators/estimator.h"
#include "core/estimators/synthetic_problem.h"
#include "core/estimators/total_propagation.h"
#include "core/learner/optimizer.h"

namespace totalgrad {
namespace {

struct Args {
  std::vector<int> horizons = {10, 30, 60, 100};
  int particles = 300;
  int replicates = 30;
  int data = 450;
  int train_iterations = 30;
  int policy_steps = 200;
  int policy_particles = 100;
  std::string cost = "angle";
  std::string scene = "cartpole-swingup";
  uint64_t seed = 1;
};

bool Parse(int argc, char** argv, Args* a) {
  for (int i = 1; i < argc; ++i) {
    const std::string key = argv[i];
    if (i + 1 >= argc) return false;
    const std::string v = argv[++i];
    if (key == "--horizons") {
      a->horizons.clear();
      std::stringstream ss(v);
      std::string item;
      while (std::getline(ss, item, ',')) a->horizons.push_back(std::atoi(item.c_str()));
    } else if (key == "--particles") a->particles = std::atoi(v.c_str());
    else if (key == "--replicates") a->replicates = std::atoi(v.c_str());
    else if (key == "--data") a->data = std::atoi(v.c_str());
    else if (key == "--train-iterations") a->train_iterations = std::atoi(v.c_str());
    else if (key == "--policy-steps") a->policy_steps = std::atoi(v.c_str());
    else if (key == "--policy-particles") a->policy_particles = std::atoi(v.c_str());
    else if (key == "--cost") a->cost = v;
    else if (key == "--scene") a->scene = v;
    else if (key == "--seed") a->seed = std::strtoull(v.c_str(), nullptr, 10);
    else return false;
  }
  return a->particles > 1 && a->replicates > 1 && !a->horizons.empty();
}

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

int Run(const Args& args) {
  SetBlasThreads(1);
  estimators::SyntheticProblemOptions po;
  po.data = args.data;
  po.horizon = 30;
  po.cost = args.cost;
  po.scene = args.scene;
  po.seed = args.seed;
  po.train_iterations = args.train_iterations;
  auto sp = estimators::MakeSyntheticProblem(po);
  if (!sp.ok()) {
    std::fprintf(stderr, "gradient_variance_bench: %s\n", std::string(sp.status().message()).c_str());
    return 1;
  }
  estimators::Problem problem = (*sp)->problem;
  policy::RbfPolicy& policy = *(*sp)->policy;

  // The policy: the paper's optimiser with RP gradients on the model.
  {
    auto rp = estimators::MakeEstimator(estimators::Method::kRp, {});
    learner::RmspropLike optimiser(learner::OptimizerOptions{}, policy.num_parameters());
    estimators::EstimateOptions eo;
    eo.particles = args.policy_particles;
    estimators::GradientEstimate e;
    Vector theta = policy.parameters();
    for (int step = 0; step < args.policy_steps; ++step) {
      Rng rng(args.seed, Stream::kParticleNoise, step);
      if (!(*rp)->Estimate(problem, eo, &rng, &e).ok() || !e.finite) continue;
      optimiser.Step(e.gradient, e.per_particle_variance, args.policy_particles, &theta);
      policy.set_parameters(theta);
      if (step % 50 == 0 || step + 1 == args.policy_steps)
        std::fprintf(stderr, "policy step %d: J(H=30) = %.4f\n", step, e.objective);
    }
  }

  struct Method {
    const char* name;
    estimators::BackwardConfig config;
  };
  std::vector<Method> methods(3);
  methods[0] = {"RP", {}};
  methods[1] = {"LR", {}};
  methods[1].config.pathwise = false;
  methods[1].config.jump = estimators::JumpKind::kLikelihoodRatio;
  methods[2] = {"TP", {}};
  methods[2].config.jump = estimators::JumpKind::kLikelihoodRatio;

  const int n = policy.num_parameters();
  for (int horizon : args.horizons) {
    problem.horizon = horizon;
    std::vector<Vector> sum(3, Vector::Zero(n)), sum_sq(3, Vector::Zero(n));
    std::vector<double> particle_var(3, 0.0), seconds(3, 0.0), k_sum(3, 0.0);
    std::vector<int> count(3, 0), non_finite(3, 0), k_count(3, 0);
    double objective = 0;
    estimators::Rollout rollout;
    estimators::RolloutRecording rec;
    rec.jacobians = true;
    for (int r = 0; r < args.replicates; ++r) {
      Rng rng(args.seed, Stream::kStudy, 1000000ULL * horizon + r);
      if (!estimators::SimulateParticles(problem, args.particles, rec, &rng, &rollout).ok()) return 1;
      objective += rollout.objective;
      for (int m = 0; m < 3; ++m) {
        estimators::BackwardResult result;
        const auto start = std::chrono::steady_clock::now();
        if (!estimators::BackwardPass(problem, rollout, methods[m].config, &rng, &result).ok()) return 1;
        seconds[m] += Seconds(start);
        const RowMatrix per_particle = result.per_particle * static_cast<double>(args.particles);
        const Vector v = estimators::ColumnSampleVariance(per_particle);
        if (!rollout.finite || !result.gradient.allFinite() || !v.allFinite()) {
          ++non_finite[m];
          continue;
        }
        ++count[m];
        sum[m] += result.gradient;
        sum_sq[m] += result.gradient.cwiseAbs2();
        particle_var[m] += v.sum() / args.particles;
        for (double k : result.k_lr) k_sum[m] += k, ++k_count[m];
      }
    }
    for (int m = 0; m < 3; ++m) {
      const double c = count[m];
      const Vector mean = c > 0 ? Vector(sum[m] / c) : Vector::Zero(n);
      const double total_var =
          c > 1 ? ((sum_sq[m] - c * mean.cwiseAbs2()) / (c - 1)).cwiseMax(0.0).sum() : NAN;
      std::printf(
          "{\"horizon\": %d, \"method\": \"%s\", \"particles\": %d, \"replicates\": %d, "
          "\"total_variance\": %.6e, \"mean_norm\": %.6e, \"particle_variance\": %.6e, "
          "\"non_finite\": %d, \"mean_k_lr\": %s, \"objective\": %.4f, \"backward_seconds\": %.4f, "
          "\"scene\": \"%s\", \"cost\": \"%s\", \"policy_steps\": %d}\n",
          horizon, methods[m].name, args.particles, args.replicates, total_var, mean.norm(),
          c > 0 ? particle_var[m] / c : NAN, non_finite[m],
          k_count[m] > 0 ? std::to_string(k_sum[m] / k_count[m]).c_str() : "null",
          objective / args.replicates, seconds[m] / args.replicates, args.scene.c_str(),
          args.cost.c_str(), args.policy_steps);
      std::fflush(stdout);
    }
  }
  return 0;
}

}  // namespace
}  // namespace totalgrad

int main(int argc, char** argv) {
  totalgrad::Args args;
  if (!totalgrad::Parse(argc, argv, &args)) {
    std::fprintf(stderr,
                 "usage: gradient_variance_bench [--horizons 10,30,60,100] [--particles 300] "
                 "[--replicates 30] [--data 450] [--train-iterations 30] [--policy-steps 200] "
                 "[--policy-particles 100] [--cost angle] [--scene cartpole-swingup] [--seed 1]\n");
    return 2;
  }
  return totalgrad::Run(args);
}
