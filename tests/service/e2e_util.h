// A coordinator process and worker processes for end-to-end tests: real
// binaries, real gRPC on loopback, a real SQLite file per test.
#ifndef TOTALGRAD_TESTS_SERVICE_E2E_UTIL_H_
#define TOTALGRAD_TESTS_SERVICE_E2E_UTIL_H_

#include <gtest/gtest.h>
#include <grpcpp/channel.h>

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "tests/service/process_util.h"
#include "totalgrad/v1/control_service.grpc.pb.h"
#include "totalgrad/v1/worker_service.grpc.pb.h"
#include "worker/job_runner.h"

namespace totalgrad::testing {

inline constexpr char kWorkerToken[] = "worker-token-0123456789abcdef";
inline constexpr char kUserToken[] = "user-token-0123456789abcdef";

// Options of a trial that takes ~0.05 s (3 episodes).
OptionPairs TinyProtocol();
// Options of a trial that takes a few seconds (9 episodes), for kill tests.
OptionPairs SlowProtocol();

// One sweep spec: method RP, seeds, and the given protocol.
v1::SweepSpec MakeSpec(const std::string& name, const std::vector<int>& seeds,
                       const OptionPairs& protocol);

// Runs the trial in this process with the real runner: the reference values
// that every stored row must equal exactly (trials are deterministic).
std::vector<worker::EpisodeOutcome> ReferenceEpisodes(const OptionPairs& options);

class ServiceFixture : public ::testing::Test {
 protected:
  void SetUp() override;
  void TearDown() override;

  // Starts the coordinator (plaintext on loopback, tokens, heartbeats every
  // 0.2 s, leases lost after `lease_timeout_seconds`) on `port` (0: any) and
  // connects the stubs. Fails the test if it does not start. Tests that wait
  // for a lease to be lost pass a short timeout; the default leaves room for a
  // loaded CI machine.
  void StartCoordinator(int port = 0, std::vector<std::string> extra = {},
                        double lease_timeout_seconds = 5);
  // A worker with a state directory of this test; `token_file` "" means the
  // worker token.
  std::unique_ptr<Process> StartWorker(const std::string& id, std::vector<std::string> extra = {},
                                       const std::string& token_file = "");

  grpc::Status Submit(const v1::SweepSpec& spec, v1::SubmitSweepResponse* response = nullptr);
  v1::SweepInfo Sweep(const std::string& name);
  bool WaitFinished(const std::string& name, std::chrono::milliseconds timeout);
  std::vector<v1::JobInfo> Jobs(const std::string& sweep);
  std::vector<v1::EpisodeRow> Export(const std::string& sweep, bool all_attempts);
  v1::GetJobLogResponse JobLog(int64_t job_id);
  // Expects the completed sweep's rows to equal the reference runs exactly:
  // every job, every episode, once, with identical values.
  void ExpectRowsEqualReference(const std::string& sweep, const OptionPairs& protocol);

  // A context with deadline and the given token ("" for none).
  static std::unique_ptr<grpc::ClientContext> Context(const std::string& token,
                                                      int timeout_ms = 10000);

  std::string dir_;
  std::string db_;
  int port_ = 0;
  std::unique_ptr<Process> coordinator_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::ControlService::Stub> control_;
  std::unique_ptr<v1::WorkerService::Stub> worker_stub_;
  int coordinator_starts_ = 0;
};

}  // namespace totalgrad::testing

#endif  // TOTALGRAD_TESTS_SERVICE_E2E_UTIL_H_
