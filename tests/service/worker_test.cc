// The worker runtime against an in-process coordinator, with fake trial
// runners: failures are reported with their reasons, episodes survive a
// coordinator restart (replayed from the worker), CANCEL and drain behave.
// Tests of the worker's own deadlines (drain_timeout, report_grace,
// heartbeats) give it a FakeClock and move it, and pace the slow trial on a
// second one, so they neither sleep for timeouts and episodes nor depend on
// how fast a loaded machine runs them; the coordinator keeps the real clock.
#include "worker/worker.h"

#include <nlohmann/json.hpp>

#include <gtest/gtest.h>
#include <grpcpp/create_channel.h>

#include <atomic>
#include <limits>
#include <optional>
#include <filesystem>
#include <fstream>
#include <functional>
#include <thread>

#include <unistd.h>

#include "absl/strings/str_cat.h"
#include "server/service/coordinator.h"
#include "tests/service/process_util.h"
#include "tests/service/service_testutil.h"
#include "core/learner/trial.h"
#include "io/episode_json.h"
#include "worker/learner_runner.h"

namespace totalgrad::worker {
namespace worker_test {

using std::chrono::seconds;
using ::totalgrad::testing::MakeTempDir;
using ::totalgrad::testing::WaitFor;

// Behaviour by seed: 13 reports a NaN evaluation cost at episode 1, 14
// throws, 15 returns an error, 16 is slow (300 ms per episode); others take
// 10 ms per episode. Values are a function of (seed, episode).
//
// With `clock` set, the slow trial's episodes are paced on it instead of on
// real time: episode e ends when the clock reaches the trial's start + 300 ms
// * (e + 1), so a test that moves the clock by k * 300 ms gets exactly k
// more episodes, however fast or loaded the machine is.
class FakeRunner final : public JobRunner {
 public:
  static constexpr int64_t kSlowEpisodeMs = 300;

  absl::StatusOr<JobOutcome> Run(const JobInput& job, JobProgress* progress) override {
    int seed = 0, episodes = 0;
    for (const auto& [key, value] : job.options) {
      if (key == "seed") seed = std::stoi(value);
      if (key == "episodes") episodes = std::stoi(value);
    }
    if (seed == 14) throw std::runtime_error("boom");
    if (seed == 15) return absl::InternalError("integrator failed at step 7");
    const bool paced = seed == 16 && clock != nullptr;
    const int64_t start_ms = paced ? clock->MonotonicMs() : 0;
    ++started;  // after start_ms is read: the test may move the clock from here on
    const int step_ms = seed == 16 ? kSlowEpisodeMs : 10;
    for (int e = 0; e <= episodes; ++e) {
      if (paced) {
        // ShouldCancel is an atomic set by the worker's threads, so nothing
        // releases this mutex when it changes; FakeClock::AwaitUntil polls
        // the condition every millisecond.
        absl::Mutex mu;
        absl::MutexLock lock(&mu);
        const auto cancel = [&] { return progress->ShouldCancel(); };
        if (clock->AwaitUntil(&mu, absl::Condition(&cancel), start_ms + step_ms * (e + 1))) {
          ++cancelled;
          return absl::CancelledError("cancelled");
        }
      }
      for (int waited = 0; !paced && waited < step_ms; waited += 5) {
        if (progress->ShouldCancel()) {
          ++cancelled;
          return absl::CancelledError("cancelled");
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
      }
      EpisodeOutcome outcome;
      outcome.episode = e;
      outcome.real_cost = seed * 100 + e;
      if (e > 0) {
        outcome.eval_cost_mean = seed == 13 ? std::nan("") : seed * 10 + e;
        outcome.eval_cost_std = 0.5;
        outcome.predicted_cost = seed + e;
      }
      outcome.optimisation_seconds = 0.01;
      outcome.details_json = "{}";
      progress->OnEpisode(outcome);
      ++produced;
    }
    JobOutcome outcome;
    outcome.success = true;
    outcome.final_eval_cost = seed * 10 + episodes;
    outcome.episodes = episodes + 1;
    return outcome;
  }
  std::optional<double> EstimateCpuSeconds(const JobInput&) const override {
    return estimate_seconds;
  }
  Clock* clock = nullptr;  // paces seed 16 if set (before the worker starts)
  std::optional<double> estimate_seconds;  // what EstimateCpuSeconds says of every trial
  std::atomic<int> started{0};    // trials that ran past the seed checks
  std::atomic<int> produced{0};
  std::atomic<int> cancelled{0};  // trials that saw ShouldCancel()
};

// Study jobs by the study's seed: 21 returns 1200 cells and 3 references
// (more than one heartbeat's worth), 22 runs until cancelled (polling
// ShouldCancel), 23 throws, 24 returns an error.
class FakeStudyRunner final : public JobRunner {
 public:
  absl::StatusOr<JobOutcome> Run(const JobInput& job, JobProgress* progress) override {
    const std::string& spec_json = job.spec_json;
    const int seed = spec_json.find("\"seed\":21") != std::string::npos   ? 21
                     : spec_json.find("\"seed\":22") != std::string::npos ? 22
                     : spec_json.find("\"seed\":23") != std::string::npos ? 23
                                                                             : 24;
    if (seed == 23) throw std::runtime_error("study boom");
    if (seed == 24) return absl::InvalidArgumentError("the inline snapshot has no episode 9");
    if (seed == 22) {
      started = true;
      for (int waited = 0; waited < 60'000; waited += 5) {
        if (progress->ShouldCancel()) {
          stopped = true;
          return absl::CancelledError("study stopped");
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
      }
      return absl::DeadlineExceededError("never cancelled");
    }
    JobOutcome outcome;
    outcome.study_cells.resize(1200);
    for (int i = 0; i < 1200; ++i) {
      study::CellResult& cell = outcome.study_cells[i];
      cell.estimator = "RP";
      cell.method = "RP";
      cell.particles = 10 + i;
      cell.horizon = 5;
      cell.replicates = 3;
      cell.rel_rmse = 0.001 * i;
      cell.error = std::string(200, 'n');  // bulk: the batches are bounded in bytes too
    }
    for (int i = 0; i < 3; ++i) {
      study::ReferenceGradient reference;
      reference.horizon = 5 * (i + 1);
      reference.norm = 1.5;
      reference.gradient = Vector::LinSpaced(500, 0, 499 * 0.25);
      outcome.study_references.push_back(reference);
    }
    return outcome;
  }
  std::atomic<bool> started{false};  // the seed-22 study is running in the runner
  std::atomic<bool> stopped{false};
};

class WorkerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = MakeTempDir();
    options_.database = dir_ + "/worker_test.db";
    options_.listen = "127.0.0.1:0";
    options_.insecure = true;
    options_.scheduler.heartbeat_interval = absl::Milliseconds(200);
    options_.scheduler.lease_timeout = absl::Seconds(5);
    StartCoordinator();
  }
  void TearDown() override {
    if (worker_) worker_->Stop();
    if (worker_thread_.joinable()) worker_thread_.join();
    if (coordinator_) coordinator_->Shutdown();
    coordinator_.reset();
    if (!HasFailure()) std::filesystem::remove_all(dir_);
  }
  void StartCoordinator() {
    auto coordinator = service::Coordinator::Start(options_);
    ASSERT_TRUE(coordinator.ok()) << coordinator.status();
    coordinator_ = std::move(*coordinator);
    options_.listen = absl::StrCat("127.0.0.1:", coordinator_->port());  // same port on restart
    control_ = v1::ControlService::NewStub(grpc::CreateChannel(
        options_.listen, grpc::InsecureChannelCredentials()));
  }
  void StartWorker(int slots, absl::Duration drain_timeout = absl::Seconds(30),
                   bool studies = true) {
    WorkerOptions options;
    options.worker_id = "fake";
    options.host = "testhost";
    options.build = "test";
    options.slots = slots;
    options.acquire_wait = absl::Seconds(1);
    options.call_timeout = absl::Seconds(5);
    options.drain_timeout = drain_timeout;
    options.report_grace = report_grace_;
    options.max_idle = max_idle_;
    options.walltime = walltime_;
    options.state_dir = state_dir_;
    JobRunners runners{{v1::JOB_KIND_TRIAL, &runner_}};
    if (studies) runners[v1::JOB_KIND_STUDY] = &study_runner_;
    worker_ = std::make_unique<Worker>(
        options, grpc::CreateChannel(options_.listen, grpc::InsecureChannelCredentials()),
        std::move(runners), worker_clock_);
    worker_done_ = false;
    worker_thread_ = std::thread([this] {
      summary_ = worker_->Run();
      worker_done_ = true;
    });
  }
  void Submit(const std::string& name, const std::vector<int>& seeds, int max_attempts = 3) {
    v1::SubmitSweepRequest request;
    auto* spec = request.mutable_spec();
    spec->set_name(name);
    spec->set_max_attempts(max_attempts);
    auto* method = spec->add_grid();
    method->set_key("method");
    method->add_values("RP");
    auto* seed = spec->add_grid();
    seed->set_key("seed");
    for (int s : seeds) seed->add_values(std::to_string(s));
    auto* episodes = spec->add_protocol();
    episodes->set_key("episodes");
    episodes->set_value("8");
    grpc::ClientContext context;
    v1::SubmitSweepResponse response;
    const grpc::Status status = control_->SubmitSweep(&context, request, &response);
    ASSERT_TRUE(status.ok()) << status.error_message();
  }
  // A sweep of study jobs, one per seed (a valid tiny study; FakeStudyRunner
  // acts on the seed).
  void SubmitStudies(const std::string& name, const std::vector<int>& seeds, int max_attempts = 3) {
    v1::SubmitSweepRequest request;
    auto* spec = request.mutable_spec();
    spec->set_name(name);
    spec->set_max_attempts(max_attempts);
    for (int seed : seeds) {
      auto* study = spec->add_studies();
      study->set_name(absl::StrCat("s", seed));
      study->set_spec_json(absl::StrCat(
          R"({"problem":{"synthetic":{}},"particles":[10],"horizons":[5],"seed":)", seed, "}"));
    }
    grpc::ClientContext context;
    v1::SubmitSweepResponse response;
    const grpc::Status status = control_->SubmitSweep(&context, request, &response);
    ASSERT_TRUE(status.ok()) << status.error_message();
  }
  std::map<std::string, v1::JobInfo> JobsBySeed(const std::string& sweep) {
    grpc::ClientContext context;
    v1::ListJobsRequest request;
    request.set_sweep_name(sweep);
    v1::ListJobsResponse response;
    std::map<std::string, v1::JobInfo> jobs;
    if (!control_->ListJobs(&context, request, &response).ok()) return jobs;
    for (const auto& job : response.jobs()) jobs[job.seed()] = job;
    return jobs;
  }
  bool Finished(const std::string& sweep) {
    grpc::ClientContext context;
    v1::SweepRequest request;
    request.set_name(sweep);
    v1::SweepInfo info;
    return control_->GetSweep(&context, request, &info).ok() && info.finished();
  }
  // Fake time for the workers (clock_) and for the slow trial's work
  // (trial_clock_): the test moves each; nothing waits for real time to
  // pass. Two clocks, so that moving the worker to a deadline does not also
  // finish episodes, and finishing episodes does not move the worker's
  // deadlines.
  void UseFakeClocks() {
    worker_clock_ = &clock_;
    runner_.clock = &trial_clock_;
  }
  // Once the `trials`-th trial has started, lets the slow trial finish
  // `episodes` more episodes and waits until the runner has produced them.
  void ProduceSlowEpisodes(int trials, int episodes) {
    ASSERT_TRUE(WaitFor([&] { return runner_.started.load() >= trials; }, seconds(30)));
    const int target = runner_.produced + episodes;
    trial_clock_.AdvanceMs(FakeRunner::kSlowEpisodeMs * episodes);
    ASSERT_TRUE(WaitFor([&] { return runner_.produced.load() >= target; }, seconds(30)));
    EXPECT_EQ(runner_.produced.load(), target);
  }
  // Whether the coordinator lists `worker_id`: it has polled (every poll is
  // recorded before it waits).
  bool WorkerKnown(const std::string& worker_id) {
    grpc::ClientContext context;
    v1::ListWorkersResponse workers;
    if (!control_->ListWorkers(&context, v1::ListWorkersRequest(), &workers).ok()) return false;
    for (const auto& worker : workers.workers()) {
      if (worker.worker_id() == worker_id) return true;
    }
    return false;
  }
  v1::GetJobLogResponse Log(int64_t job_id) {
    grpc::ClientContext context;
    v1::JobRequest request;
    request.set_job_id(job_id);
    v1::GetJobLogResponse response;
    EXPECT_TRUE(control_->GetJobLog(&context, request, &response).ok());
    return response;
  }

  std::string dir_;
  std::string state_dir_;  // the worker's --state-dir; empty: none
  absl::Duration report_grace_ = absl::Milliseconds(500);
  absl::Duration max_idle_ = absl::InfiniteDuration();
  absl::Duration walltime_ = absl::InfiniteDuration();
  // The clock of the workers StartWorker makes; null: the system clock. A
  // test that sets it to &clock_ moves the workers' time itself. With the
  // clock at rest a worker beats only when an episode is new, so such a test
  // must end well within the coordinator's (real) 5 s lease timeout or send
  // episodes.
  Clock* worker_clock_ = nullptr;
  FakeClock clock_;
  FakeClock trial_clock_;  // paces FakeRunner's slow trial after UseFakeClocks()
  service::CoordinatorOptions options_;
  std::unique_ptr<service::Coordinator> coordinator_;
  std::unique_ptr<v1::ControlService::Stub> control_;
  FakeRunner runner_;
  FakeStudyRunner study_runner_;
  std::unique_ptr<Worker> worker_;
  std::thread worker_thread_;
  std::atomic<bool> worker_done_{false};  // Run() has returned (summary_ is set)
  WorkerSummary summary_;
};

TEST_F(WorkerTest, FailuresAreReportedWithTheirReasons) {
  Submit("failures", {1, 13, 14, 15}, /*max_attempts=*/1);
  StartWorker(2);
  ASSERT_TRUE(WaitFor([&] { return Finished("failures"); }, seconds(60)));
  auto jobs = JobsBySeed("failures");
  EXPECT_EQ(jobs["1"].state(), v1::JOB_STATE_COMPLETED);
  EXPECT_EQ(jobs["1"].episodes_stored(), 9);
  EXPECT_EQ(jobs["1"].final_eval_cost(), 18);
  EXPECT_EQ(jobs["13"].state(), v1::JOB_STATE_FAILED);
  EXPECT_NE(jobs["13"].last_error().find("episode 1: eval_cost_mean is not finite"),
            std::string::npos) << jobs["13"].last_error();
  EXPECT_EQ(jobs["13"].episodes_stored(), 1);  // episode 0 is kept with the failed attempt
  EXPECT_EQ(jobs["14"].state(), v1::JOB_STATE_FAILED);
  EXPECT_NE(jobs["14"].last_error().find("the trial threw: boom"), std::string::npos)
      << jobs["14"].last_error();
  EXPECT_EQ(jobs["15"].state(), v1::JOB_STATE_FAILED);
  EXPECT_NE(jobs["15"].last_error().find("integrator failed at step 7"), std::string::npos)
      << jobs["15"].last_error();
  EXPECT_EQ(Log(jobs["15"].job_id()).attempts(0).state(), v1::ATTEMPT_STATE_FAILED);
}

TEST_F(WorkerTest, FailedJobsAreRetriedUpToMaxAttempts) {
  Submit("retries", {14}, /*max_attempts=*/3);
  StartWorker(1);
  ASSERT_TRUE(WaitFor([&] { return Finished("retries"); }, seconds(60)));
  const v1::JobInfo job = JobsBySeed("retries")["14"];
  EXPECT_EQ(job.state(), v1::JOB_STATE_FAILED);
  EXPECT_EQ(job.attempts(), 3);
  EXPECT_EQ(job.failures(), 3);
}

// The coordinator goes away in the middle of a trial; the worker keeps
// computing, keeps the unacknowledged episodes, and replays them when the
// coordinator is back. The lease survives (recovery extends it).
TEST_F(WorkerTest, EpisodesAreReplayedAfterACoordinatorRestart) {
  UseFakeClocks();
  Submit("replay", {16});
  StartWorker(1);
  ProduceSlowEpisodes(1, 2);
  ASSERT_TRUE(WaitFor([&] { return JobsBySeed("replay")["16"].episodes_stored() == 2; }, seconds(30)));
  coordinator_->Shutdown();
  coordinator_.reset();
  ProduceSlowEpisodes(1, 2);  // episodes 2 and 3 finish while nobody listens
  StartCoordinator();
  ProduceSlowEpisodes(1, 5);  // the rest: the trial ends
  ASSERT_TRUE(WaitFor([&] { return Finished("replay"); }, seconds(60)));
  const v1::JobInfo job = JobsBySeed("replay")["16"];
  EXPECT_EQ(job.state(), v1::JOB_STATE_COMPLETED);
  EXPECT_EQ(job.attempts(), 1);
  EXPECT_EQ(job.lost_leases(), 0);
  EXPECT_EQ(job.episodes_stored(), 9);
}

// The CANCEL comes with a heartbeat. With no new episode (the trial is held
// at its second), beats are due only as the worker's clock passes heartbeat
// intervals, so the test moves it one interval at a time until the cancel
// arrives: the trial stops after exactly its first episode.
TEST_F(WorkerTest, CancelDirectiveStopsTheTrialAndReleasesIt) {
  UseFakeClocks();
  Submit("cancel", {16});
  StartWorker(1);
  ProduceSlowEpisodes(1, 1);
  ASSERT_TRUE(WaitFor([&] { return JobsBySeed("cancel")["16"].episodes_stored() == 1; }, seconds(30)));
  grpc::ClientContext context;
  v1::SweepRequest request;
  request.set_name("cancel");
  v1::SweepInfo info;
  ASSERT_TRUE(control_->CancelSweep(&context, request, &info).ok());
  const int64_t job_id = JobsBySeed("cancel")["16"].job_id();
  ASSERT_TRUE(WaitFor(
      [&] {
        clock_.AdvanceMs(absl::ToInt64Milliseconds(options_.scheduler.heartbeat_interval));
        return Log(job_id).attempts(0).state() == v1::ATTEMPT_STATE_CANCELLED;
      },
      seconds(30)));
  EXPECT_EQ(runner_.cancelled.load(), 1);
  EXPECT_EQ(runner_.produced.load(), 1);  // stopped early
  worker_->Drain();
  worker_thread_.join();
  EXPECT_EQ(summary_.released, 1);
}

TEST_F(WorkerTest, DrainLetsRunningTrialsFinishWithinTheTimeout) {
  UseFakeClocks();
  Submit("drain", {16});
  StartWorker(1, /*drain_timeout=*/absl::Seconds(60));
  ProduceSlowEpisodes(1, 1);
  ASSERT_TRUE(WaitFor([&] { return JobsBySeed("drain")["16"].episodes_stored() == 1; }, seconds(30)));
  worker_->Drain();
  ProduceSlowEpisodes(1, 8);  // the trial finishes while the worker drains
  worker_thread_.join();
  EXPECT_EQ(summary_.completed, 1);
  EXPECT_EQ(JobsBySeed("drain")["16"].state(), v1::JOB_STATE_COMPLETED);
}

// Issue 12.3: SIGTERM (Drain) while the coordinator is unreachable. The
// drain is bounded by drain_timeout + report_grace: the unacknowledged
// episodes and the release are kept in the spool instead of being retried
// for the 30-minute orphan timeout. The next worker with the same id and
// state directory replays them while the lease is still valid (the
// restarted coordinator extended it): the episodes are stored with the first
// attempt, which ends released, not lost.
//
// The worker's deadlines are on a FakeClock, set far beyond the test's own
// waits: the drain ends when, and because, the clock passes drain_timeout +
// report_grace (a worker that timed them on the real clock would hold on for
// minutes, and the bounded waits below would fail).
TEST_F(WorkerTest, DrainWhileTheCoordinatorIsDownSpoolsAndTheNextWorkerReplays) {
  state_dir_ = dir_ + "/state";
  UseFakeClocks();
  const absl::Duration drain_timeout = absl::Minutes(10);
  report_grace_ = absl::Minutes(5);
  Submit("spool", {16});
  StartWorker(1, drain_timeout);
  ProduceSlowEpisodes(1, 2);
  ASSERT_TRUE(WaitFor([&] { return JobsBySeed("spool")["16"].episodes_stored() == 2; }, seconds(30)));
  coordinator_->Shutdown();
  coordinator_.reset();
  ProduceSlowEpisodes(1, 1);  // never acknowledged
  worker_->Drain();
  std::atomic<bool> joined{false};
  std::thread joiner([&] {
    worker_thread_.join();
    joined = true;
  });
  // Bounded waits on the real clock; without them a broken drain would hang
  // the test instead of failing it.
  const auto within_5s = [&](const std::function<bool()>& done) {
    const bool ok = WaitFor(done, seconds(5));
    if (!ok) {
      worker_->Stop();  // let the test end either way
      joiner.join();
    }
    return ok;
  };
  // At the drain deadline the running trial is stopped ...
  clock_.AdvanceMs(absl::ToInt64Milliseconds(drain_timeout));
  ASSERT_TRUE(within_5s([&] { return runner_.cancelled.load() == 1; }))
      << "the trial was not stopped at the drain deadline";
  // ... and its release is retried (the coordinator is down) until the
  // report grace has passed too: only then is it spooled and the drain ends.
  EXPECT_FALSE(joined.load()) << "the worker gave up before report_grace had passed";
  clock_.AdvanceMs(absl::ToInt64Milliseconds(report_grace_));
  ASSERT_TRUE(within_5s([&] { return joined.load(); }))
      << "the drain did not end once drain_timeout + report_grace had passed";
  joiner.join();
  EXPECT_EQ(summary_.spooled, 1);
  const int produced = runner_.produced;
  EXPECT_EQ(produced, 3);
  worker_.reset();

  StartCoordinator();  // the same database: recovery extends the open lease
  StartWorker(1);      // the same id and state directory
  ProduceSlowEpisodes(2, 9);  // attempt 2, from the start
  ASSERT_TRUE(WaitFor([&] { return Finished("spool"); }, seconds(60)));
  worker_->Drain();
  worker_thread_.join();
  EXPECT_EQ(summary_.replayed, 1);
  const v1::JobInfo job = JobsBySeed("spool")["16"];
  EXPECT_EQ(job.state(), v1::JOB_STATE_COMPLETED);
  const v1::GetJobLogResponse log = Log(job.job_id());
  ASSERT_EQ(log.attempts_size(), 2);
  EXPECT_EQ(log.attempts(0).state(), v1::ATTEMPT_STATE_RELEASED);
  // Every episode the first process computed reached the database.
  EXPECT_EQ(log.attempts(0).episodes_stored(), produced);
  EXPECT_EQ(log.attempts(1).state(), v1::ATTEMPT_STATE_COMPLETED);
  EXPECT_TRUE(std::filesystem::is_empty(state_dir_ + "/id-fake/spool"));
}

// While a trial runs, its lease is marked held in the spool (so a successor
// can release it should this process be killed outright, e2e_test
// KilledWorkersSuccessorWithTheSameIdReleasesItsLeasesAtOnce); the mark is
// gone once the completion reached the coordinator.
TEST_F(WorkerTest, RunningLeaseIsMarkedHeldInTheSpoolUntilItsEndIsDelivered) {
  state_dir_ = dir_ + "/state";
  UseFakeClocks();
  Submit("held", {16});
  StartWorker(1);
  ProduceSlowEpisodes(1, 1);
  const int64_t job_id = JobsBySeed("held")["16"].job_id();
  const std::string mark =
      absl::StrCat(state_dir_, "/id-fake/spool/job-", job_id, "-attempt-1.pb");
  EXPECT_TRUE(std::filesystem::exists(mark));
  ProduceSlowEpisodes(1, 8);
  ASSERT_TRUE(WaitFor([&] { return Finished("held"); }, seconds(60)));
  worker_->Drain();
  worker_thread_.join();
  EXPECT_EQ(summary_.completed, 1);
  EXPECT_FALSE(std::filesystem::exists(mark));
  EXPECT_TRUE(std::filesystem::is_empty(state_dir_ + "/id-fake/spool"));
}

// A spooled attempt whose lease has expired by the time the next worker
// starts is refused by the coordinator and dropped with a log line; the job
// re-runs and the spool is emptied.
TEST_F(WorkerTest, SpooledResultsOfAnExpiredLeaseAreDropped) {
  state_dir_ = dir_ + "/state";
  options_.scheduler.lease_timeout = absl::Seconds(1);
  coordinator_->Shutdown();
  coordinator_.reset();
  StartCoordinator();
  Submit("expired", {16});
  UseFakeClocks();  // the drain's deadlines pass when the test moves the clock
  const absl::Duration drain_timeout = absl::Milliseconds(200);
  StartWorker(1, drain_timeout);
  ProduceSlowEpisodes(1, 1);
  ASSERT_TRUE(WaitFor([&] { return JobsBySeed("expired")["16"].episodes_stored() == 1; }, seconds(30)));
  coordinator_->Shutdown();
  coordinator_.reset();
  worker_->Drain();
  clock_.AdvanceMs(absl::ToInt64Milliseconds(drain_timeout));
  ASSERT_TRUE(WaitFor([&] { return runner_.cancelled.load() == 1; }, seconds(30)));
  clock_.AdvanceMs(absl::ToInt64Milliseconds(report_grace_));
  worker_thread_.join();
  ASSERT_EQ(summary_.spooled, 1);
  worker_.reset();
  StartCoordinator();
  // Nobody beats for the lease: after the recovery extension it is lost.
  ASSERT_TRUE(WaitFor([&] { return JobsBySeed("expired")["16"].lost_leases() == 1; }, seconds(30)));
  StartWorker(1);
  ProduceSlowEpisodes(2, 9);  // attempt 2, from the start
  ASSERT_TRUE(WaitFor([&] { return Finished("expired"); }, seconds(60)));
  worker_->Drain();
  worker_thread_.join();
  EXPECT_EQ(summary_.replayed, 0);
  EXPECT_EQ(summary_.dropped, 1);
  const v1::JobInfo job = JobsBySeed("expired")["16"];
  EXPECT_EQ(job.state(), v1::JOB_STATE_COMPLETED);
  EXPECT_EQ(Log(job.job_id()).attempts(0).state(), v1::ATTEMPT_STATE_LEASE_LOST);
  EXPECT_TRUE(std::filesystem::is_empty(state_dir_ + "/id-fake/spool"));
}

// A second process with the same worker id and state directory on this host
// refuses to run (it would mix two workers' leases under one name), naming
// the holder.
TEST_F(WorkerTest, SecondProcessWithTheSameIdOnThisHostIsRefused) {
  state_dir_ = dir_ + "/state";
  StartWorker(1);
  // The lock file exists before its lock is taken and names its holder only
  // after: wait for the holder (a twin started between the two would win
  // the lock, or find no holder to name).
  ASSERT_TRUE(WaitFor(
      [&] {
        std::ifstream lock(state_dir_ + "/id-fake/lock");
        std::string holder;
        std::getline(lock, holder);
        return holder.find("pid ") != std::string::npos;
      },
      seconds(10)));
  WorkerOptions options;
  options.worker_id = "fake";
  options.host = "testhost";
  options.state_dir = state_dir_;
  Worker twin(options, grpc::CreateChannel(options_.listen, grpc::InsecureChannelCredentials()),
              {{v1::JOB_KIND_TRIAL, &runner_}});
  const WorkerSummary twin_summary = twin.Run();
  EXPECT_EQ(twin_summary.exit, WorkerExit::kWorkerIdInUse);
  EXPECT_NE(twin_summary.exit_message.find("already in use on this host"), std::string::npos)
      << twin_summary.exit_message;
  EXPECT_NE(twin_summary.exit_message.find(absl::StrCat("pid ", getpid())), std::string::npos)
      << twin_summary.exit_message;
}

// A long poll cancelled by its caller (as Drain() cancels waiting
// AcquireLease calls) that the coordinator then answers with a lease: the
// caller never sees it, so the coordinator releases it at once (a release,
// not a failure) instead of leaving the job running until the lease expires.
TEST_F(WorkerTest, LeaseGrantedToACancelledPollIsReleasedAtOnce) {
  auto stub = v1::WorkerService::NewStub(
      grpc::CreateChannel(options_.listen, grpc::InsecureChannelCredentials()));
  grpc::ClientContext context;
  v1::AcquireLeaseRequest request;
  request.mutable_worker()->set_worker_id("gone");
  request.mutable_worker()->set_host("testhost");
  request.mutable_worker()->set_build("test");
  request.mutable_worker()->set_slots(1);
  request.set_wait_ms(4000);
  grpc::Status status;
  std::thread poll([&] {
    v1::AcquireLeaseResponse response;
    status = stub->AcquireLease(&context, request, &response);
  });
  // Let the call reach the coordinator's long poll (nothing is queued yet):
  // every poll records its worker before it waits, so the worker is listed
  // once the handler is in the scheduler.
  ASSERT_TRUE(WaitFor([&] { return WorkerKnown("gone"); }, seconds(10)));
  context.TryCancel();
  poll.join();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::CANCELLED);
  // The coordinator's handler is still waiting; new work wakes it and it grants.
  Submit("orphan", {1});
  ASSERT_TRUE(WaitFor(
      [&] {
        const v1::JobInfo job = JobsBySeed("orphan")["1"];
        return job.attempts() == 1 && job.state() == v1::JOB_STATE_QUEUED;
      },
      seconds(3)))  // well inside the 5 s lease timeout
      << "state " << JobsBySeed("orphan")["1"].state();
  const v1::JobInfo job = JobsBySeed("orphan")["1"];
  EXPECT_EQ(job.failures(), 0);
  // No worker held the lease, so it does not charge the lost-lease budget
  // (a drain's release of a lease the worker did hold does).
  EXPECT_EQ(job.lost_leases(), 0);
  const v1::GetJobLogResponse log = Log(job.job_id());
  ASSERT_EQ(log.attempts_size(), 1);
  EXPECT_EQ(log.attempts(0).state(), v1::ATTEMPT_STATE_RELEASED);
  EXPECT_EQ(log.attempts(0).worker_id(), "gone");
  EXPECT_EQ(log.attempts(0).error().rfind("undelivered: ", 0), 0u) << log.attempts(0).error();
  // A real worker then runs it to completion.
  StartWorker(1);
  ASSERT_TRUE(WaitFor([&] { return Finished("orphan"); }, seconds(30)));
}

// max_idle is measured on the worker's clock: a worker with nothing to do
// exits once the clock has passed it, at the end of the poll under way
// (acquire_wait, 1 s of real time). A worker that timed it on the real clock
// would run on for 10 minutes.
TEST_F(WorkerTest, IdleWorkerExitsOnceItsClockPassesMaxIdle) {
  UseFakeClocks();
  max_idle_ = absl::Minutes(10);
  StartWorker(1);
  // Its idle time counts from the start of its poll loop, which precedes
  // its first poll.
  ASSERT_TRUE(WaitFor([&] { return WorkerKnown("fake"); }, seconds(10)));
  clock_.AdvanceMs(absl::ToInt64Milliseconds(max_idle_) + 1);
  ASSERT_TRUE(WaitFor([&] { return worker_done_.load(); }, seconds(10)))
      << "still running after max_idle on its clock";
  worker_thread_.join();
  EXPECT_EQ(summary_.exit, WorkerExit::kDone);
  EXPECT_EQ(summary_.completed + summary_.failed + summary_.released, 0);
}

// Issue 28 item 6: with a walltime (a batch allocation's time left), a
// granted trial whose cost-model estimate is more than the time left is
// given back unstarted, charging no lease budget, and the worker drains;
// given time enough, the same trial runs.
TEST_F(WorkerTest, ATrialThatCannotFinishBeforeTheWalltimeIsGivenBackUnstarted) {
  Submit("long", {1});
  runner_.estimate_seconds = 7200;
  walltime_ = absl::Hours(1);
  StartWorker(1);
  ASSERT_TRUE(WaitFor([&] { return worker_done_.load(); }, seconds(30)))
      << "the worker did not drain after giving the trial back";
  worker_thread_.join();
  EXPECT_EQ(runner_.started.load(), 0);
  EXPECT_EQ(summary_.exit, WorkerExit::kDone);
  v1::JobInfo job = JobsBySeed("long")["1"];
  EXPECT_EQ(job.state(), v1::JOB_STATE_QUEUED);
  EXPECT_EQ(job.lost_leases(), 0);
  EXPECT_EQ(job.failures(), 0);

  walltime_ = absl::Hours(3);
  StartWorker(1);
  ASSERT_TRUE(WaitFor([&] { return Finished("long"); }, seconds(30)));
  EXPECT_EQ(runner_.started.load(), 1);
  EXPECT_EQ(JobsBySeed("long")["1"].state(), v1::JOB_STATE_COMPLETED);
}

// ---- study jobs ----

TEST_F(WorkerTest, StudyRowsAreSentInBoundedBatchesAndTheJobCompletes) {
  SubmitStudies("study-rows", {21});
  StartWorker(1);
  ASSERT_TRUE(WaitFor([&] { return Finished("study-rows"); }, seconds(60)));
  const v1::JobInfo job = JobsBySeed("study-rows")["21"];
  EXPECT_EQ(job.state(), v1::JOB_STATE_COMPLETED) << job.last_error();
  EXPECT_EQ(job.kind(), v1::JOB_KIND_STUDY);
  grpc::ClientContext context;
  v1::ListStudyRowsRequest request;
  request.set_sweep_name("study-rows");
  v1::ListStudyRowsResponse rows;
  ASSERT_TRUE(control_->ListStudyRows(&context, request, &rows).ok());
  ASSERT_EQ(rows.cells_size(), 1200);
  ASSERT_EQ(rows.references_size(), 3);
  for (int i = 0; i < rows.cells_size(); ++i) {
    EXPECT_EQ(rows.cells(i).index(), i);
    EXPECT_EQ(rows.cells(i).particles(), 10 + i);
    EXPECT_EQ(rows.cells(i).study(), "s21");
  }
  EXPECT_EQ(rows.references(2).horizon(), 15);
  EXPECT_EQ(rows.references(2).gradient_size(), 500);
  worker_->Drain();
  worker_thread_.join();
  EXPECT_EQ(summary_.completed, 1);
}

TEST_F(WorkerTest, StudyFailuresAreReportedWithTheirReasons) {
  SubmitStudies("study-fail", {23, 24}, /*max_attempts=*/1);
  StartWorker(1);
  ASSERT_TRUE(WaitFor([&] { return Finished("study-fail"); }, seconds(60)));
  auto jobs = JobsBySeed("study-fail");
  EXPECT_EQ(jobs["23"].state(), v1::JOB_STATE_FAILED);
  EXPECT_NE(jobs["23"].last_error().find("the study threw: study boom"), std::string::npos)
      << jobs["23"].last_error();
  EXPECT_EQ(jobs["24"].state(), v1::JOB_STATE_FAILED);
  EXPECT_NE(jobs["24"].last_error().find("the inline snapshot has no episode 9"), std::string::npos)
      << jobs["24"].last_error();
  worker_->Drain();
  worker_thread_.join();
  EXPECT_EQ(summary_.failed, 2);
}

TEST_F(WorkerTest, CancelDirectiveStopsTheStudyAndReleasesIt) {
  SubmitStudies("study-cancel", {22});
  StartWorker(1);
  ASSERT_TRUE(WaitFor([&] { return JobsBySeed("study-cancel")["22"].state() == v1::JOB_STATE_RUNNING; },
                      seconds(30)));
  grpc::ClientContext context;
  v1::SweepRequest request;
  request.set_name("study-cancel");
  v1::SweepInfo info;
  ASSERT_TRUE(control_->CancelSweep(&context, request, &info).ok());
  const int64_t job_id = JobsBySeed("study-cancel")["22"].job_id();
  ASSERT_TRUE(WaitFor([&] { return Log(job_id).attempts(0).state() == v1::ATTEMPT_STATE_CANCELLED; },
                      seconds(30)));
  EXPECT_TRUE(study_runner_.stopped.load());
  worker_->Drain();
  worker_thread_.join();
  EXPECT_EQ(summary_.released, 1);
}

// The drain deadline is on the worker's (fake) clock: the study runs on
// through the drain until the clock reaches it.
TEST_F(WorkerTest, DrainTimeoutStopsTheStudyAndRequeuesItWithoutBlame) {
  SubmitStudies("study-drain", {22});
  worker_clock_ = &clock_;
  const absl::Duration drain_timeout = absl::Minutes(10);
  StartWorker(1, drain_timeout);
  // Running in the runner, not only leased: a drain deadline that passed
  // before the worker registered the lease would find nothing to stop (a
  // race this test lost once under load).
  ASSERT_TRUE(WaitFor([&] { return JobsBySeed("study-drain")["22"].state() == v1::JOB_STATE_RUNNING &&
                                   study_runner_.started.load(); },
                      seconds(30)));
  worker_->Drain();
  EXPECT_FALSE(study_runner_.stopped.load()) << "stopped before the drain deadline";
  clock_.AdvanceMs(absl::ToInt64Milliseconds(drain_timeout));
  // Bounded: a worker that timed the drain on the real clock would run on
  // for 10 minutes.
  ASSERT_TRUE(WaitFor([&] { return study_runner_.stopped.load(); }, seconds(5)))
      << "the study was not stopped at the drain deadline";
  worker_thread_.join();
  EXPECT_TRUE(study_runner_.stopped.load());
  EXPECT_EQ(summary_.released, 1);
  const v1::JobInfo job = JobsBySeed("study-drain")["22"];
  EXPECT_EQ(job.state(), v1::JOB_STATE_QUEUED);
  EXPECT_EQ(job.failures(), 0);
}

// A worker without a study runner (like an older build) is never given a
// study job; it still takes trials. Every claim below is decided with the
// study queued ahead of the trial, the second one on a poll woken by the
// new sweep (no waiting for polls to time out).
TEST_F(WorkerTest, WorkersThatDoNotRunStudiesGetOnlyTrials) {
  SubmitStudies("study-only", {21});
  Submit("trials", {1});
  StartWorker(1, absl::Seconds(30), /*studies=*/false);
  ASSERT_TRUE(WaitFor([&] { return Finished("trials"); }, seconds(60)));
  Submit("more-trials", {2});
  ASSERT_TRUE(WaitFor([&] { return Finished("more-trials"); }, seconds(60)));
  EXPECT_EQ(JobsBySeed("study-only")["21"].state(), v1::JOB_STATE_QUEUED);
  EXPECT_EQ(JobsBySeed("study-only")["21"].attempts(), 0);
}

// The worker skips checkpoints the coordinator would refuse.
static_assert(kMaxCheckpointBytes == scheduler::kMaxCheckpointBytes);

// The stored episode details keep PILCO's per-step predicted cost mean and
// std (NaN as null) and leave them out for particle methods.
TEST(EpisodeDetailsJsonTest, PilcoPerStepPredictionsAreStored) {
  learner::EpisodeResult result;
  result.episode = 2;
  result.predicted_cost_mean_per_step = Vector{{0.5, 0.25, 0.125}};
  result.predicted_cost_std_per_step =
      Vector{{0.0625, 0.03125, std::numeric_limits<double>::quiet_NaN()}};
  const nlohmann::json details = nlohmann::json::parse(io::EpisodeDetailsJson(result));
  EXPECT_EQ(details["predicted_cost_mean_per_step"], nlohmann::json::array({0.5, 0.25, 0.125}));
  ASSERT_EQ(details["predicted_cost_std_per_step"].size(), 3u);
  EXPECT_EQ(details["predicted_cost_std_per_step"][1], 0.03125);
  EXPECT_TRUE(details["predicted_cost_std_per_step"][2].is_null());
  EXPECT_TRUE(details.contains("flags"));

  const nlohmann::json particle = nlohmann::json::parse(io::EpisodeDetailsJson(learner::EpisodeResult{}));
  EXPECT_FALSE(particle.contains("predicted_cost_mean_per_step"));
  EXPECT_FALSE(particle.contains("predicted_cost_std_per_step"));
}

}  // namespace worker_test
}  // namespace totalgrad::worker
