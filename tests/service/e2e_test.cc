// End to end: the real coordinator and worker binaries over gRPC on loopback
// with a real SQLite file, running real (tiny) trials. Stored rows are
// compared bit for bit with in-process runs of the same trials.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>
#include <thread>

#include <google/protobuf/descriptor.h>
#include <grpcpp/generic/generic_stub.h>
#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "server/storage/sqlite_db.h"
#include "tests/service/e2e_util.h"
#include "tests/service/service_testutil.h"

namespace totalgrad::testing {
namespace e2e_test {

using std::chrono::seconds;

class EndToEndTest : public ServiceFixture {};

// A loopback port that was free a moment ago (bound to 0, then released).
int FreeLoopbackPort() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t length = sizeof(address);
  int port = 0;
  if (::bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)) == 0 &&
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length) == 0) {
    port = ntohs(address.sin_port);
  }
  ::close(fd);
  return port;
}

// Sends `request` to 127.0.0.1:port and returns everything the server sends
// back until it closes ("" if it cannot connect).
std::string HttpExchange(int port, const std::string& request) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  timeval timeout{5, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof(timeout));
  ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &timeout, sizeof(timeout));
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  address.sin_port = htons(static_cast<uint16_t>(port));
  std::string response;
  if (::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)) == 0 &&
      ::send(fd, request.data(), request.size(), MSG_NOSIGNAL) ==
          static_cast<ssize_t>(request.size())) {
    char buffer[1024];
    ssize_t got;
    while ((got = ::recv(fd, buffer, sizeof(buffer), 0)) > 0) response.append(buffer, got);
  }
  ::close(fd);
  return response;
}

std::string HttpGet(int port, const std::string& path) {
  return HttpExchange(port, absl::StrCat("GET ", path, " HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"));
}

// The plain health port: GET /healthz is 200 "ok", everything else 404, a
// junk request gets 400 and the endpoint carries on; gRPC is unaffected.
TEST_F(EndToEndTest, HealthPortAnswersPlainHttp) {
  const int health_port = FreeLoopbackPort();
  ASSERT_GT(health_port, 0);
  StartCoordinator(0, {"--health-listen", absl::StrCat("127.0.0.1:", health_port)});
  const std::string ok = HttpGet(health_port, "/healthz");
  EXPECT_EQ(ok.rfind("HTTP/1.1 200 OK\r\n", 0), 0u) << ok;
  EXPECT_NE(ok.find("\r\n\r\nok\n"), std::string::npos) << ok;
  EXPECT_EQ(ok.substr(ok.size() - 3), "ok\n") << ok;
  const std::string other = HttpGet(health_port, "/other");
  EXPECT_EQ(other.rfind("HTTP/1.1 404 ", 0), 0u) << other;
  const std::string post =
      HttpExchange(health_port, "POST /healthz HTTP/1.1\r\nContent-Length: 0\r\n\r\n");
  EXPECT_EQ(post.rfind("HTTP/1.1 404 ", 0), 0u) << post;
  const std::string junk = HttpExchange(health_port, std::string(8000, 'x') + "\r\n\r\n");
  EXPECT_EQ(junk.rfind("HTTP/1.1 4", 0), 0u) << junk;  // refused (400 or 414), not served
  EXPECT_EQ(HttpGet(health_port, "/healthz").rfind("HTTP/1.1 200 OK\r\n", 0), 0u);
  // gRPC still serves alongside.
  v1::HealthResponse health;
  ASSERT_TRUE(control_->Health(Context(kUserToken).get(), {}, &health).ok());
  EXPECT_TRUE(health.serving());
  // SIGTERM stops both cleanly.
  coordinator_->Signal(SIGTERM);
  EXPECT_EQ(coordinator_->Wait(seconds(20)), 0) << coordinator_->Log();
  EXPECT_EQ(HttpGet(health_port, "/healthz"), "");
}

// Starts a coordinator that is expected to refuse to start; returns its exit
// status after at most 10 s (-1 if it was still running: then it is killed)
// and its log in *log.
int StartRefusedCoordinator(const std::string& dir, const std::vector<std::string>& extra,
                            std::string* log) {
  static int runs = 0;
  std::vector<std::string> argv = {TOTALGRAD_COORDINATOR_BIN, "--listen", "127.0.0.1:0",
                                   "--insecure"};
  argv.insert(argv.end(), extra.begin(), extra.end());
  Process process(argv, absl::StrCat(dir, "/refused-coordinator-", runs++, ".log"));
  const int status = process.Wait(seconds(10));
  *log = process.Log();
  return status;
}

// Issue 12.4: a second coordinator on the same database is refused, naming
// the one that holds it.
TEST_F(EndToEndTest, SecondCoordinatorOnTheSameDatabaseIsRefused) {
  StartCoordinator();
  std::string log;
  const int status = StartRefusedCoordinator(dir_, {"--db", db_}, &log);
  ASSERT_NE(status, -1) << "the second coordinator started:\n" << log;
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) != 0) << status;
  EXPECT_NE(log.find("is in use by another coordinator"), std::string::npos) << log;
  EXPECT_NE(log.find(absl::StrCat("pid ", coordinator_->pid())), std::string::npos) << log;
  // The first one is unaffected.
  ASSERT_TRUE(Submit(MakeSpec("still-mine", {1}, TinyProtocol())).ok());
}

// Issue 12.4: the database files deleted under a running coordinator. It used
// to keep acknowledging (into the deleted file) and report /healthz ok, and
// a restart silently began a new, empty database. Now writes are refused
// with the problem named, /healthz says 503 with the reason, and a restart
// without --init is refused.
TEST_F(EndToEndTest, DeletedDatabaseIsNoLongerAcknowledgedNorSilentlyRecreated) {
  const int health_port = FreeLoopbackPort();
  ASSERT_GT(health_port, 0);
  StartCoordinator(0, {"--health-listen", absl::StrCat("127.0.0.1:", health_port)});
  ASSERT_TRUE(Submit(MakeSpec("before", {1}, TinyProtocol())).ok());
  EXPECT_EQ(HttpGet(health_port, "/healthz").rfind("HTTP/1.1 200 OK", 0), 0u);
  for (const char* suffix : {"", "-wal", "-shm"}) std::filesystem::remove(db_ + suffix);
  const grpc::Status refused = Submit(MakeSpec("after", {1}, TinyProtocol()));
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::UNAVAILABLE) << refused.error_message();
  EXPECT_NE(refused.error_message().find("was deleted"), std::string::npos)
      << refused.error_message();
  const std::string health = HttpGet(health_port, "/healthz");
  EXPECT_EQ(health.rfind("HTTP/1.1 503 ", 0), 0u) << health;
  EXPECT_NE(health.find("was deleted"), std::string::npos) << health;
  // The gRPC Health call says the same.
  v1::HealthResponse rpc_health;
  ASSERT_TRUE(control_->Health(Context(kUserToken).get(), {}, &rpc_health).ok());
  EXPECT_FALSE(rpc_health.serving());
  EXPECT_NE(rpc_health.not_serving_reason().find("was deleted"), std::string::npos)
      << rpc_health.not_serving_reason();
  coordinator_->Signal(SIGTERM);
  EXPECT_EQ(coordinator_->Wait(seconds(20)), 0) << coordinator_->Log();
  EXPECT_FALSE(std::filesystem::exists(db_));  // not recreated on the way out
  std::string log;
  const int status = StartRefusedCoordinator(dir_, {"--db", db_}, &log);
  ASSERT_NE(status, -1) << "the restarted coordinator began a new database:\n" << log;
  EXPECT_NE(log.find("is missing, but its lock file records"), std::string::npos) << log;
  EXPECT_NE(log.find("--init"), std::string::npos) << log;
  EXPECT_FALSE(std::filesystem::exists(db_));
}

// Issue 28.4 and 28.5: while another process holds SQLite's write lock
// (here the test, as `sqlite3 FILE` with BEGIN IMMEDIATE would), /healthz
// answers 503 naming it within a second (it hung behind the waiting write),
// and a CLI submit fails after the store's busy timeout with exit code 4,
// "the coordinator refused", naming the lock (it retried until the lock
// went, then exited 3, "unreachable", for a full disk or a deleted
// database). Once the lock goes the same submit works; after the database
// is deleted a submit exits 4 naming that.
TEST_F(EndToEndTest, HeldWriteLockAnswers503AtOnceAndTheCliExitsFourNamingIt) {
  const int health_port = FreeLoopbackPort();
  ASSERT_GT(health_port, 0);
  StartCoordinator(0, {"--health-listen", absl::StrCat("127.0.0.1:", health_port)});
  const std::string sweep_file = dir_ + "/locked.toml";
  WriteFile(sweep_file,
            "name = \"locked\"\n[grid]\nmethod = [\"RP\"]\nseed = [1]\n[protocol]\n"
            "episodes = 1\npolicy_steps = 2\nparticles = 4\neval_rollouts = 1\nhorizon = 5\n");
  const std::vector<std::string> submit = {
      TOTALGRAD_CLI_BIN, "sweep",     "submit", sweep_file, "--coordinator",
      absl::StrCat("127.0.0.1:", port_), "--insecure", "--token-file", dir_ + "/user.token"};
  TG_ASSERT_OK_AND_ASSIGN(storage::internal::Db other, storage::internal::Db::Open(db_, false, 0));
  TG_ASSERT_OK(other.Exec("BEGIN IMMEDIATE"));

  int exit_code = -1;
  std::string out, err;
  const auto start = std::chrono::steady_clock::now();
  std::thread cli([&] { exit_code = RunCommand(submit, &out, &err); });
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // the submit waits for the lock
  const auto probe = std::chrono::steady_clock::now();
  const std::string health = HttpGet(health_port, "/healthz");
  EXPECT_LT(std::chrono::steady_clock::now() - probe, seconds(1));
  EXPECT_EQ(health.rfind("HTTP/1.1 503 ", 0), 0u) << health;
  EXPECT_NE(health.find("write lock"), std::string::npos) << health;
  cli.join();
  EXPECT_EQ(exit_code, 4) << err;
  EXPECT_NE(err.find("write lock"), std::string::npos) << err;
  EXPECT_NE(err.find("the coordinator answered"), std::string::npos) << err;
  EXPECT_LT(std::chrono::steady_clock::now() - start, seconds(12));

  TG_ASSERT_OK(other.Exec("ROLLBACK"));
  EXPECT_EQ(RunCommand(submit, &out, &err), 0) << err;

  for (const char* suffix : {"", "-wal", "-shm"}) std::filesystem::remove(db_ + suffix);
  WriteFile(sweep_file,
            "name = \"after\"\n[grid]\nmethod = [\"RP\"]\nseed = [1]\n[protocol]\n"
            "episodes = 1\npolicy_steps = 2\nparticles = 4\neval_rollouts = 1\nhorizon = 5\n");
  EXPECT_EQ(RunCommand(submit, &out, &err), 4) << err;
  EXPECT_NE(err.find("was deleted"), std::string::npos) << err;
}

// Issue 12.4: a 0-byte file is not silently made a new store (--init is
// needed), and a file of a newer schema version is refused without one
// byte of it changing.
TEST_F(EndToEndTest, EmptyAndNewerSchemaFilesAreRefusedUntouched) {
  const std::string empty = dir_ + "/empty.db";
  WriteFile(empty, "");
  std::string log;
  int status = StartRefusedCoordinator(dir_, {"--db", empty}, &log);
  ASSERT_NE(status, -1) << "a 0-byte file was initialised:\n" << log;
  EXPECT_NE(log.find("an empty (0-byte) file"), std::string::npos) << log;
  EXPECT_EQ(std::filesystem::file_size(empty), 0u);

  const std::string newer = dir_ + "/newer.db";
  {
    auto db = storage::internal::Db::Open(newer, /*create=*/true, 1000);
    ASSERT_TRUE(db.ok()) << db.status();
    ASSERT_TRUE(db->Exec("CREATE TABLE meta(key TEXT PRIMARY KEY, value TEXT); "
                         "PRAGMA user_version=99").ok());
  }
  const std::string before = ReadFile(newer);
  status = StartRefusedCoordinator(dir_, {"--db", newer}, &log);
  ASSERT_NE(status, -1) << log;
  EXPECT_NE(log.find("schema version 99"), std::string::npos) << log;
  EXPECT_EQ(ReadFile(newer), before);
  EXPECT_FALSE(std::filesystem::exists(newer + "-wal"));

  // With --init the empty file becomes a store.
  db_ = empty;
  StartCoordinator(0, {"--init"});
  ASSERT_TRUE(Submit(MakeSpec("in-empty", {1}, TinyProtocol())).ok());
}

// Issue 12.6: /healthz answers within 1 s while five idle TCP connections
// are open (the hand-written server served one connection at a time with a
// 2 s budget each: 9.8 s, longer than the shipped Kubernetes probe timeout).
TEST_F(EndToEndTest, HealthAnswersWithinASecondBesideIdleConnections) {
  const int health_port = FreeLoopbackPort();
  ASSERT_GT(health_port, 0);
  StartCoordinator(0, {"--health-listen", absl::StrCat("127.0.0.1:", health_port)});
  std::vector<int> idle;
  for (int i = 0; i < 5; ++i) {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    address.sin_port = htons(static_cast<uint16_t>(health_port));
    ASSERT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)), 0);
    idle.push_back(fd);  // connected, sends nothing
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(100));  // let the server accept them
  const auto start = std::chrono::steady_clock::now();
  const std::string answer = HttpGet(health_port, "/healthz");
  const auto took = std::chrono::steady_clock::now() - start;
  for (int fd : idle) ::close(fd);
  EXPECT_EQ(answer.rfind("HTTP/1.1 200 OK", 0), 0u) << answer;
  EXPECT_LT(took, seconds(1));
}

TEST_F(EndToEndTest, TwoWorkersStoreExactlyTheExpectedRows) {
  StartCoordinator();
  auto worker_a = StartWorker("a");
  auto worker_b = StartWorker("b");
  // Both workers are polling before the work arrives, so both take part.
  ASSERT_TRUE(WaitFor(
      [&] {
        v1::ListWorkersResponse workers;
        return control_->ListWorkers(Context(kUserToken).get(), {}, &workers).ok() &&
               workers.workers_size() == 2;
      },
      seconds(30)));
  v1::SubmitSweepResponse submitted;
  ASSERT_TRUE(Submit(MakeSpec("e2e", {1, 2, 3, 4, 5, 6}, TinyProtocol()), &submitted).ok());
  EXPECT_TRUE(submitted.created());
  EXPECT_EQ(submitted.sweep().jobs_total(), 6);
  ASSERT_TRUE(WaitFinished("e2e", seconds(60)));
  const v1::SweepInfo sweep = Sweep("e2e");
  EXPECT_EQ(sweep.jobs_completed(), 6);
  EXPECT_EQ(sweep.episodes_stored(), 18);
  EXPECT_EQ(sweep.episodes_expected(), 18);
  ExpectRowsEqualReference("e2e", TinyProtocol());
  // Both workers took part and each attempt records the worker's build.
  std::set<std::string> workers;
  for (const v1::JobInfo& job : Jobs("e2e")) {
    const v1::GetJobLogResponse log = JobLog(job.job_id());
    ASSERT_EQ(log.attempts_size(), 1);
    workers.insert(log.attempts(0).worker_id());
    EXPECT_NE(log.attempts(0).worker_build().find("totalgrad"), std::string::npos);
  }
  EXPECT_EQ(workers.size(), 2u);
  // SIGTERM drains and exits cleanly.
  worker_a->Signal(SIGTERM);
  worker_b->Signal(SIGTERM);
  EXPECT_EQ(worker_a->Wait(seconds(20)), 0) << worker_a->Log();
  EXPECT_EQ(worker_b->Wait(seconds(20)), 0) << worker_b->Log();
}

// --threads-per-slot: a worker whose trials run on 2 threads stores exactly
// the rows of the single-threaded in-process trials, and every episode's
// details carry its CPU seconds by phase (issue 11).
TEST_F(EndToEndTest, ThreadsPerSlotGiveTheSameRowsAndRecordCpuTime) {
  StartCoordinator();
  auto worker = StartWorker("threads", {"--threads-per-slot", "2"});
  OptionPairs protocol = TinyProtocol();
  for (auto& [key, value] : protocol)
    if (key == "particles") value = "70";  // more than one 64-particle block
  ASSERT_TRUE(Submit(MakeSpec("threads", {1, 2}, protocol)).ok());
  ASSERT_TRUE(WaitFinished("threads", seconds(60)));
  EXPECT_NE(worker->Log().find("x 2 threads per trial"), std::string::npos) << worker->Log();
  ExpectRowsEqualReference("threads", protocol);
  for (const v1::EpisodeRow& row : Export("threads", /*all_attempts=*/false)) {
    const nlohmann::json details = nlohmann::json::parse(row.report().details_json());
    ASSERT_TRUE(details.contains("cpu_seconds")) << row.report().details_json();
    EXPECT_GT(details["cpu_seconds"].get<double>(), 0.0);
    if (row.report().episode() > 0) {
      EXPECT_GT(details["timing"]["policy_cpu"].get<double>(), 0.0);
      EXPECT_GT(details["timing"]["policy_steps"].get<int>(), 0);
    }
  }
}

// A worker killed in the middle of a trial: the lease is lost, the job is
// re-queued and finished by another worker, and the counting rows equal an
// undisturbed run exactly (no episode lost or duplicated).
TEST_F(EndToEndTest, KilledWorkersTrialIsFinishedByAnother) {
  StartCoordinator(0, {}, /*lease_timeout_seconds=*/1.5);
  ASSERT_TRUE(Submit(MakeSpec("kill-worker", {7}, SlowProtocol())).ok());
  auto victim = StartWorker("victim");
  ASSERT_TRUE(WaitFor(
      [&] {
        auto jobs = Jobs("kill-worker");
        return !jobs.empty() && jobs[0].state() == v1::JOB_STATE_RUNNING &&
               jobs[0].episodes_stored() >= 2;
      },
      seconds(60)));
  ASSERT_TRUE(victim->Running());
  victim->Signal(SIGKILL);
  victim->Wait(seconds(10));
  auto rescuer = StartWorker("rescuer");
  ASSERT_TRUE(WaitFinished("kill-worker", seconds(120)));
  ExpectRowsEqualReference("kill-worker", SlowProtocol());
  const v1::JobInfo job = Jobs("kill-worker")[0];
  EXPECT_EQ(job.attempts(), 2);
  EXPECT_EQ(job.failures(), 0);  // a lost lease is not an application failure
  EXPECT_EQ(job.lost_leases(), 1);
  const v1::GetJobLogResponse log = JobLog(job.job_id());
  ASSERT_EQ(log.attempts_size(), 2);
  EXPECT_EQ(log.attempts(0).state(), v1::ATTEMPT_STATE_LEASE_LOST);
  EXPECT_EQ(log.attempts(0).worker_id(), "victim");
  EXPECT_GE(log.attempts(0).episodes_stored(), 2);
  EXPECT_EQ(log.attempts(1).state(), v1::ATTEMPT_STATE_COMPLETED);
  EXPECT_EQ(log.attempts(1).worker_id(), "rescuer");
}

// Issue 12.7: kill -9 of a worker in the middle of a trial. The trial's
// checkpoints reached the coordinator with its episodes; the next attempt
// resumes from the last one instead of starting over, re-reports the restored
// episodes (the completed attempt holds every episode), and the counting rows
// equal the in-process trial bit for bit. `protocol` with a small
// gp_inducing makes the trial reach FITC before the kill, so the warm-started
// inducing inputs must travel in the checkpoint too.
class CheckpointTest : public ServiceFixture {
 protected:
  void KillAndResume(const std::string& sweep, const OptionPairs& protocol,
                     int kill_after_checkpoint) {
    StartCoordinator(0, {}, /*lease_timeout_seconds=*/1.5);
    ASSERT_TRUE(Submit(MakeSpec(sweep, {7}, protocol)).ok());
    auto victim = StartWorker("victim");
    ASSERT_TRUE(WaitFor(
        [&] {
          const auto jobs = Jobs(sweep);
          if (jobs.empty() || jobs[0].state() != v1::JOB_STATE_RUNNING) return false;
          const v1::GetJobLogResponse log = JobLog(jobs[0].job_id());
          return log.attempts_size() == 1 &&
                 log.attempts(0).checkpoint_episode() >= kill_after_checkpoint;
        },
        seconds(120)));
    ASSERT_TRUE(victim->Running());
    victim->Signal(SIGKILL);
    victim->Wait(seconds(10));
    auto rescuer = StartWorker("rescuer");
    ASSERT_TRUE(WaitFinished(sweep, seconds(180)));
    ExpectRowsEqualReference(sweep, protocol);

    const v1::JobInfo job = Jobs(sweep)[0];
    const v1::GetJobLogResponse log = JobLog(job.job_id());
    ASSERT_EQ(log.attempts_size(), 2);
    EXPECT_EQ(log.attempts(0).state(), v1::ATTEMPT_STATE_LEASE_LOST);
    EXPECT_EQ(log.attempts(1).state(), v1::ATTEMPT_STATE_COMPLETED);
    const int k = log.attempts(0).checkpoint_episode();
    ASSERT_GE(k, kill_after_checkpoint);
    EXPECT_EQ(log.attempts(1).episodes_stored(), job.episodes_expected());
    EXPECT_EQ(log.attempts(1).checkpoint_episode(), job.episodes_expected() - 1);
    EXPECT_NE(rescuer->Log().find(absl::StrCat("resuming from the checkpoint of attempt 1 after "
                                               "episode ", k)),
              std::string::npos)
        << rescuer->Log();
    // Restored, not recomputed: episodes 0..k of attempt 2 carry attempt 1's
    // own optimisation times (wall-clock measurements never repeat exactly).
    std::map<std::pair<int, int>, double> seconds_by_attempt_episode;
    for (const v1::EpisodeRow& row : Export(sweep, /*all_attempts=*/true)) {
      seconds_by_attempt_episode[{row.attempt(), row.report().episode()}] =
          row.report().optimisation_seconds();
    }
    for (int e = 1; e <= k; ++e) {
      const auto first = seconds_by_attempt_episode.find({1, e});
      const auto second = seconds_by_attempt_episode.find({2, e});
      ASSERT_TRUE(first != seconds_by_attempt_episode.end()) << "episode " << e;
      ASSERT_TRUE(second != seconds_by_attempt_episode.end()) << "episode " << e;
      EXPECT_EQ(second->second, first->second) << "episode " << e;
    }
  }
};

TEST_F(CheckpointTest, KilledWorkersTrialResumesFromItsCheckpointBitForBit) {
  KillAndResume("resume", SlowProtocol(), /*kill_after_checkpoint=*/3);
}

// horizon 15 and gp_inducing 20: episode 1 fits the full GP (15 points),
// episodes 2.. FITC (30, 45, ... points), warm-starting the inducing inputs.
TEST_F(CheckpointTest, KilledWorkersFitcTrialResumesFromItsCheckpointBitForBit) {
  OptionPairs protocol = SlowProtocol();
  protocol.emplace_back("gp_inducing", "20");
  KillAndResume("resume-fitc", protocol, /*kill_after_checkpoint=*/3);
}

// Issue 28: a worker killed outright and started again with the same id and
// state directory (a reboot, a session's end) releases the leases its
// predecessor held at once, from the marks in its spool, instead of leaving
// them to expire after the lease timeout (a minute here): the job is
// re-queued without blame, and the successor resumes it from its checkpoint
// with the same results.
TEST_F(CheckpointTest, KilledWorkersSuccessorWithTheSameIdReleasesItsLeasesAtOnce) {
  StartCoordinator(0, {}, /*lease_timeout_seconds=*/60);
  ASSERT_TRUE(Submit(MakeSpec("same-id", {7}, SlowProtocol())).ok());
  auto first = StartWorker("same-id-worker");
  ASSERT_TRUE(WaitFor(
      [&] {
        const auto jobs = Jobs("same-id");
        if (jobs.empty() || jobs[0].state() != v1::JOB_STATE_RUNNING) return false;
        return JobLog(jobs[0].job_id()).attempts(0).checkpoint_episode() >= 2;
      },
      seconds(120)));
  ASSERT_TRUE(first->Running());
  first->Signal(SIGKILL);
  first->Wait(seconds(10));
  const int64_t job_id = Jobs("same-id")[0].job_id();
  auto second = StartWorker("same-id-worker");
  // Well within the lease timeout: the old attempt ended by the successor's
  // release, not by expiry.
  ASSERT_TRUE(WaitFor([&] { return JobLog(job_id).attempts_size() == 2; }, seconds(20)))
      << second->Log();
  ASSERT_TRUE(WaitFinished("same-id", seconds(180)));
  ExpectRowsEqualReference("same-id", SlowProtocol());
  const v1::JobInfo job = Jobs("same-id")[0];
  EXPECT_EQ(job.failures(), 0);
  const v1::GetJobLogResponse log = JobLog(job_id);
  ASSERT_EQ(log.attempts_size(), 2);
  EXPECT_EQ(log.attempts(0).state(), v1::ATTEMPT_STATE_RELEASED);
  EXPECT_EQ(log.attempts(1).state(), v1::ATTEMPT_STATE_COMPLETED);
  EXPECT_EQ(log.attempts(1).worker_id(), "same-id-worker");
  const std::string resumed = absl::StrCat("resuming from the checkpoint of attempt 1 after episode ",
                                           log.attempts(0).checkpoint_episode());
  EXPECT_NE(second->Log().find(resumed), std::string::npos) << second->Log();
  EXPECT_NE(second->Log().find("held by an earlier process"), std::string::npos) << second->Log();
}

// The coordinator killed in the middle of a sweep and restarted on the same
// file and port: every row acknowledged before the kill is still there, the
// running workers reattach, and the sweep completes with exact results.
TEST_F(EndToEndTest, KilledCoordinatorRestartsAndLosesNothing) {
  StartCoordinator();
  const int port = port_;
  ASSERT_TRUE(Submit(MakeSpec("kill-coordinator", {1, 2, 3}, SlowProtocol())).ok());
  auto worker_a = StartWorker("a");
  auto worker_b = StartWorker("b");
  ASSERT_TRUE(WaitFor([&] { return Sweep("kill-coordinator").episodes_stored() >= 4; }, seconds(60)));
  std::vector<v1::EpisodeRow> acknowledged = Export("kill-coordinator", /*all_attempts=*/true);
  ASSERT_GE(acknowledged.size(), 4u);
  coordinator_->Signal(SIGKILL);
  coordinator_->Wait(seconds(10));
  StartCoordinator(port);
  ASSERT_TRUE(WaitFinished("kill-coordinator", seconds(180)));
  // Nothing acknowledged was lost: every row read before the kill is still stored, unchanged.
  std::map<std::tuple<int64_t, int, int>, double> after;
  for (const auto& row : Export("kill-coordinator", /*all_attempts=*/true)) {
    after[{row.job_id(), row.attempt(), row.report().episode()}] = row.report().real_cost();
  }
  for (const auto& row : acknowledged) {
    auto it = after.find({row.job_id(), row.attempt(), row.report().episode()});
    ASSERT_NE(it, after.end()) << "lost: job " << row.job_id() << " episode " << row.report().episode();
    EXPECT_EQ(it->second, row.report().real_cost());
  }
  ExpectRowsEqualReference("kill-coordinator", SlowProtocol());
  // The workers reattached to their leases: no attempt was lost.
  for (const v1::JobInfo& job : Jobs("kill-coordinator")) EXPECT_EQ(job.lost_leases(), 0);
}

// Issue 12.2 with a real process: the coordinator is stopped (SIGSTOP) for
// twice the lease timeout while two workers run trials, then continued. Its
// lease loop notices that it did not run for longer than a heartbeat
// interval and extends both leases instead of declaring them lost; the
// trials finish on their first attempt with exact results. The workers are
// stopped too and continued 0.3 s after the coordinator, so that its lease
// loop certainly runs before any delayed heartbeat is processed (with
// running workers that order is a race, which the expiry used to win within
// milliseconds).
TEST_F(EndToEndTest, CoordinatorStallDoesNotExpireLeases) {
  StartCoordinator(0, {}, /*lease_timeout_seconds=*/1.5);
  ASSERT_TRUE(Submit(MakeSpec("stall", {1, 2}, SlowProtocol())).ok());
  auto worker_a = StartWorker("a");
  auto worker_b = StartWorker("b");
  ASSERT_TRUE(WaitFor(
      [&] {
        const auto jobs = Jobs("stall");
        return jobs.size() == 2 && jobs[0].state() == v1::JOB_STATE_RUNNING &&
               jobs[1].state() == v1::JOB_STATE_RUNNING && jobs[0].episodes_stored() >= 1 &&
               jobs[1].episodes_stored() >= 1;
      },
      seconds(60)));
  worker_a->Signal(SIGSTOP);
  worker_b->Signal(SIGSTOP);
  coordinator_->Signal(SIGSTOP);
  std::this_thread::sleep_for(seconds(3));
  coordinator_->Signal(SIGCONT);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  worker_a->Signal(SIGCONT);
  worker_b->Signal(SIGCONT);
  ASSERT_TRUE(WaitFinished("stall", seconds(120)));
  for (const v1::JobInfo& job : Jobs("stall")) {
    EXPECT_EQ(job.lost_leases(), 0) << "job " << job.job_id() << ": " << job.last_error();
    EXPECT_EQ(job.attempts(), 1) << "job " << job.job_id();
  }
  ExpectRowsEqualReference("stall", SlowProtocol());
  EXPECT_NE(coordinator_->Log().find("the coordinator stalled for"), std::string::npos);
}

// A worker that stops heartbeating loses its lease; its late reports are
// refused with ABORTED and change nothing. Repeated reports are no-ops.
TEST_F(EndToEndTest, StaleLeaseIsRefusedAndDuplicatesAreNoOps) {
  StartCoordinator(0, {}, /*lease_timeout_seconds=*/1.5);
  ASSERT_TRUE(Submit(MakeSpec("stale", {1}, TinyProtocol())).ok());
  v1::AcquireLeaseRequest acquire;
  acquire.mutable_worker()->set_worker_id("ghost");
  acquire.mutable_worker()->set_slots(1);
  acquire.set_wait_ms(1000);
  v1::AcquireLeaseResponse ghost;
  ASSERT_TRUE(worker_stub_->AcquireLease(Context(kWorkerToken).get(), acquire, &ghost).ok());
  ASSERT_TRUE(ghost.granted());
  EXPECT_EQ(ghost.lease().key().attempt(), 1);
  EXPECT_EQ(ghost.lease().episodes_expected(), 3);
  // Silence: the coordinator's clock takes the lease back (timeout 1.5 s).
  ASSERT_TRUE(WaitFor([&] { return Jobs("stale")[0].state() == v1::JOB_STATE_QUEUED; }, seconds(20)));

  v1::HeartbeatRequest late;
  late.set_worker_id("ghost");
  *late.mutable_lease() = ghost.lease().key();
  auto* episode = late.add_episodes();
  episode->set_episode(0);
  episode->set_real_cost(1.0);
  v1::HeartbeatResponse beat;
  grpc::Status status = worker_stub_->Heartbeat(Context(kWorkerToken).get(), late, &beat);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::ABORTED) << status.error_message();
  v1::CompleteRequest late_complete;
  late_complete.set_worker_id("ghost");
  *late_complete.mutable_lease() = ghost.lease().key();
  late_complete.set_episodes_total(1);
  late_complete.set_final_eval_cost(1);
  v1::CompleteResponse completed;
  status = worker_stub_->Complete(Context(kWorkerToken).get(), late_complete, &completed);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::ABORTED) << status.error_message();

  // A new lease (attempt 2): every report sent twice changes nothing the second time.
  acquire.mutable_worker()->set_worker_id("honest");
  v1::AcquireLeaseResponse honest;
  ASSERT_TRUE(worker_stub_->AcquireLease(Context(kWorkerToken).get(), acquire, &honest).ok());
  ASSERT_TRUE(honest.granted());
  EXPECT_EQ(honest.lease().key().attempt(), 2);
  v1::HeartbeatRequest report;
  report.set_worker_id("honest");
  *report.mutable_lease() = honest.lease().key();
  for (int e = 0; e < 3; ++e) {
    auto* ep = report.add_episodes();
    ep->set_episode(e);
    ep->set_real_cost(10 + e);
    ep->set_eval_cost_mean(e == 0 ? std::nan("") : 5 + e);
    ep->set_predicted_cost(e == 0 ? std::nan("") : 6 + e);
  }
  for (int i = 0; i < 2; ++i) {
    status = worker_stub_->Heartbeat(Context(kWorkerToken).get(), report, &beat);
    ASSERT_TRUE(status.ok()) << status.error_message();
    EXPECT_EQ(beat.episodes_stored(), 3);
    EXPECT_EQ(beat.directive(), v1::DIRECTIVE_CONTINUE);
  }
  v1::CompleteRequest complete;
  complete.set_worker_id("honest");
  *complete.mutable_lease() = honest.lease().key();
  complete.set_episodes_total(3);
  complete.set_success(true);
  complete.set_final_eval_cost(7);
  for (int i = 0; i < 2; ++i) {
    status = worker_stub_->Complete(Context(kWorkerToken).get(), complete, &completed);
    EXPECT_TRUE(status.ok()) << status.error_message();
  }
  const std::vector<v1::EpisodeRow> rows = Export("stale", /*all_attempts=*/true);
  EXPECT_EQ(rows.size(), 3u);  // the ghost stored nothing; the honest rows once each
  for (const auto& row : rows) EXPECT_EQ(row.attempt(), 2);
  const v1::JobInfo job = Jobs("stale")[0];
  EXPECT_EQ(job.state(), v1::JOB_STATE_COMPLETED);
  EXPECT_EQ(job.final_eval_cost(), 7);
  EXPECT_EQ(job.lost_leases(), 1);
}

// A lease granted while a draining worker cancelled its poll, and given back
// unstarted, re-queues its job without charging max_lost_leases; an ordinary
// release (a trial that started) is charged.
TEST_F(EndToEndTest, UnstartedReleaseIsNotChargedAsALostLease) {
  StartCoordinator(0, {}, /*lease_timeout_seconds=*/30);
  ASSERT_TRUE(Submit(MakeSpec("unstarted", {1}, TinyProtocol())).ok());
  v1::AcquireLeaseRequest acquire;
  acquire.mutable_worker()->set_worker_id("drainer");
  acquire.mutable_worker()->set_slots(1);
  acquire.set_wait_ms(1000);
  const auto acquire_and_release = [&](bool never_started) {
    v1::AcquireLeaseResponse granted;
    ASSERT_TRUE(worker_stub_->AcquireLease(Context(kWorkerToken).get(), acquire, &granted).ok());
    ASSERT_TRUE(granted.granted());
    v1::ReleaseRequest release;
    release.set_worker_id("drainer");
    *release.mutable_lease() = granted.lease().key();
    release.set_reason("drain");
    release.set_never_started(never_started);
    v1::ReleaseResponse released;
    const grpc::Status status =
        worker_stub_->Release(Context(kWorkerToken).get(), release, &released);
    ASSERT_TRUE(status.ok()) << status.error_message();
  };
  acquire_and_release(/*never_started=*/true);
  v1::JobInfo job = Jobs("unstarted")[0];
  EXPECT_EQ(job.state(), v1::JOB_STATE_QUEUED);
  EXPECT_EQ(job.lost_leases(), 0);
  acquire_and_release(/*never_started=*/false);
  job = Jobs("unstarted")[0];
  EXPECT_EQ(job.state(), v1::JOB_STATE_QUEUED);
  EXPECT_EQ(job.lost_leases(), 1);
}

// Issue 12.1: a hand-made Complete that reports fewer episodes than the job
// expects (or claims the right total with episodes missing) is refused; the
// job stays running and nothing reaches the results table.
TEST_F(EndToEndTest, ForgedCompletionsWithMissingEpisodesAreRefused) {
  StartCoordinator();
  ASSERT_TRUE(Submit(MakeSpec("forged", {1}, TinyProtocol())).ok());  // episodes = 2: 3 expected
  v1::AcquireLeaseRequest acquire;
  acquire.mutable_worker()->set_worker_id("forger");
  acquire.mutable_worker()->set_slots(1);
  acquire.set_wait_ms(1000);
  v1::AcquireLeaseResponse granted;
  ASSERT_TRUE(worker_stub_->AcquireLease(Context(kWorkerToken).get(), acquire, &granted).ok());
  ASSERT_TRUE(granted.granted());
  ASSERT_EQ(granted.lease().episodes_expected(), 3);
  const auto episode = [](int e) {
    v1::EpisodeReport report;
    report.set_episode(e);
    report.set_real_cost(10 + e);
    report.set_eval_cost_mean(e == 0 ? std::nan("") : 5 + e);
    report.set_predicted_cost(e == 0 ? std::nan("") : 6 + e);
    return report;
  };
  v1::CompleteRequest short_total;
  short_total.set_worker_id("forger");
  *short_total.mutable_lease() = granted.lease().key();
  *short_total.add_episodes() = episode(0);
  short_total.set_episodes_total(1);
  short_total.set_success(true);
  short_total.set_final_eval_cost(1);
  v1::CompleteResponse completed;
  grpc::Status status = worker_stub_->Complete(Context(kWorkerToken).get(), short_total, &completed);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
  EXPECT_NE(status.error_message().find("reports 1 episodes; the job expects 3"), std::string::npos)
      << status.error_message();

  v1::CompleteRequest right_total_missing_rows = short_total;
  right_total_missing_rows.set_episodes_total(3);
  status = worker_stub_->Complete(Context(kWorkerToken).get(), right_total_missing_rows, &completed);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << status.error_message();
  EXPECT_NE(status.error_message().find("episodes 1,2 of 0..2 are not stored"), std::string::npos)
      << status.error_message();

  v1::CompleteRequest too_many = short_total;
  too_many.set_episodes_total(4);
  status = worker_stub_->Complete(Context(kWorkerToken).get(), too_many, &completed);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();

  // Nothing was counted: the job still runs and the results table is empty.
  EXPECT_EQ(Jobs("forged")[0].state(), v1::JOB_STATE_RUNNING);
  v1::SweepRequest sweep_request;
  sweep_request.set_name("forged");
  v1::ListTrialResultsResponse results;
  ASSERT_TRUE(
      control_->ListTrialResults(Context(kUserToken).get(), sweep_request, &results).ok());
  EXPECT_EQ(results.results_size(), 0);

  // Every episode, then the right total: completed.
  v1::CompleteRequest honest = right_total_missing_rows;
  *honest.add_episodes() = episode(1);
  *honest.add_episodes() = episode(2);
  status = worker_stub_->Complete(Context(kWorkerToken).get(), honest, &completed);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(Jobs("forged")[0].state(), v1::JOB_STATE_COMPLETED);
  EXPECT_EQ(Export("forged", /*all_attempts=*/false).size(), 3u);
}

TEST_F(EndToEndTest, ResubmittingASweepIsIdempotent) {
  StartCoordinator();
  const v1::SweepSpec spec = MakeSpec("again", {1, 2}, TinyProtocol());
  v1::SubmitSweepResponse first, second;
  ASSERT_TRUE(Submit(spec, &first).ok());
  ASSERT_TRUE(Submit(spec, &second).ok());
  EXPECT_TRUE(first.created());
  EXPECT_FALSE(second.created());
  EXPECT_EQ(first.sweep().spec_hash(), second.sweep().spec_hash());
  EXPECT_EQ(second.sweep().jobs_total(), 2);
  // The same values written differently canonicalize to the same spec.
  v1::SweepSpec respelled = spec;
  for (auto& option : *respelled.mutable_protocol()) {
    if (option.key() == "horizon") option.set_value("10.0e0") ;
  }
  v1::SubmitSweepResponse third;
  grpc::Status status = Submit(respelled, &third);
  // "10.0e0" is not an integer for the runner: refused with the field named.
  if (!status.ok()) {
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(status.error_message().find("protocol.horizon"), std::string::npos)
        << status.error_message();
  }
  // Issue 12.6: the protocol's keys in another order are the same sweep.
  v1::SweepSpec reordered = spec;
  std::reverse(reordered.mutable_protocol()->begin(), reordered.mutable_protocol()->end());
  v1::SubmitSweepResponse fourth;
  status = Submit(reordered, &fourth);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_FALSE(fourth.created());
  EXPECT_EQ(fourth.sweep().spec_hash(), first.sweep().spec_hash());
  // Another protocol under the same name is refused and stores nothing.
  OptionPairs other_protocol = TinyProtocol();
  other_protocol[0].second = "3";  // episodes
  status = Submit(MakeSpec("again", {1, 2}, other_protocol));
  EXPECT_EQ(status.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << status.error_message();
  EXPECT_NE(status.error_message().find("protocol (episodes = 2 there, 3 here)"), std::string::npos)
      << status.error_message();
  EXPECT_EQ(Sweep("again").jobs_total(), 2);
  // More seeds grow it (issue 15): only the new job is added.
  v1::SubmitSweepResponse grown;
  ASSERT_TRUE(Submit(MakeSpec("again", {1, 2, 3}, TinyProtocol()), &grown).ok());
  EXPECT_FALSE(grown.created());
  EXPECT_EQ(grown.jobs_added(), 1);
  EXPECT_EQ(Sweep("again").jobs_total(), 3);
  v1::ListSweepsResponse sweeps;
  ASSERT_TRUE(control_->ListSweeps(Context(kUserToken).get(), {}, &sweeps).ok());
  EXPECT_EQ(sweeps.sweeps_size(), 1);
}

// Calls `method` ("/package.Service/Method") with one empty request message
// through a generic stub, so every RPC of a service descriptor can be called
// whatever its types and streaming kind. Returns the call's final status.
grpc::Status CallWithEmptyMessage(grpc::GenericStub& stub, const std::string& method,
                                  const std::string& token) {
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
  if (!token.empty()) context.AddMetadata("authorization", absl::StrCat("Bearer ", token));
  grpc::CompletionQueue queue;
  const auto wait = [&queue] {
    void* tag = nullptr;
    bool ok = false;
    queue.Next(&tag, &ok);
    return ok;
  };
  std::unique_ptr<grpc::GenericClientAsyncReaderWriter> call =
      stub.PrepareCall(&context, method, &queue);
  call->StartCall(reinterpret_cast<void*>(1));
  if (wait()) {
    grpc::Slice empty;
    grpc::ByteBuffer message(&empty, 1);
    call->Write(message, reinterpret_cast<void*>(2));
    if (wait()) {
      call->WritesDone(reinterpret_cast<void*>(3));
      wait();
    }
    grpc::ByteBuffer response;  // a unary answer, if any (drained before Finish)
    call->Read(&response, reinterpret_cast<void*>(5));
    wait();
  }
  grpc::Status status;
  call->Finish(&status, reinterpret_cast<void*>(4));
  wait();
  queue.Shutdown();
  void* tag = nullptr;
  bool ok = false;
  while (queue.Next(&tag, &ok)) {
  }
  return status;
}

// Issue 13: every RPC of both services, found from the service descriptors
// (so an RPC added later is covered without editing this test), refuses a
// call without a token and a call with the other role's token, before it
// looks at the request. gRPC C++ server interceptors cannot fail a call and
// an AuthMetadataProcessor needs TLS, so the check is one line in each
// handler; this test is what keeps a new handler from forgetting it.
TEST_F(EndToEndTest, EveryRpcOfBothServicesRefusesCallsWithoutTheRightToken) {
  StartCoordinator();
  grpc::GenericStub stub(channel_);
  struct ServiceRole {
    const google::protobuf::ServiceDescriptor* service;
    std::string other_roles_token;
  };
  int methods = 0;
  const google::protobuf::DescriptorPool* pool = google::protobuf::DescriptorPool::generated_pool();
  const ServiceRole roles[] = {
      {pool->FindServiceByName("totalgrad.v1.ControlService"), kWorkerToken},
      {pool->FindServiceByName("totalgrad.v1.WorkerService"), kUserToken}};
  for (const ServiceRole& role : roles) {
    ASSERT_NE(role.service, nullptr);
    for (int m = 0; m < role.service->method_count(); ++m) {
      const std::string method =
          absl::StrCat("/", role.service->full_name(), "/", role.service->method(m)->name());
      SCOPED_TRACE(method);
      ++methods;
      EXPECT_EQ(CallWithEmptyMessage(stub, method, "").error_code(),
                grpc::StatusCode::UNAUTHENTICATED);
      EXPECT_EQ(CallWithEmptyMessage(stub, method, "not-a-valid-token-at-all").error_code(),
                grpc::StatusCode::UNAUTHENTICATED);
      EXPECT_EQ(CallWithEmptyMessage(stub, method, role.other_roles_token).error_code(),
                grpc::StatusCode::PERMISSION_DENIED);
    }
  }
  EXPECT_GE(methods, 24);  // both services were walked (19 + 5 RPCs today)
  // The generic path reaches real handlers: with the right token a call
  // gets past the check (Health answers, ListSweeps lists none).
  EXPECT_TRUE(CallWithEmptyMessage(stub, "/totalgrad.v1.ControlService/ListSweeps", kUserToken)
                  .ok());
}

TEST_F(EndToEndTest, TokensAreCheckedOnEveryCallWithPreciseErrors) {
  StartCoordinator();
  v1::HealthResponse health;
  EXPECT_EQ(control_->Health(Context("").get(), {}, &health).error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(control_->Health(Context("not-a-valid-token-at-all").get(), {}, &health).error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
  const grpc::Status worker_on_control = control_->Health(Context(kWorkerToken).get(), {}, &health);
  EXPECT_EQ(worker_on_control.error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_NE(worker_on_control.error_message().find("worker token"), std::string::npos);
  v1::AcquireLeaseRequest acquire;
  acquire.mutable_worker()->set_worker_id("w");
  acquire.mutable_worker()->set_slots(1);
  v1::AcquireLeaseResponse lease;
  const grpc::Status user_on_worker =
      worker_stub_->AcquireLease(Context(kUserToken).get(), acquire, &lease);
  EXPECT_EQ(user_on_worker.error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_NE(user_on_worker.error_message().find("user token"), std::string::npos);
  EXPECT_EQ(worker_stub_->AcquireLease(Context("").get(), acquire, &lease).error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
  ASSERT_TRUE(control_->Health(Context(kUserToken).get(), {}, &health).ok());
  EXPECT_TRUE(health.serving());
  EXPECT_EQ(health.workers_active(), 0);  // refused calls register nobody
}

TEST_F(EndToEndTest, BadRequestsGetPreciseStatusesAndStoreNothing) {
  StartCoordinator();
  v1::SweepSpec unknown_method = MakeSpec("bad", {1}, TinyProtocol());
  unknown_method.mutable_grid(0)->add_values("NOPE");
  grpc::Status status = Submit(unknown_method);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(status.error_message().find("grid.method[1]"), std::string::npos) << status.error_message();
  EXPECT_NE(status.error_message().find("NOPE"), std::string::npos) << status.error_message();

  v1::SweepSpec unknown_key = MakeSpec("bad", {1}, {{"partikles", "3"}});
  status = Submit(unknown_key);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(status.error_message().find("protocol.partikles"), std::string::npos)
      << status.error_message();

  v1::SweepSpec bad_name = MakeSpec("no spaces allowed", {1}, TinyProtocol());
  EXPECT_EQ(Submit(bad_name).error_code(), grpc::StatusCode::INVALID_ARGUMENT);

  v1::ListSweepsResponse sweeps;
  ASSERT_TRUE(control_->ListSweeps(Context(kUserToken).get(), {}, &sweeps).ok());
  EXPECT_EQ(sweeps.sweeps_size(), 0);

  v1::SweepRequest missing;
  missing.set_name("missing");
  v1::SweepInfo info;
  EXPECT_EQ(control_->GetSweep(Context(kUserToken).get(), missing, &info).error_code(),
            grpc::StatusCode::NOT_FOUND);
  v1::JobRequest no_job;
  no_job.set_job_id(424242);
  v1::JobInfo job;
  EXPECT_EQ(control_->RetryJob(Context(kUserToken).get(), no_job, &job).error_code(),
            grpc::StatusCode::NOT_FOUND);
  v1::BackupRequest backup;
  backup.set_file_name("x.db");
  v1::BackupResponse backed_up;
  EXPECT_EQ(control_->Backup(Context(kUserToken).get(), backup, &backed_up).error_code(),
            grpc::StatusCode::FAILED_PRECONDITION);  // no --backup-dir
}

TEST_F(EndToEndTest, OversizedMessageIsRefusedAndTheCoordinatorCarriesOn) {
  StartCoordinator(0, {"--max-message-bytes", "262144"});
  ASSERT_TRUE(Submit(MakeSpec("big", {1}, TinyProtocol())).ok());
  v1::AcquireLeaseRequest acquire;
  acquire.mutable_worker()->set_worker_id("w");
  acquire.mutable_worker()->set_slots(1);
  v1::AcquireLeaseResponse lease;
  ASSERT_TRUE(worker_stub_->AcquireLease(Context(kWorkerToken).get(), acquire, &lease).ok());
  ASSERT_TRUE(lease.granted());
  v1::HeartbeatRequest huge;
  huge.set_worker_id("w");
  *huge.mutable_lease() = lease.lease().key();
  auto* episode = huge.add_episodes();
  episode->set_episode(0);
  episode->set_real_cost(1);
  episode->set_details_json(std::string(1 << 20, 'x'));
  v1::HeartbeatResponse beat;
  const grpc::Status status = worker_stub_->Heartbeat(Context(kWorkerToken).get(), huge, &beat);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << status.error_message();
  // Within the transport limit but over the per-episode details limit.
  episode->set_details_json(std::string(100 * 1024, 'x'));
  const grpc::Status too_detailed =
      worker_stub_->Heartbeat(Context(kWorkerToken).get(), huge, &beat);
  EXPECT_EQ(too_detailed.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(too_detailed.error_message().find("details_json"), std::string::npos);
  EXPECT_EQ(Jobs("big")[0].episodes_stored(), 0);
  v1::HealthResponse health;
  EXPECT_TRUE(control_->Health(Context(kUserToken).get(), {}, &health).ok());
}

TEST_F(EndToEndTest, CoordinatorRefusesPlaintextOffLoopback) {
  std::string out, err;
  const int code = RunCommand({TOTALGRAD_COORDINATOR_BIN, "--db", db_, "--listen", "0.0.0.0:0",
                               "--insecure"},
                              &out, &err);
  EXPECT_NE(code, 0);
  EXPECT_NE((out + err).find("--insecure is only allowed on a loopback address"), std::string::npos)
      << out << err;
  const int no_tls = RunCommand({TOTALGRAD_COORDINATOR_BIN, "--db", db_, "--listen", "0.0.0.0:0"},
                                &out, &err);
  EXPECT_NE(no_tls, 0);
  EXPECT_NE((out + err).find("--tls-cert and --tls-key are required"), std::string::npos) << out << err;
}

TEST_F(EndToEndTest, CancelStopsRunningTrialsAndKeepsStoredResults) {
  StartCoordinator();
  ASSERT_TRUE(Submit(MakeSpec("cancel-me", {1, 2, 3}, SlowProtocol())).ok());
  auto worker = StartWorker("w");
  ASSERT_TRUE(WaitFor(
      [&] {
        for (const auto& job : Jobs("cancel-me")) {
          if (job.state() == v1::JOB_STATE_RUNNING && job.episodes_stored() >= 1) return true;
        }
        return false;
      },
      seconds(60)));
  v1::SweepRequest request;
  request.set_name("cancel-me");
  v1::SweepInfo info;
  ASSERT_TRUE(control_->CancelSweep(Context(kUserToken).get(), request, &info).ok());
  EXPECT_EQ(info.state(), v1::SWEEP_STATE_CANCELLED);
  // The running trial hears CANCEL on its next beat and releases its lease.
  ASSERT_TRUE(WaitFor(
      [&] {
        for (const auto& job : Jobs("cancel-me")) {
          const v1::GetJobLogResponse log = JobLog(job.job_id());
          for (const auto& attempt : log.attempts()) {
            if (attempt.state() == v1::ATTEMPT_STATE_RUNNING) return false;
          }
        }
        return true;
      },
      seconds(30)));
  const v1::SweepInfo after = Sweep("cancel-me");
  EXPECT_TRUE(after.finished());
  EXPECT_EQ(after.jobs_cancelled() + after.jobs_completed(), 3);
  EXPECT_GE(after.jobs_cancelled(), 2);
  EXPECT_FALSE(Export("cancel-me", /*all_attempts=*/true).empty());  // kept
  v1::SweepInfo paused;
  EXPECT_EQ(control_->PauseSweep(Context(kUserToken).get(), request, &paused).error_code(),
            grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_TRUE(worker->Running());  // a cancel is not a reason for the worker to exit
}

// Issue 12.3: SIGTERM while the coordinator is unreachable (stopped). The
// worker used to retry its final report for up to 30 minutes; now it exits
// within --drain-timeout + --report-grace, keeping the unacknowledged
// episodes and the release on local disk. The next worker with the same id
// on this host replays them while the lease is still valid: the first
// attempt ends released with its episodes, not lost.
TEST_F(EndToEndTest, WorkerShutdownIsBoundedWhileTheCoordinatorIsUnreachable) {
  StartCoordinator();
  // The trial must still be running well after the drain deadline: five times
  // SlowProtocol's gradient steps (a few seconds per episode at N >= 60).
  OptionPairs protocol = SlowProtocol();
  for (auto& [key, value] : protocol)
    if (key == "policy_steps") value = "400";
  ASSERT_TRUE(Submit(MakeSpec("unreachable", {3}, protocol)).ok());
  auto worker = StartWorker("w", {"--drain-timeout", "1", "--report-grace", "1"});
  ASSERT_TRUE(WaitFor([&] { return Jobs("unreachable")[0].episodes_stored() >= 2; }, seconds(60)));
  coordinator_->Signal(SIGSTOP);
  const auto signalled = std::chrono::steady_clock::now();
  worker->Signal(SIGTERM);
  const int status = worker->Wait(seconds(8));
  const auto took = std::chrono::steady_clock::now() - signalled;
  coordinator_->Signal(SIGCONT);
  ASSERT_NE(status, -1) << "the worker was still running 8 s after SIGTERM\n" << worker->Log();
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;
  EXPECT_LT(took, seconds(5));
  EXPECT_NE(worker->Log().find("for the next worker with id 'w' on this host"), std::string::npos)
      << worker->Log();

  auto successor = StartWorker("w");
  ASSERT_TRUE(WaitFinished("unreachable", seconds(120)));
  ExpectRowsEqualReference("unreachable", protocol);
  const v1::JobInfo job = Jobs("unreachable")[0];
  EXPECT_EQ(job.lost_leases(), 1);  // the release counts; no lease was lost
  const v1::GetJobLogResponse log = JobLog(job.job_id());
  ASSERT_EQ(log.attempts_size(), 2);
  EXPECT_EQ(log.attempts(0).state(), v1::ATTEMPT_STATE_RELEASED) << log.attempts(0).error();
  EXPECT_GE(log.attempts(0).episodes_stored(), 2);
  EXPECT_NE(successor->Log().find("spooled results delivered"), std::string::npos)
      << successor->Log();
}

// Issue 12.3: a second SIGTERM exits at once, even while final reports
// cannot be delivered, keeping what is unfinished in the state directory.
TEST_F(EndToEndTest, SecondSigtermExitsAtOnce) {
  StartCoordinator();
  ASSERT_TRUE(Submit(MakeSpec("twice", {4}, SlowProtocol())).ok());
  auto worker = StartWorker("w", {"--drain-timeout", "60"});
  ASSERT_TRUE(WaitFor([&] { return Jobs("twice")[0].episodes_stored() >= 1; }, seconds(60)));
  coordinator_->Signal(SIGSTOP);
  worker->Signal(SIGTERM);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const auto signalled = std::chrono::steady_clock::now();
  worker->Signal(SIGTERM);
  const int status = worker->Wait(seconds(5));
  const auto took = std::chrono::steady_clock::now() - signalled;
  coordinator_->Signal(SIGCONT);
  ASSERT_NE(status, -1) << "still running 5 s after the second SIGTERM\n" << worker->Log();
  EXPECT_LT(took, seconds(2));
  EXPECT_TRUE(WIFEXITED(status)) << status;
  bool spooled = false;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(dir_ + "/worker-state")) {
    if (entry.path().extension() == ".pb") spooled = true;
  }
  EXPECT_TRUE(spooled) << worker->Log();
}

// Issue 12.3: a worker whose token the coordinator refuses (unknown, or a
// user token) exits at once with its own exit code instead of retrying
// forever; a supervisor can tell it from a crash.
TEST_F(EndToEndTest, WorkerWithARefusedTokenExitsAtOnceWithItsOwnCode) {
  StartCoordinator();
  WriteFile(dir_ + "/wrong.token", "not-the-worker-token-0123456789");
  for (const std::string& token_file : {dir_ + "/wrong.token", dir_ + "/user.token"}) {
    auto worker = StartWorker("refused", {}, token_file);
    const int status = worker->Wait(seconds(10));
    ASSERT_NE(status, -1) << token_file << ": still retrying after 10 s\n" << worker->Log();
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 77) << token_file << ": " << status;
    EXPECT_NE(worker->Log().find("refused this worker's token"), std::string::npos)
        << worker->Log();
  }
}

// Issue 15: a worker pointed at an address where no coordinator answers gives
// up after --max-unreachable (with its own exit code, so a batch job can tell)
// instead of retrying for ever and burning the allocation.
TEST_F(EndToEndTest, WorkerWithoutACoordinatorGivesUpWithItsOwnCode) {
  std::vector<std::string> argv = {TOTALGRAD_WORKER_BIN, "--coordinator", "127.0.0.1:9",
                                   "--insecure", "--token-file", dir_ + "/worker.token",
                                   "--worker-id", "lonely", "--state-dir", dir_ + "/lonely-state",
                                   "--max-unreachable", "1", "--acquire-wait", "1"};
  Process worker(argv, dir_ + "/worker-lonely.log");
  const int status = worker.Wait(seconds(30));
  ASSERT_NE(status, -1) << "still retrying after 30 s\n" << worker.Log();
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 69) << status << "\n" << worker.Log();
  EXPECT_NE(worker.Log().find("no answer from the coordinator"), std::string::npos) << worker.Log();
}

// Issue 29: a worker pointed at an address where nothing listens says so within
// seconds (before: silent for the first lease request's 35 s, then "Deadline
// Exceeded").
TEST_F(EndToEndTest, WorkerSaysAtOnceThatNothingAnswersAtItsAddress) {
  std::vector<std::string> argv = {TOTALGRAD_WORKER_BIN, "--coordinator", "127.0.0.1:9",
                                   "--insecure", "--token-file", dir_ + "/worker.token",
                                   "--worker-id", "lonely", "--state-dir", dir_ + "/lonely-state",
                                   "--max-unreachable", "120"};
  Process worker(argv, dir_ + "/worker-lonely.log");
  EXPECT_TRUE(WaitFor([&] { return worker.Log().find("nothing answers at 127.0.0.1:9") !=
                                   std::string::npos; },
                      seconds(12)))
      << worker.Log();
  EXPECT_NE(worker.Log().find("--max-unreachable (2m)"), std::string::npos) << worker.Log();
  EXPECT_TRUE(worker.Running());
}

// Issue 12.6: a token file that others may read is accepted with a warning
// naming the file and the fix; a 0600 file gets none.
TEST_F(EndToEndTest, TokenFilesReadableByOthersAreWarnedAbout) {
  std::filesystem::permissions(dir_ + "/worker.token", std::filesystem::perms::owner_read |
                                                           std::filesystem::perms::owner_write);
  std::filesystem::permissions(dir_ + "/user.token",
                               std::filesystem::perms::owner_read |
                                   std::filesystem::perms::owner_write |
                                   std::filesystem::perms::group_read |
                                   std::filesystem::perms::others_read);
  StartCoordinator();
  const std::string log = coordinator_->Log();
  EXPECT_NE(log.find(absl::StrCat("token file ", dir_, "/user.token has group or other permission "
                                  "bits (mode 0644)")),
            std::string::npos)
      << log;
  EXPECT_NE(log.find(absl::StrCat("chmod 600 ", dir_, "/user.token")), std::string::npos) << log;
  EXPECT_EQ(log.find("worker.token has group"), std::string::npos) << log;
  WriteFile(dir_ + "/shared.token", kWorkerToken);
  std::filesystem::permissions(dir_ + "/shared.token",
                               std::filesystem::perms::owner_read |
                                   std::filesystem::perms::owner_write |
                                   std::filesystem::perms::group_read);
  auto worker = StartWorker("warned", {}, dir_ + "/shared.token");
  ASSERT_TRUE(WaitFor([&] { return worker->Log().find("mode 0640") != std::string::npos; },
                      seconds(10)))
      << worker->Log();
}

// Issue 12.6: a second worker process with an id already in use on this host
// refuses to start (exit code 78), naming the process that holds the id.
TEST_F(EndToEndTest, DuplicateWorkerIdIsRefused) {
  StartCoordinator();
  auto first = StartWorker("same");
  ASSERT_TRUE(WaitFor(
      [&] {
        v1::ListWorkersResponse workers;
        return control_->ListWorkers(Context(kUserToken).get(), {}, &workers).ok() &&
               workers.workers_size() == 1;
      },
      seconds(30)));
  auto second = StartWorker("same");
  const int status = second->Wait(seconds(10));
  ASSERT_NE(status, -1) << second->Log();
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 78) << status;
  EXPECT_NE(second->Log().find(absl::StrCat("pid ", first->pid())), std::string::npos)
      << second->Log();
  EXPECT_TRUE(first->Running());
}

TEST_F(EndToEndTest, WorkerDrainsOnSigtermAndTheJobIsRequeuedWithoutBlame) {
  StartCoordinator();
  ASSERT_TRUE(Submit(MakeSpec("drain", {5}, SlowProtocol())).ok());
  auto worker = StartWorker("drainer", {"--drain-timeout", "0"});
  ASSERT_TRUE(WaitFor(
      [&] {
        auto jobs = Jobs("drain");
        return jobs[0].state() == v1::JOB_STATE_RUNNING && jobs[0].episodes_stored() >= 1;
      },
      seconds(60)));
  worker->Signal(SIGTERM);
  EXPECT_EQ(worker->Wait(seconds(30)), 0) << worker->Log();
  const v1::JobInfo job = Jobs("drain")[0];
  EXPECT_EQ(job.state(), v1::JOB_STATE_QUEUED);
  EXPECT_EQ(job.failures(), 0);
  const v1::GetJobLogResponse log = JobLog(job.job_id());
  ASSERT_EQ(log.attempts_size(), 1);
  EXPECT_EQ(log.attempts(0).state(), v1::ATTEMPT_STATE_RELEASED);
  // Another worker finishes it with exact results.
  auto finisher = StartWorker("finisher");
  ASSERT_TRUE(WaitFinished("drain", seconds(120)));
  ExpectRowsEqualReference("drain", SlowProtocol());
}

}  // namespace e2e_test
}  // namespace totalgrad::testing
