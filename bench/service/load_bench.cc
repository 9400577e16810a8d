// Load benchmark of the coordinator (not a timed test): N concurrent worker
// connections lease trivial jobs and report every episode with its own
// heartbeat, as real workers do, against a real coordinator with its SQLite
// file (WAL, synchronous=FULL) on loopback. Reports the sustained episode
// reports per second and checks that every row is stored exactly once.
//
//   service_load_bench [--workers 64] [--jobs 512] [--episodes 16] [--dir /tmp]
//                      [--queued Q] [--max-seconds S]
//
// With --queued Q the store holds Q queued jobs (sweeps of at most 100,000,
// the per-sweep limit) and the workers run --jobs of them, so the cost of a
// lease and a completion can be measured against the queue's length
// (issue 28 item 2). The coordinator runs in this process; its CPU time is
// the process's less the fake workers' own threads'. Every worker connects
// first (connect_seconds); the clock and the CPU count start once all are
// connected, since real workers connect once and then run for hours.
//
// Prints one JSON object.
#include <grpcpp/create_channel.h>
#include <sys/resource.h>
#include <unistd.h>
#include <time.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <iostream>
#include <set>
#include <thread>

#include "absl/strings/str_cat.h"
#include "absl/synchronization/mutex.h"
#include "server/service/coordinator.h"
#include "tests/testutil/proc_memory.h"
#include "totalgrad/v1/control_service.grpc.pb.h"
#include "totalgrad/v1/worker_service.grpc.pb.h"

namespace {

std::unique_ptr<grpc::ClientContext> Context(int timeout_ms = 30000) {
  auto context = std::make_unique<grpc::ClientContext>();
  context->set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(timeout_ms));
  return context;
}

double ProcessCpuSeconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_utime.tv_sec + usage.ru_stime.tv_sec +
         1e-6 * (usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
}

// Resident set of this process now, and its peak (MB).
double ResidentMb() {
  return totalgrad::testing::ProcStatusMb(totalgrad::testing::kThisProcess, "VmRSS");
}

double PeakResidentMb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;
}

double ThreadCpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"coordinator load benchmark"};
  int workers = 64, jobs = 512, episodes = 16;
  int64_t queued = 0;
  double max_seconds = 600, settle_seconds = 0;
  std::string dir = std::filesystem::temp_directory_path().string();
  app.add_option("--workers", workers, "concurrent worker connections")->capture_default_str();
  app.add_option("--jobs", jobs, "jobs in the sweep")->capture_default_str();
  app.add_option("--episodes", episodes, "episodes per job")->capture_default_str();
  app.add_option("--dir", dir, "where the database goes")->capture_default_str();
  app.add_option("--queued", queued, "jobs in the store (default: --jobs); the workers run --jobs of them")
      ->check(CLI::Range(int64_t{0}, int64_t{10'000'000}));
  app.add_option("--max-seconds", max_seconds, "stop the workers after this long")
      ->capture_default_str();
  app.add_option("--settle-seconds", settle_seconds,
                 "wait this long after submitting and report the resident memory then")
      ->capture_default_str();
  int malloc_arenas = totalgrad::service::kCoordinatorMallocArenas;
  app.add_option("--malloc-arenas", malloc_arenas,
                 "glibc malloc arenas at most (0: glibc's default of 8 per core)")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  // As totalgrad-coordinator's main does (server/main.cc).
  totalgrad::service::LimitMallocArenas(malloc_arenas);
  absl::SetMutexDeadlockDetectionMode(absl::OnDeadlockCycle::kIgnore);

  const std::string db = absl::StrCat(dir, "/totalgrad_load_bench_", getpid(), ".db");
  totalgrad::service::CoordinatorOptions options;
  options.database = db;
  options.listen = "127.0.0.1:0";
  options.insecure = true;
  auto coordinator = totalgrad::service::Coordinator::Start(options);
  if (!coordinator.ok()) {
    std::cerr << coordinator.status() << "\n";
    return 1;
  }
  const std::string address = absl::StrCat("127.0.0.1:", (*coordinator)->port());
  auto control = totalgrad::v1::ControlService::NewStub(
      grpc::CreateChannel(address, grpc::InsecureChannelCredentials()));

  // The sweeps: "load-0" holds the jobs the workers run first (ordinals in
  // order), the rest stay queued behind them.
  queued = std::max<int64_t>(queued, jobs);
  constexpr int64_t kPerSweep = 100'000;
  const auto submit_start = std::chrono::steady_clock::now();
  for (int64_t first = 0, index = 0; first < queued; first += kPerSweep, ++index) {
    totalgrad::v1::SubmitSweepRequest submit;
    auto* spec = submit.mutable_spec();
    spec->set_name(absl::StrCat("load-", index));
    auto* method = spec->add_grid();
    method->set_key("method");
    method->add_values("RP");
    auto* seed = spec->add_grid();
    seed->set_key("seed");
    for (int64_t s = first; s < std::min(queued, first + kPerSweep); ++s) {
      seed->add_values(std::to_string(s));
    }
    auto* protocol = spec->add_protocol();
    protocol->set_key("episodes");
    protocol->set_value(std::to_string(episodes - 1));
    totalgrad::v1::SubmitSweepResponse submitted;
    grpc::Status status = control->SubmitSweep(Context(600000).get(), submit, &submitted);
    if (!status.ok()) {
      std::cerr << "submit: " << status.error_message() << "\n";
      return 1;
    }
  }
  const double submit_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - submit_start).count();
  const double resident_after_submit_mb = ResidentMb();
  std::this_thread::sleep_for(std::chrono::duration<double>(settle_seconds));
  const double resident_after_settle_mb = ResidentMb();

  std::atomic<int64_t> reports{0}, errors{0}, leased{0}, completed{0};
  absl::Mutex cpu_mutex;
  double workers_cpu_seconds = 0;
  // The start line: workers connect, then wait until all have.
  absl::Mutex start_mutex;
  int connected = 0;
  bool go = false;
  std::chrono::steady_clock::time_point deadline;
  const auto connect_start = std::chrono::steady_clock::now();
  std::vector<std::thread> threads;
  for (int w = 0; w < workers; ++w) {
    threads.emplace_back([&, w] {
      // One connection per worker, as separate worker processes would have.
      grpc::ChannelArguments arguments;
      arguments.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
      arguments.SetInt("totalgrad.bench.worker", w);
      auto channel =
          grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), arguments);
      channel->WaitForConnected(
          gpr_time_add(gpr_now(GPR_CLOCK_MONOTONIC), gpr_time_from_seconds(120, GPR_TIMESPAN)));
      auto stub = totalgrad::v1::WorkerService::NewStub(channel);
      {
        absl::MutexLock lock(&start_mutex);
        ++connected;
        start_mutex.Await(absl::Condition(&go));
      }
      const double cpu_at_start = ThreadCpuSeconds();
      const std::string id = absl::StrCat("bench-", w);
      const auto account = [&] {
        absl::MutexLock lock(&cpu_mutex);
        workers_cpu_seconds += ThreadCpuSeconds() - cpu_at_start;
      };
      while (true) {
        if (leased.fetch_add(1) >= jobs || std::chrono::steady_clock::now() > deadline) {
          account();
          return;
        }
        totalgrad::v1::AcquireLeaseRequest acquire;
        acquire.mutable_worker()->set_worker_id(id);
        acquire.mutable_worker()->set_slots(1);
        acquire.set_wait_ms(0);
        totalgrad::v1::AcquireLeaseResponse lease;
        if (const grpc::Status status = stub->AcquireLease(Context().get(), acquire, &lease);
            !status.ok()) {
          if (++errors <= 5) {
            std::cerr << "AcquireLease: " << status.error_code() << " " << status.error_message()
                      << "\n";
          }
          continue;
        }
        if (!lease.granted()) {
          account();
          return;
        }
        for (int e = 0; e < episodes; ++e) {
          totalgrad::v1::HeartbeatRequest beat;
          beat.set_worker_id(id);
          *beat.mutable_lease() = lease.lease().key();
          auto* report = beat.add_episodes();
          report->set_episode(e);
          report->set_real_cost(e);
          report->set_eval_cost_mean(e == 0 ? std::nan("") : e);
          report->set_predicted_cost(e == 0 ? std::nan("") : e);
          totalgrad::v1::HeartbeatResponse answer;
          if (stub->Heartbeat(Context().get(), beat, &answer).ok()) {
            ++reports;
          } else {
            ++errors;
            --e;  // retry the same episode (idempotent)
          }
        }
        totalgrad::v1::CompleteRequest complete;
        complete.set_worker_id(id);
        *complete.mutable_lease() = lease.lease().key();
        complete.set_episodes_total(episodes);
        complete.set_success(true);
        complete.set_final_eval_cost(1);
        totalgrad::v1::CompleteResponse done;
        while (!stub->Complete(Context().get(), complete, &done).ok()) ++errors;
        ++completed;
      }
    });
  }
  double connect_seconds = 0, cpu_before = 0;
  totalgrad::storage::WriteCounts writes_before;
  std::chrono::steady_clock::time_point start;
  {
    absl::MutexLock lock(&start_mutex);
    const auto all_connected = [&] { return connected == workers; };
    start_mutex.Await(absl::Condition(&all_connected));
    connect_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() -
                                                    connect_start).count();
    cpu_before = ProcessCpuSeconds();
    writes_before = (*coordinator)->store()->write_counts();
    start = std::chrono::steady_clock::now();
    deadline = start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                           std::chrono::duration<double>(max_seconds));
    go = true;
  }
  for (auto& t : threads) t.join();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double coordinator_cpu_seconds = ProcessCpuSeconds() - cpu_before - workers_cpu_seconds;
  // Group commit: how many writes each fsynced transaction carried.
  const totalgrad::storage::WriteCounts writes_after = (*coordinator)->store()->write_counts();
  const int64_t writes = writes_after.writes - writes_before.writes;
  const int64_t commits = writes_after.commits - writes_before.commits;

  // Every row stored once: export and count distinct (job, episode).
  totalgrad::v1::ExportEpisodesRequest export_request;
  export_request.set_sweep_name("load-0");
  export_request.set_all_attempts(true);
  auto context = Context(300000);
  auto reader = control->ExportEpisodes(context.get(), export_request);
  std::set<std::pair<int64_t, int>> distinct;
  int64_t rows = 0;
  totalgrad::v1::ExportEpisodesResponse batch;
  while (reader->Read(&batch)) {
    for (const auto& row : batch.rows()) {
      ++rows;
      distinct.insert({row.job_id(), row.report().episode()});
    }
  }
  const grpc::Status status = reader->Finish();
  totalgrad::v1::SweepRequest sweep_request;
  sweep_request.set_name("load-0");
  totalgrad::v1::SweepInfo sweep;
  control->GetSweep(Context().get(), sweep_request, &sweep);
  const int64_t jobs_done = completed.load();
  const bool every_row_once = status.ok() && rows == jobs_done * episodes &&
                              static_cast<int64_t>(distinct.size()) == rows &&
                              sweep.jobs_completed() == jobs_done;
  std::cout << "{\"workers\": " << workers << ", \"malloc_arenas\": " << malloc_arenas
            << ", \"jobs_queued\": " << queued
            << ", \"submit_seconds\": " << submit_seconds << ", \"jobs\": " << jobs
            << ", \"jobs_completed_by_workers\": " << jobs_done
            << ", \"lease_complete_per_second\": " << jobs_done / seconds
            << ", \"coordinator_cpu_seconds\": " << coordinator_cpu_seconds
            << ", \"coordinator_cpu_ms_per_job\": " << 1000 * coordinator_cpu_seconds / std::max<int64_t>(jobs_done, 1)
            << ", \"connect_seconds\": " << connect_seconds
            << ", \"writes\": " << writes << ", \"commits\": " << commits
            << ", \"writes_per_commit\": " << static_cast<double>(writes) / std::max<int64_t>(commits, 1)
            << ", \"resident_mb_after_submit\": " << resident_after_submit_mb
            << ", \"settle_seconds\": " << settle_seconds
            << ", \"resident_mb_after_settle\": " << resident_after_settle_mb
            << ", \"resident_mb_at_end\": " << ResidentMb()
            << ", \"peak_resident_mb\": " << PeakResidentMb()
            << ", \"database_bytes\": " << std::filesystem::file_size(db)
            << ", \"episodes_per_job\": "
            << episodes << ", \"episode_reports\": " << reports << ", \"errors\": " << errors
            << ", \"seconds\": " << seconds << ", \"reports_per_second\": " << reports / seconds
            << ", \"rows_stored\": " << rows << ", \"distinct_rows\": " << distinct.size()
            << ", \"jobs_completed\": " << sweep.jobs_completed()
            << ", \"every_row_stored_once\": " << (every_row_once ? "true" : "false") << "}\n";
  (*coordinator)->Shutdown();
  std::filesystem::remove(db);
  return every_row_once ? 0 : 1;
}
