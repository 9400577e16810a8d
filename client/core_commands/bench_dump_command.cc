#include "client/core_commands/bench_dump_command.h"

#include <fstream>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "core/common/rng.h"
#include "core/estimators/rollout.h"
#include "core/estimators/rp.h"
#include "core/estimators/synthetic_problem.h"
#include "core/tasks/cost.h"

namespace totalgrad::cli {
namespace {

// bench iteration's round r draws from Rng(seed, kStudy, 100 + r) and does not
// time round 0 (see bench_command.cc), so its first timed round is this one.
constexpr uint64_t kFirstTimedRoundIndex = 101;

struct DumpState {
  DumpIterationOptions options;
  std::string out_path;
};

nlohmann::ordered_json RowsToJson(const ConstRowMatrixRef& m) {
  nlohmann::ordered_json rows = nlohmann::ordered_json::array();
  for (Eigen::Index r = 0; r < m.rows(); ++r) {
    nlohmann::ordered_json row = nlohmann::ordered_json::array();
    for (Eigen::Index c = 0; c < m.cols(); ++c) row.push_back(m(r, c));
    rows.push_back(std::move(row));
  }
  return rows;
}

nlohmann::ordered_json VectorToJson(const ConstVectorRef& v) {
  nlohmann::ordered_json out = nlohmann::ordered_json::array();
  for (Eigen::Index i = 0; i < v.size(); ++i) out.push_back(v(i));
  return out;
}

absl::StatusOr<nlohmann::ordered_json> CostToJson(const tasks::StateCost& cost) {
  if (const auto* angle = dynamic_cast<const tasks::AngleCost*>(&cost)) {
    return nlohmann::ordered_json{{"type", "angle"},
                                  {"target", VectorToJson(angle->target())},
                                  {"q_diagonal", VectorToJson(angle->q_diagonal())}};
  }
  if (const auto* tip = dynamic_cast<const tasks::TipCost*>(&cost)) {
    return nlohmann::ordered_json{{"type", "tip"},
                                  {"target_position", tip->target_position()},
                                  {"pendulum_length", tip->pendulum_length()},
                                  {"width", tip->width()}};
  }
  return absl::InternalError(absl::StrCat("dump-iteration: cost '", cost.Name(),
                                          "' has no JSON description"));
}

// The parameter-vector layout of policy::RbfPolicy, split into its parts.
nlohmann::ordered_json PolicyVectorToJson(const Vector& packed, int num_basis, int state_dim) {
  const Eigen::Map<const RowMatrix> centres(packed.data(), num_basis, state_dim);
  const int loglen_offset = num_basis * state_dim;
  return nlohmann::ordered_json{
      {"centres", RowsToJson(centres)},
      {"log_lengthscales", VectorToJson(packed.segment(loglen_offset, state_dim))},
      {"weights", VectorToJson(packed.segment(loglen_offset + state_dim, num_basis))}};
}

}  // namespace

absl::StatusOr<nlohmann::ordered_json> DumpRpIteration(const DumpIterationOptions& options) {
  if (options.particles < 1) return absl::InvalidArgumentError("--particles must be >= 1");
  estimators::SyntheticProblemOptions problem_options;
  problem_options.data = options.data;
  problem_options.horizon = options.horizon;
  problem_options.seed = options.seed;
  absl::StatusOr<std::unique_ptr<estimators::SyntheticProblem>> synthetic =
      estimators::MakeSyntheticProblem(problem_options);
  if (!synthetic.ok()) return synthetic.status();
  const estimators::Problem& problem = (*synthetic)->problem;
  const gp::GpModel& model = *(*synthetic)->model;
  const policy::RbfPolicy& policy = *(*synthetic)->policy;
  const int s_dim = policy.state_dim();

  Rng rng(options.seed, Stream::kStudy, kFirstTimedRoundIndex);
  // The normals, from a copy of the generator in SimulateParticles' order:
  // x0 first, then eps_t for t = 0..H-1, each filled row by row.
  Rng normals_rng = rng;
  RowMatrix x0_normals(options.particles, s_dim);
  normals_rng.FillNormal(&x0_normals);
  std::vector<RowMatrix> eps(options.horizon, RowMatrix(options.particles, s_dim));
  for (RowMatrix& step_normals : eps) normals_rng.FillNormal(&step_normals);

  // A rollout from a second copy must have drawn exactly these numbers;
  // otherwise the documented order is stale and the dump would describe some
  // other iteration.
  {
    Rng replay_rng = rng;
    estimators::Rollout replay;
    absl::Status status = estimators::SimulateParticles(problem, options.particles, {},
                                                        &replay_rng, &replay);
    if (!status.ok()) return status;
    const RowMatrix x0 =
        (x0_normals * problem.initial_std.asDiagonal()).rowwise() + problem.mu0.transpose();
    bool same = replay.steps.front().state == x0;
    for (int t = 0; t < options.horizon; ++t) same = same && replay.steps[t].noise == eps[t];
    if (!same) {
      return absl::InternalError(
          "dump-iteration: SimulateParticles no longer draws x0 and then eps_t row by row; "
          "update the dump to its order");
    }
  }

  estimators::RpEstimator estimator;
  estimators::EstimateOptions estimate_options;
  estimate_options.particles = options.particles;
  estimators::GradientEstimate estimate;
  absl::Status status = estimator.Estimate(problem, estimate_options, &rng, &estimate);
  if (!status.ok()) return status;
  if (!estimate.finite) return absl::InternalError("dump-iteration: the RP estimate is not finite");

  absl::StatusOr<nlohmann::ordered_json> cost = CostToJson(*problem.cost);
  if (!cost.ok()) return cost.status();

  const gp::GpHyperparameters& hyp = model.hyperparameters();
  Vector jitter(model.num_outputs());
  for (int a = 0; a < model.num_outputs(); ++a) jitter(a) = model.jitter(a);
  nlohmann::ordered_json eps_json = nlohmann::ordered_json::array();
  for (const RowMatrix& step_normals : eps) eps_json.push_back(RowsToJson(step_normals));

  return nlohmann::ordered_json{
      {"format", "totalgrad-rp-iteration"},
      {"version", 1},
      {"data", options.data},
      {"particles", options.particles},
      {"horizon", options.horizon},
      {"seed", options.seed},
      {"gp",
       {{"inputs", RowsToJson(model.inputs())},
        {"targets", RowsToJson(model.targets())},
        {"log_lengthscales", RowsToJson(hyp.log_lengthscales)},
        {"log_signal_std", VectorToJson(hyp.log_signal_std)},
        {"log_noise_std", VectorToJson(hyp.log_noise_std)},
        {"jitter", VectorToJson(jitter)},
        {"noise_variance_multiplier", problem.noise_variance_multiplier}}},
      {"policy",
       {{"centres", RowsToJson(policy.centres())},
        {"log_lengthscales", VectorToJson(policy.log_lengthscales())},
        {"weights", VectorToJson(policy.weights())},
        {"max_force", policy.max_force()}}},
      {"cost", *std::move(cost)},
      {"mu0", VectorToJson(problem.mu0)},
      {"initial_std", VectorToJson(problem.initial_std)},
      {"normals", {{"x0", RowsToJson(x0_normals)}, {"eps", std::move(eps_json)}}},
      {"objective", estimate.objective},
      {"gradient", PolicyVectorToJson(estimate.gradient, policy.num_basis(), s_dim)}};
}

void AddBenchDumpIterationCommand(CLI::App* bench, int* exit_code) {
  auto state = std::make_shared<DumpState>();
  CLI::App* dump = bench->add_subcommand(
      "dump-iteration",
      "Write bench iteration's problem, random numbers and RP result as JSON "
      "(input of bench/torch_rp_iteration.py)");
  dump->add_option("--data", state->options.data, "N, GP training points")
      ->check(CLI::Range(2, 100000));
  dump->add_option("--particles", state->options.particles, "P")->check(CLI::PositiveNumber);
  dump->add_option("--horizon", state->options.horizon, "H, steps")->check(CLI::PositiveNumber);
  dump->add_option("--seed", state->options.seed,
                   "problem and rollout seed (bench iteration uses 1)");
  dump->add_option("--out", state->out_path, "output JSON file")->required();
  dump->callback([state, exit_code]() {
    absl::StatusOr<nlohmann::ordered_json> doc = DumpRpIteration(state->options);
    if (!doc.ok()) {
      std::cerr << "totalgrad bench dump-iteration: " << doc.status().message() << "\n";
      *exit_code = doc.status().code() == absl::StatusCode::kInvalidArgument ? 2 : 1;
      return;
    }
    std::ofstream out(state->out_path);
    out << doc->dump() << "\n";
    out.close();
    if (!out) {
      std::cerr << "totalgrad bench dump-iteration: cannot write " << state->out_path << "\n";
      *exit_code = 1;
      return;
    }
    *exit_code = 0;
  });
}

}  // namespace totalgrad::cli
