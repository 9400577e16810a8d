// Load benchmark of the coordinator (not a timed test): N concurrent worker
// connections lease trivial jobs and report every episode with its own
// heartbeat, as real workers do, against a real coordinator with its SQLite
// file (WAL, synchronous=FULL) on loopback. Reports the sustained episode
// reports per second and checks that every row is stored exactly once.
//
//   service_load_bench [--workers 64] [--jobs 512] [--episodes 16] [--dir /tmp]
//
// Prints one JSON object.
#include <grpcpp/create_channel.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <iostream>
#include <set>
#include <thread>

#include "absl/strings/str_cat.h"
#include "server/service/coordinator.h"
#include "totalgrad/v1/control_service.grpc.pb.h"
#include "totalgrad/v1/worker_service.grpc.pb.h"

namespace {

std::unique_ptr<grpc::ClientContext> Context(int timeout_ms = 30000) {
  auto context = std::make_unique<grpc::ClientContext>();
  context->set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(timeout_ms));
  return context;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"coordinator load benchmark"};
  int workers = 64, jobs = 512, episodes = 16;
  std::string dir = std::filesystem::temp_directory_path().string();
  app.add_option("--workers", workers, "concurrent worker connections")->capture_default_str();
  app.add_option("--jobs", jobs, "jobs in the sweep")->capture_default_str();
  app.add_option("--episodes", episodes, "episodes per job")->capture_default_str();
  app.add_option("--dir", dir, "where the database goes")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

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

  totalgrad::v1::SubmitSweepRequest submit;
  auto* spec = submit.mutable_spec();
  spec->set_name("load");
  auto* method = spec->add_grid();
  method->set_key("method");
  method->add_values("RP");
  auto* seed = spec->add_grid();
  seed->set_key("seed");
  for (int s = 0; s < jobs; ++s) seed->add_values(std::to_string(s));
  auto* protocol = spec->add_protocol();
  protocol->set_key("episodes");
  protocol->set_value(std::to_string(episodes - 1));
  totalgrad::v1::SubmitSweepResponse submitted;
  grpc::Status status = control->SubmitSweep(Context().get(), submit, &submitted);
  if (!status.ok()) {
    std::cerr << "submit: " << status.error_message() << "\n";
    return 1;
  }

  std::atomic<int64_t> reports{0}, errors{0};
  const auto start = std::chrono::steady_clock::now();
  std::vector<std::thread> threads;
  for (int w = 0; w < workers; ++w) {
    threads.emplace_back([&, w] {
      // One connection per worker, as separate worker processes would have.
      grpc::ChannelArguments arguments;
      arguments.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
      arguments.SetInt("totalgrad.bench.worker", w);
      auto stub = totalgrad::v1::WorkerService::NewStub(grpc::CreateCustomChannel(
          address, grpc::InsecureChannelCredentials(), arguments));
      const std::string id = absl::StrCat("bench-", w);
      while (true) {
        totalgrad::v1::AcquireLeaseRequest acquire;
        acquire.mutable_worker()->set_worker_id(id);
        acquire.mutable_worker()->set_slots(1);
        acquire.set_wait_ms(0);
        totalgrad::v1::AcquireLeaseResponse lease;
        if (!stub->AcquireLease(Context().get(), acquire, &lease).ok()) {
          ++errors;
          continue;
        }
        if (!lease.granted()) return;
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
      }
    });
  }
  for (auto& t : threads) t.join();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  // Every row stored once: export and count distinct (job, episode).
  totalgrad::v1::ExportEpisodesRequest export_request;
  export_request.set_sweep_name("load");
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
  status = reader->Finish();
  totalgrad::v1::SweepRequest sweep_request;
  sweep_request.set_name("load");
  totalgrad::v1::SweepInfo sweep;
  control->GetSweep(Context().get(), sweep_request, &sweep);
  const bool every_row_once = status.ok() && rows == static_cast<int64_t>(jobs) * episodes &&
                              static_cast<int64_t>(distinct.size()) == rows &&
                              sweep.jobs_completed() == jobs;
  std::cout << "{\"workers\": " << workers << ", \"jobs\": " << jobs << ", \"episodes_per_job\": "
            << episodes << ", \"episode_reports\": " << reports << ", \"errors\": " << errors
            << ", \"seconds\": " << seconds << ", \"reports_per_second\": " << reports / seconds
            << ", \"rows_stored\": " << rows << ", \"distinct_rows\": " << distinct.size()
            << ", \"jobs_completed\": " << sweep.jobs_completed()
            << ", \"every_row_stored_once\": " << (every_row_once ? "true" : "false") << "}\n";
  (*coordinator)->Shutdown();
  std::filesystem::remove(db);
  return every_row_once ? 0 : 1;
}
