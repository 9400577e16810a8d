// `totalgrad job artifacts JOB --out DIR`: the final policy and GP model of a
// trial job, from the trial checkpoint the coordinator keeps
// (GetJobArtifacts), written as
//   DIR/snapshot.json   the trial snapshot format (io/snapshot_json.h)
//                       of the checkpoint's last episode: the data its model
//                       was fitted on, the model's GP hyperparameters, the
//                       policy before and after that episode's optimisation;
//                       `totalgrad evaluate --policy` and `totalgrad study`
//                       read it;
//   DIR/artifacts.json  what it is: job, sweep, method, seed, variant, the
//                       attempt and build that wrote it, and the FITC
//                       inducing inputs when the model was sparse (the
//                       snapshot format has no field for them).
// `totalgrad job trajectory JOB --episode E [--rollout R]`: one recorded
// trajectory of the same checkpoint (core/learner/trajectory.h): the real
// episode E with the model's prediction of it, or rollout R of the rollout
// verdict's rollouts (the last episode's), as a table, CSV or JSON
// (io/trajectory_json.h).
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>

#include <nlohmann/json.hpp>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "client/service_commands/connection.h"
#include "core/learner/checkpoint.h"
#include "io/record_format.h"
#include "io/snapshot_json.h"
#include "io/trajectory_json.h"

namespace totalgrad::cli {
namespace {

// The job's checkpoint, decoded; otherwise prints the error, sets
// *exit_code (ReportError's for a refused call, 1 for one that does not
// decode) and returns nullopt.
std::optional<learner::TrialCheckpoint> FetchCheckpoint(Connection* connection, int64_t job_id,
                                                        const std::string& what,
                                                        v1::GetJobArtifactsResponse* response,
                                                        int* exit_code) {
  v1::JobRequest request;
  request.set_job_id(job_id);
  const grpc::Status status =
      connection->Call(&v1::ControlService::Stub::GetJobArtifacts, request, response);
  if (!status.ok()) {
    *exit_code = ReportError(status, what);
    return std::nullopt;
  }
  absl::StatusOr<learner::TrialCheckpoint> checkpoint =
      learner::DecodeCheckpoint(response->checkpoint().data());
  if (!checkpoint.ok()) {
    std::cerr << "error: " << what << ": " << checkpoint.status().message()
              << " (written by " << response->worker_build() << ")\n";
    *exit_code = 1;
    return std::nullopt;
  }
  return *std::move(checkpoint);
}

int PrintJobTrajectory(Connection* connection, int64_t job_id, int episode, int rollout) {
  const std::string what = absl::StrCat("job trajectory ", job_id);
  v1::GetJobArtifactsResponse response;
  int exit_code = 0;
  const std::optional<learner::TrialCheckpoint> checkpoint =
      FetchCheckpoint(connection, job_id, what, &response, &exit_code);
  if (!checkpoint) return exit_code;
  absl::StatusOr<io::TrajectoryView> view = io::ViewTrajectory(*checkpoint, episode, rollout);
  if (!view.ok()) {
    std::cerr << "error: " << what << ": " << view.status().message() << " (attempt "
              << response.attempt() << ", written by " << response.worker_build() << ")\n";
    return 1;
  }
  if (connection->format() == Format::kJson) {
    nlohmann::ordered_json out;
    out["job"] = response.job().job_id();
    out["method"] = response.job().method();
    out["seed"] = response.job().seed();
    out["attempt"] = response.attempt();
    const nlohmann::ordered_json trajectory = io::TrajectoryToJson(*view);
    for (const auto& [key, value] : trajectory.items()) out[key] = value;
    std::cout << out.dump(2) << "\n";
    return 0;
  }
  const io::TrajectoryTable table = io::TrajectoryRows(*view);
  Listing listing;
  listing.columns = table.columns;
  for (const std::vector<double>& row : table.rows) {
    std::vector<std::string>& cells = listing.rows.emplace_back();
    for (double v : row) cells.push_back(io::RecordNumberText(v));
  }
  listing.numeric_columns = table.columns;
  Print(listing, connection->format(), std::cout);
  return 0;
}

int WriteJobArtifacts(Connection* connection, int64_t job_id, const std::string& dir) {
  const std::string what = absl::StrCat("job artifacts ", job_id);
  v1::GetJobArtifactsResponse response;
  int exit_code = 0;
  const std::optional<learner::TrialCheckpoint> checkpoint =
      FetchCheckpoint(connection, job_id, what, &response, &exit_code);
  if (!checkpoint) return exit_code;
  const int k = checkpoint->episode;
  if (k < 1 || !checkpoint->hyperparameters) {
    std::cerr << "error: " << what << ": the job's checkpoint holds only the random episode; "
              << "there is no learned policy or model yet\n";
    return 1;
  }
  // Episode k's model was fitted on the data of episodes 0..k-1: the
  // checkpoint's data without episode k's own transitions.
  // Every episode has the same number of transitions; forces hold F per
  // transition (N F, transition-major).
  const Eigen::Index per_episode = checkpoint->states.rows() / (k + 1);
  const Eigen::Index model_rows = per_episode * k;
  const Eigen::Index controls =
      checkpoint->states.rows() == 0 ? 1 : checkpoint->forces.size() / checkpoint->states.rows();
  learner::TrialSnapshot snapshot;
  snapshot.episode = k;
  snapshot.options = checkpoint->options;
  snapshot.states = checkpoint->states.topRows(model_rows);
  snapshot.forces = checkpoint->forces.head(model_rows * controls);
  snapshot.next_states = checkpoint->next_states.topRows(model_rows);
  snapshot.hyperparameters = *checkpoint->hyperparameters;
  // Before episode 1 the policy was the initial one, which a checkpoint does not keep.
  if (k >= 2) snapshot.policy_parameters_before = checkpoint->episodes[k - 1].policy_parameters;
  snapshot.policy_parameters = checkpoint->policy_parameters;

  std::error_code error;
  std::filesystem::create_directories(dir, error);
  if (error) {
    std::cerr << "error: " << what << ": cannot create " << dir << ": " << error.message() << "\n";
    return 1;
  }
  const std::string snapshot_path = (std::filesystem::path(dir) / "snapshot.json").string();
  absl::Status written = io::WriteSnapshotFile(snapshot_path, {snapshot});
  if (!written.ok()) {
    std::cerr << "error: " << what << ": " << written.message() << "\n";
    return 1;
  }
  const v1::JobInfo& job = response.job();
  nlohmann::ordered_json manifest;
  manifest["format"] = "totalgrad-job-artifacts";
  manifest["version"] = 1;
  manifest["job"] = job.job_id();
  manifest["sweep"] = job.sweep_name();
  manifest["method"] = job.method();
  int64_t seed = 0;
  if (absl::SimpleAtoi(job.seed(), &seed)) {
    manifest["seed"] = seed;  // an integer below 2^53, as stored
  } else {
    manifest["seed"] = job.seed();
  }
  manifest["variant"] = job.variant();
  manifest["state"] = StateName(job.state());
  manifest["attempt"] = response.attempt();
  manifest["episode"] = k;
  manifest["worker_build"] = response.worker_build();
  manifest["final_eval_cost"] = checkpoint->episodes[k].eval_cost_mean;
  manifest["snapshot"] = "snapshot.json";
  nlohmann::ordered_json gp;
  gp["sparse"] = checkpoint->inducing_inputs.rows() > 0;
  nlohmann::ordered_json inducing = nlohmann::ordered_json::array();
  for (Eigen::Index r = 0; r < checkpoint->inducing_inputs.rows(); ++r) {
    nlohmann::ordered_json row = nlohmann::ordered_json::array();
    for (Eigen::Index c = 0; c < checkpoint->inducing_inputs.cols(); ++c) {
      row.push_back(checkpoint->inducing_inputs(r, c));
    }
    inducing.push_back(row);
  }
  gp["inducing_inputs"] = inducing;  // of the last sparse fit; [] for the full GP
  manifest["gp"] = gp;
  const std::string manifest_path = (std::filesystem::path(dir) / "artifacts.json").string();
  std::ofstream(manifest_path) << manifest.dump(2) << "\n";
  std::cout << "job " << job.job_id() << " (" << job.method() << " seed " << job.seed()
            << "), attempt " << response.attempt() << " after episode " << k << ": wrote "
            << snapshot_path << " and " << manifest_path << "\n";
  return 0;
}

}  // namespace

void AddJobArtifactCommands(CLI::App* job_cmd, int* exit_code) {
  auto artifacts_id = std::make_shared<int64_t>(0);
  auto artifacts_dir = std::make_shared<std::string>();
  CLI::App* artifacts = AddCommand(
      job_cmd, "artifacts",
      "write a trial job's final policy and GP model (trial snapshot JSON) into --out DIR",
      exit_code,
      [artifacts_id, artifacts_dir](Connection* c) {
        return WriteJobArtifacts(c, *artifacts_id, *artifacts_dir);
      },
      /*with_format=*/false);
  artifacts->add_option("JOB", *artifacts_id, "job id")->required();
  artifacts->add_option("--out", *artifacts_dir, "directory to write into")->required();

  auto trajectory_id = std::make_shared<int64_t>(0);
  auto trajectory_episode = std::make_shared<int>(0);
  auto trajectory_rollout = std::make_shared<int>(-1);
  CLI::App* trajectory = AddCommand(
      job_cmd, "trajectory",
      "a trial's recorded trajectory: the real episode E (true states, controls) beside the "
      "model's prediction of it (mean, std per state), or with --rollout R one of the rollout "
      "verdict's rollouts of the last episode; from the job's checkpoint",
      exit_code,
      [trajectory_id, trajectory_episode, trajectory_rollout](Connection* c) {
        return PrintJobTrajectory(c, *trajectory_id, *trajectory_episode, *trajectory_rollout);
      });
  trajectory->add_option("JOB", *trajectory_id, "job id")->required();
  trajectory->add_option("--episode", *trajectory_episode, "episode (0 = the random one)")
      ->required()
      ->check(CLI::NonNegativeNumber);
  trajectory->add_option("--rollout", *trajectory_rollout,
                         "a verdict rollout of that episode (0-based) instead of the episode")
      ->check(CLI::NonNegativeNumber);
}

}  // namespace totalgrad::cli
