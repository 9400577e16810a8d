// `totalgrad bench dump-iteration --data N --particles P --horizon H [--seed S]
// --out FILE.json`: writes one RP gradient iteration of `totalgrad bench
// iteration` as data, so that a peer implementation (bench/torch_rp_iteration.py,
// PyTorch autograd) can recompute it from the same numbers and be checked
// against ours before it is timed.
//
// The problem is MakeSyntheticProblem with --data/--horizon and seed S (bench
// iteration uses the default seed 1), and the random numbers are those of
// bench iteration's first timed round: Rng(S, Stream::kStudy, 101) (its round
// r draws from index 100 + r; round 0 is the warm-up and is not timed).
//
// File format (doubles with round-trip precision; matrices are arrays of rows):
//   {"format": "totalgrad-rp-iteration", "version": 1,
//    "data": N, "particles": P, "horizon": H, "seed": S,
//    "gp": {"inputs": N x 5, "targets": N x 4,
//           "log_lengthscales": 4 x 5, "log_signal_std": [4], "log_noise_std": [4],
//           "jitter": [4],                    // added to diag(K_a), see gp.h
//           "noise_variance_multiplier": m},  // variance = sf^2 - k'K^-1 k + m sn^2
//    "policy": {"centres": C x 4, "log_lengthscales": [4], "weights": [C],
//               "max_force": u_max},
//    "cost": {"type": "angle", "target": [4], "q_diagonal": [4]}
//         or {"type": "tip", "target_position": s, "pendulum_length": l, "width": w},
//    "mu0": [4], "initial_std": [4],
//    "normals": {"x0": P x 4, "eps": H x P x 4},  // as SimulateParticles drew them
//    "objective": J,
//    "gradient": {"centres": C x 4, "log_lengthscales": [4], "weights": [C]}}
//
// The split of the parameter vector follows policy::RbfPolicy (centres
// row-major, then log length-scales, then weights).
#ifndef TOTALGRAD_CLIENT_CORE_COMMANDS_BENCH_DUMP_COMMAND_H_
#define TOTALGRAD_CLIENT_CORE_COMMANDS_BENCH_DUMP_COMMAND_H_

#include <cstdint>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "absl/status/statusor.h"

namespace totalgrad::cli {

struct DumpIterationOptions {
  int data = 450;
  int particles = 300;
  int horizon = 30;
  uint64_t seed = 1;
};

// Builds the problem, runs RpEstimator once and returns the document above.
// Errors: the problem builder's (InvalidArgument for a bad size); Internal if
// the rollout did not draw its normals in the order rollout.h documents (the
// dump would then not describe the iteration it claims to).
absl::StatusOr<nlohmann::ordered_json> DumpRpIteration(const DumpIterationOptions& options);

// Adds `dump-iteration` under the `bench` subcommand.
void AddBenchDumpIterationCommand(CLI::App* bench, int* exit_code);

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_CORE_COMMANDS_BENCH_DUMP_COMMAND_H_
