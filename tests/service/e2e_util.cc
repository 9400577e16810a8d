#include "tests/service/e2e_util.h"

#include <grpcpp/create_channel.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <set>

#include "absl/strings/str_cat.h"
#include "tests/service/service_testutil.h"
#include "core/learner/trial_options.h"
#include "worker/learner_runner.h"

namespace totalgrad::testing {

OptionPairs TinyProtocol() {
  return {{"episodes", "2"}, {"policy_steps", "3"}, {"particles", "8"},
          {"eval_rollouts", "2"}, {"horizon", "10"}};
}

OptionPairs SlowProtocol() {
  return {{"episodes", "8"}, {"policy_steps", "80"}, {"particles", "40"},
          {"eval_rollouts", "2"}, {"horizon", "15"}};
}

v1::SweepSpec MakeSpec(const std::string& name, const std::vector<int>& seeds,
                       const OptionPairs& protocol) {
  v1::SweepSpec spec;
  spec.set_name(name);
  auto* method = spec.add_grid();
  method->set_key("method");
  method->add_values("RP");
  auto* seed = spec.add_grid();
  seed->set_key("seed");
  for (int s : seeds) seed->add_values(std::to_string(s));
  for (const auto& [key, value] : protocol) {
    auto* option = spec.add_protocol();
    option->set_key(key);
    option->set_value(value);
  }
  return spec;
}

namespace {
class Collect final : public worker::JobProgress {
 public:
  void OnEpisode(const worker::EpisodeOutcome& e) override { episodes.push_back(e); }
  bool ShouldCancel() override { return false; }
  std::vector<worker::EpisodeOutcome> episodes;
};
}  // namespace

std::vector<worker::EpisodeOutcome> ReferenceEpisodes(const OptionPairs& options) {
  worker::LearnerTrialRunner runner;
  Collect collect;
  worker::JobInput job;
  // The service stores a job's options as every key's pair (resolved at
  // submission), and the worker reads a key missing from stored pairs as the
  // value it had before the key existed (learner::TrialOptionsFromStoredPairs);
  // so the reference runs on the full list too: keys the protocol leaves out
  // take today's defaults, as in the stored job.
  absl::StatusOr<learner::TrialOptions> resolved = learner::TrialOptionsFromPairs(options);
  EXPECT_TRUE(resolved.ok()) << resolved.status();
  job.options = resolved.ok() ? learner::TrialOptionPairs(*resolved) : options;
  auto outcome = runner.Run(job, &collect);
  EXPECT_TRUE(outcome.ok()) << outcome.status();
  return collect.episodes;
}

void ServiceFixture::SetUp() {
  dir_ = MakeTempDir();
  db_ = dir_ + "/coordinator.db";
  WriteFile(dir_ + "/worker.token", kWorkerToken);
  WriteFile(dir_ + "/user.token", kUserToken);
}

void ServiceFixture::TearDown() {
  if (!HasFailure()) {
    coordinator_.reset();
    std::error_code ignored;
    std::filesystem::remove_all(dir_, ignored);
    return;
  }
  {
    // Leave the evidence in the test output.
    for (const auto& entry : std::filesystem::directory_iterator(dir_)) {
      if (entry.path().extension() == ".log") {
        std::cerr << "---- " << entry.path() << "\n" << ReadFile(entry.path()).substr(0, 20000);
      }
    }
  }
}

void ServiceFixture::StartCoordinator(int port, std::vector<std::string> extra,
                                      double lease_timeout_seconds) {
  const std::string port_file = dir_ + "/port";
  std::filesystem::remove(port_file);
  std::vector<std::string> argv = {TOTALGRAD_COORDINATOR_BIN,
                                   "--db", db_,
                                   "--listen", absl::StrCat("127.0.0.1:", port),
                                   "--insecure",
                                   "--worker-token-file", dir_ + "/worker.token",
                                   "--user-token-file", dir_ + "/user.token",
                                   "--port-file", port_file,
                                   "--heartbeat-interval", "0.2",
                                   "--lease-timeout", absl::StrCat(lease_timeout_seconds)};
  argv.insert(argv.end(), extra.begin(), extra.end());
  coordinator_ = std::make_unique<Process>(
      argv, absl::StrCat(dir_, "/coordinator-", coordinator_starts_++, ".log"));
  int bound = 0;
  ASSERT_TRUE(WaitFor(
      [&] {
        std::ifstream in(port_file);
        return (in >> bound) && bound > 0;
      },
      std::chrono::seconds(30)))
      << "coordinator did not start:\n" << coordinator_->Log();
  port_ = bound;
  channel_ = grpc::CreateChannel(absl::StrCat("127.0.0.1:", port_),
                                 grpc::InsecureChannelCredentials());
  control_ = v1::ControlService::NewStub(channel_);
  worker_stub_ = v1::WorkerService::NewStub(channel_);
}

std::unique_ptr<Process> ServiceFixture::StartWorker(const std::string& id,
                                                     std::vector<std::string> extra,
                                                     const std::string& token_file) {
  std::vector<std::string> argv = {TOTALGRAD_WORKER_BIN,
                                   "--coordinator", absl::StrCat("127.0.0.1:", port_),
                                   "--insecure",
                                   "--token-file",
                                   token_file.empty() ? dir_ + "/worker.token" : token_file,
                                   "--slots", "1",
                                   "--worker-id", id,
                                   "--state-dir", dir_ + "/worker-state",
                                   "--acquire-wait", "1"};
  argv.insert(argv.end(), extra.begin(), extra.end());
  return std::make_unique<Process>(argv, absl::StrCat(dir_, "/worker-", id, ".log"));
}

std::unique_ptr<grpc::ClientContext> ServiceFixture::Context(const std::string& token,
                                                             int timeout_ms) {
  auto context = std::make_unique<grpc::ClientContext>();
  context->set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(timeout_ms));
  if (!token.empty()) context->AddMetadata("authorization", absl::StrCat("Bearer ", token));
  return context;
}

grpc::Status ServiceFixture::Submit(const v1::SweepSpec& spec, v1::SubmitSweepResponse* response) {
  v1::SubmitSweepRequest request;
  *request.mutable_spec() = spec;
  request.set_source_name("test");
  v1::SubmitSweepResponse ignored;
  return control_->SubmitSweep(Context(kUserToken).get(), request, response ? response : &ignored);
}

v1::SweepInfo ServiceFixture::Sweep(const std::string& name) {
  v1::SweepRequest request;
  request.set_name(name);
  v1::SweepInfo info;
  const grpc::Status status = control_->GetSweep(Context(kUserToken).get(), request, &info);
  EXPECT_TRUE(status.ok()) << status.error_message();
  return info;
}

bool ServiceFixture::WaitFinished(const std::string& name, std::chrono::milliseconds timeout) {
  return WaitFor(
      [&] {
        v1::SweepRequest request;
        request.set_name(name);
        v1::SweepInfo info;
        return control_->GetSweep(Context(kUserToken).get(), request, &info).ok() &&
               info.finished();
      },
      timeout);
}

std::vector<v1::JobInfo> ServiceFixture::Jobs(const std::string& sweep) {
  v1::ListJobsRequest request;
  request.set_sweep_name(sweep);
  v1::ListJobsResponse response;
  const grpc::Status status = control_->ListJobs(Context(kUserToken).get(), request, &response);
  EXPECT_TRUE(status.ok()) << status.error_message();
  return {response.jobs().begin(), response.jobs().end()};
}

std::vector<v1::EpisodeRow> ServiceFixture::Export(const std::string& sweep, bool all_attempts) {
  v1::ExportEpisodesRequest request;
  request.set_sweep_name(sweep);
  request.set_all_attempts(all_attempts);
  auto context = Context(kUserToken);
  auto reader = control_->ExportEpisodes(context.get(), request);
  std::vector<v1::EpisodeRow> rows;
  v1::ExportEpisodesResponse batch;
  while (reader->Read(&batch)) rows.insert(rows.end(), batch.rows().begin(), batch.rows().end());
  const grpc::Status status = reader->Finish();
  EXPECT_TRUE(status.ok()) << status.error_message();
  return rows;
}

v1::GetJobLogResponse ServiceFixture::JobLog(int64_t job_id) {
  v1::JobRequest request;
  request.set_job_id(job_id);
  v1::GetJobLogResponse response;
  const grpc::Status status = control_->GetJobLog(Context(kUserToken).get(), request, &response);
  EXPECT_TRUE(status.ok()) << status.error_message();
  return response;
}

void ServiceFixture::ExpectRowsEqualReference(const std::string& sweep,
                                              const OptionPairs& protocol) {
  const std::vector<v1::JobInfo> jobs = Jobs(sweep);
  const std::vector<v1::EpisodeRow> rows = Export(sweep, /*all_attempts=*/false);
  std::map<int64_t, std::map<int, const v1::EpisodeRow*>> by_job;
  for (const auto& row : rows) {
    EXPECT_TRUE(row.final_attempt()) << "job " << row.job_id() << " episode " << row.report().episode();
    const bool inserted = by_job[row.job_id()].emplace(row.report().episode(), &row).second;
    EXPECT_TRUE(inserted) << "duplicate row: job " << row.job_id() << " episode "
                          << row.report().episode();
  }
  size_t expected_rows = 0;
  for (const v1::JobInfo& job : jobs) {
    EXPECT_EQ(job.state(), v1::JOB_STATE_COMPLETED) << "job " << job.job_id();
    if (job.kind() == v1::JOB_KIND_STUDY) continue;  // no episodes; study_e2e_test checks its rows
    OptionPairs options = protocol;
    options.emplace_back("method", job.method());
    options.emplace_back("seed", job.seed());
    const std::vector<worker::EpisodeOutcome> reference = ReferenceEpisodes(options);
    expected_rows += reference.size();
    ASSERT_EQ(by_job[job.job_id()].size(), reference.size()) << "job " << job.job_id();
    for (const worker::EpisodeOutcome& e : reference) {
      const v1::EpisodeRow* row = by_job[job.job_id()][e.episode];
      ASSERT_NE(row, nullptr) << "job " << job.job_id() << " lacks episode " << e.episode;
      // Bit-for-bit: same seed and build give the same numbers.
      EXPECT_EQ(row->report().real_cost(), e.real_cost) << "job " << job.job_id() << " ep " << e.episode;
      if (e.episode > 0) {
        EXPECT_EQ(row->report().eval_cost_mean(), e.eval_cost_mean);
        EXPECT_EQ(row->report().eval_cost_std(), e.eval_cost_std);
        EXPECT_EQ(row->report().predicted_cost(), e.predicted_cost);
      } else {
        EXPECT_TRUE(std::isnan(row->report().eval_cost_mean()));
      }
    }
  }
  EXPECT_EQ(rows.size(), expected_rows);
}

}  // namespace totalgrad::testing
