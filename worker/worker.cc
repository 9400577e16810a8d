#include "worker/worker.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <random>
#include <set>
#include <thread>

#include "absl/strings/str_cat.h"
#include "server/common/rpc_client.h"

namespace totalgrad::worker {
namespace {

int64_t SteadyMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// Why an episode cannot be accepted as a result, or "" if it can.
std::string NonFiniteReason(const EpisodeOutcome& e) {
  const auto describe = [&](const char* field, double value) {
    return absl::StrCat("episode ", e.episode, ": ", field, " is not finite (", value, ")");
  };
  if (!std::isfinite(e.real_cost)) return describe("real_cost", e.real_cost);
  if (e.episode >= 1) {
    if (!std::isfinite(e.eval_cost_mean)) return describe("eval_cost_mean", e.eval_cost_mean);
    if (!std::isfinite(e.predicted_cost)) return describe("predicted_cost", e.predicted_cost);
  }
  for (auto [field, value] : {std::pair{"eval_cost_std", e.eval_cost_std},
                              std::pair{"optimisation_seconds", e.optimisation_seconds}}) {
    if (std::isinf(value)) return describe(field, value);
  }
  return "";
}

v1::EpisodeReport ToReport(const EpisodeOutcome& e) {
  v1::EpisodeReport report;
  report.set_episode(e.episode);
  report.set_real_cost(e.real_cost);
  report.set_eval_cost_mean(e.eval_cost_mean);
  report.set_eval_cost_std(e.eval_cost_std);
  report.set_predicted_cost(e.predicted_cost);
  report.set_optimisation_seconds(e.optimisation_seconds);
  report.set_details_json(e.details_json);
  return report;
}

std::string Describe(const v1::LeaseKey& key) {
  return absl::StrCat("job ", key.job_id(), " attempt ", key.attempt());
}

}  // namespace

struct Worker::ActiveLease {
  v1::Lease lease;
  // The fields below are guarded by Worker::mutex_.
  std::vector<v1::EpisodeReport> unacked;
  bool has_new = false;
  bool beat_in_flight = false;
  int64_t next_beat_ms = 0;
  int64_t backoff_ms = 200;
  std::string cancel_reason;
  std::string failure;
  // Read by the trial's thread without the lock.
  std::atomic<bool> cancel{false};
  std::atomic<bool> lost{false};
};

class Worker::Progress final : public TrialProgress {
 public:
  Progress(Worker* worker, std::shared_ptr<ActiveLease> active)
      : worker_(worker), active_(std::move(active)) {}
  void OnEpisode(const EpisodeOutcome& episode) override {
    const std::string reason = NonFiniteReason(episode);
    {
      std::lock_guard<std::mutex> lock(worker_->mutex_);
      if (!reason.empty()) {
        if (active_->failure.empty()) active_->failure = reason;
        active_->cancel = true;
      } else {
        active_->unacked.push_back(ToReport(episode));
        active_->has_new = true;
      }
    }
    worker_->changed_.notify_all();
  }
  bool ShouldCancel() override { return active_->cancel.load(); }

 private:
  Worker* worker_;
  std::shared_ptr<ActiveLease> active_;
};

Worker::Worker(WorkerOptions options, std::shared_ptr<grpc::Channel> channel, TrialRunner* runner,
               StudyRunner* study_runner)
    : options_(std::move(options)),
      stub_(v1::WorkerService::NewStub(std::move(channel))),
      runner_(runner),
      study_runner_(study_runner) {}

Worker::~Worker() = default;

WorkerSummary Worker::Run() {
  std::thread heartbeat([this] { HeartbeatLoop(); });
  std::vector<std::thread> slots;
  for (int slot = 0; slot < options_.slots; ++slot) {
    slots.emplace_back([this, slot] { SlotLoop(slot); });
  }
  for (auto& t : slots) t.join();
  finished_ = true;
  changed_.notify_all();
  heartbeat.join();
  std::lock_guard<std::mutex> lock(mutex_);
  return summary_;
}

void Worker::Drain() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!draining_.exchange(true)) {
      drain_started_ms_ = SteadyMs();
      spdlog::info("draining: no new leases; running trials have {} to finish",
                   absl::FormatDuration(options_.drain_timeout));
    }
    for (grpc::ClientContext* context : acquiring_) context->TryCancel();
  }
  changed_.notify_all();
}

void Worker::Stop() {
  stopping_ = true;
  Drain();
  CancelAll("worker stopping");
}

void Worker::CancelAll(const std::string& reason) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto& [job, active] : active_) {
      if (active->cancel_reason.empty()) active->cancel_reason = reason;
      active->cancel = true;
    }
  }
  changed_.notify_all();
}

void Worker::SlotLoop(int slot) {
  thread_local std::mt19937_64 random(std::random_device{}() + slot);
  int64_t last_work_ms = SteadyMs();
  int64_t backoff_ms = 200;
  while (!draining_ && !stopping_) {
    v1::AcquireLeaseRequest request;
    request.mutable_worker()->set_worker_id(options_.worker_id);
    request.mutable_worker()->set_host(options_.host);
    request.mutable_worker()->set_build(options_.build);
    request.mutable_worker()->set_slots(options_.slots);
    request.mutable_worker()->set_study_jobs(study_runner_ != nullptr);
    request.set_wait_ms(static_cast<int32_t>(absl::ToInt64Milliseconds(options_.acquire_wait)));
    v1::AcquireLeaseResponse response;
    grpc::ClientContext context;
    rpc::PrepareContext(&context, options_.token, options_.acquire_wait + options_.call_timeout,
                        /*wait_for_ready=*/true);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (draining_) break;
      acquiring_.push_back(&context);
    }
    const grpc::Status status = stub_->AcquireLease(&context, request, &response);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      acquiring_.erase(std::find(acquiring_.begin(), acquiring_.end(), &context));
    }
    if (draining_ || stopping_) {
      // A lease granted while we were cancelling the poll is given back.
      if (status.ok() && response.granted()) {
        auto active = std::make_shared<ActiveLease>();
        active->lease = response.lease();
        Finish(active, absl::CancelledError("drain"));
      }
      break;
    }
    if (!status.ok()) {
      spdlog::warn("slot {}: AcquireLease failed: {} ({}); retrying", slot, status.error_message(),
                   static_cast<int>(status.error_code()));
      std::uniform_real_distribution<double> jitter(0.8, 1.2);
      std::unique_lock<std::mutex> lock(mutex_);
      changed_.wait_for(lock, std::chrono::milliseconds(static_cast<int64_t>(backoff_ms * jitter(random))),
                        [&] { return draining_ || stopping_; });
      backoff_ms = std::min<int64_t>(backoff_ms * 2, 10'000);
      continue;
    }
    backoff_ms = 200;
    if (!response.granted()) {
      if (options_.max_idle != absl::InfiniteDuration() &&
          SteadyMs() - last_work_ms > absl::ToInt64Milliseconds(options_.max_idle)) {
        spdlog::info("slot {}: idle for {}; exiting", slot, absl::FormatDuration(options_.max_idle));
        break;
      }
      continue;
    }
    RunLease(response.lease());
    last_work_ms = SteadyMs();
  }
}

void Worker::RunLease(const v1::Lease& lease) {
  auto active = std::make_shared<ActiveLease>();
  active->lease = lease;
  active->next_beat_ms = SteadyMs() + std::max(100, lease.heartbeat_interval_ms());
  {
    std::lock_guard<std::mutex> lock(mutex_);
    active_[lease.key().job_id()] = active;
    if (stopping_) {
      active->cancel = true;
      active->cancel_reason = "worker stopping";
    }
  }
  const bool is_study = lease.kind() == v1::JOB_KIND_STUDY;
  if (is_study) {
    spdlog::info("{}: study {} (seed {})", Describe(lease.key()), lease.variant(), lease.seed());
  } else {
    spdlog::info("{}: {} seed {} {} ({} episodes)", Describe(lease.key()), lease.method(),
                 lease.seed(), lease.variant(), lease.episodes_expected());
  }
  OptionList options;
  for (const auto& option : lease.options()) options.emplace_back(option.key(), option.value());
  Progress progress(this, active);
  absl::StatusOr<TrialOutcome> result;
  absl::StatusOr<StudyOutcome> study = absl::UnknownError("not a study");
  const char* what = is_study ? "the study" : "the trial";
  try {
    if (!is_study) {
      result = runner_->Run(options, &progress);
    } else if (study_runner_ == nullptr) {
      result = absl::FailedPreconditionError("this worker cannot run study jobs");
    } else {
      study = study_runner_->Run(lease.study_spec_json(), &progress);
      result = study.ok() ? absl::StatusOr<TrialOutcome>(TrialOutcome{})
                          : absl::StatusOr<TrialOutcome>(study.status());
    }
  } catch (const std::exception& error) {
    result = absl::InternalError(absl::StrCat(what, " threw: ", error.what()));
  } catch (...) {
    result = absl::InternalError(absl::StrCat(what, " threw a non-standard exception"));
  }
  {
    // Take the lease away from the heartbeat thread before the final report.
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait(lock, [&] { return !active->beat_in_flight; });
    active_.erase(lease.key().job_id());
  }
  changed_.notify_all();
  Finish(active, result, is_study && result.ok() && study.ok() ? &*study : nullptr);
}

void Worker::HeartbeatLoop() {
  std::unique_lock<std::mutex> lock(mutex_);
  while (!finished_) {
    const int64_t now = SteadyMs();
    if (draining_ && !stopping_ &&
        now - drain_started_ms_ > absl::ToInt64Milliseconds(options_.drain_timeout)) {
      for (auto& [job, active] : active_) {
        if (!active->cancel) {
          active->cancel_reason = "drain timeout";
          active->cancel = true;
        }
      }
    }
    int64_t wake = now + 1000;
    std::vector<std::shared_ptr<ActiveLease>> due;
    for (auto& [job, active] : active_) {
      if (active->beat_in_flight || active->lost) continue;
      if (active->has_new || now >= active->next_beat_ms) {
        due.push_back(active);
      } else {
        wake = std::min(wake, active->next_beat_ms);
      }
    }
    if (due.empty()) {
      changed_.wait_until(lock, std::chrono::steady_clock::time_point(std::chrono::milliseconds(wake)),
                          [&] {
                            if (finished_) return true;
                            for (auto& [job, active] : active_) {
                              if (active->has_new && !active->beat_in_flight && !active->lost) {
                                return true;
                              }
                            }
                            return false;
                          });
      continue;
    }
    for (auto& active : due) active->beat_in_flight = true;
    lock.unlock();
    for (auto& active : due) Beat(active);
    lock.lock();
    for (auto& active : due) active->beat_in_flight = false;
    changed_.notify_all();
  }
}

void Worker::Beat(const std::shared_ptr<ActiveLease>& active) {
  v1::HeartbeatRequest request;
  request.set_worker_id(options_.worker_id);
  *request.mutable_lease() = active->lease.key();
  std::set<int> sent;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& episode : active->unacked) {
      if (request.episodes_size() >= 1000) break;
      *request.add_episodes() = episode;
      sent.insert(episode.episode());
    }
    active->has_new = false;
  }
  v1::HeartbeatResponse response;
  grpc::ClientContext context;
  rpc::PrepareContext(&context, options_.token, options_.call_timeout, /*wait_for_ready=*/false);
  const grpc::Status status = stub_->Heartbeat(&context, request, &response);
  bool drain = false;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const int64_t now = SteadyMs();
    const int64_t interval = std::max(100, active->lease.heartbeat_interval_ms());
    if (status.ok()) {
      std::erase_if(active->unacked,
                    [&](const v1::EpisodeReport& e) { return sent.count(e.episode()) > 0; });
      active->next_beat_ms = now + interval;
      active->backoff_ms = 200;
      if (response.directive() == v1::DIRECTIVE_CANCEL && !active->cancel) {
        active->cancel_reason = "sweep cancelled";
        active->cancel = true;
        spdlog::info("{}: cancelled by the coordinator", Describe(active->lease.key()));
      } else if (response.directive() == v1::DIRECTIVE_DRAIN) {
        drain = true;
      }
    } else if (status.error_code() == grpc::StatusCode::ABORTED ||
               status.error_code() == grpc::StatusCode::NOT_FOUND) {
      spdlog::warn("{}: the coordinator refused the lease ({}); dropping the trial",
                   Describe(active->lease.key()), status.error_message());
      active->lost = true;
      active->cancel = true;
    } else if (status.error_code() == grpc::StatusCode::INVALID_ARGUMENT) {
      // A report the coordinator will never accept: fail the attempt with the reason.
      active->failure = absl::StrCat("the coordinator refused a report: ", status.error_message());
      active->unacked.clear();
      active->cancel = true;
    } else {
      // Unreachable or busy: keep the episodes and try again soon, with
      // jitter so many workers do not retry in lockstep after an outage.
      thread_local std::mt19937_64 random(std::random_device{}());
      std::uniform_real_distribution<double> jitter(0.8, 1.2);
      active->next_beat_ms =
          now + static_cast<int64_t>(std::min(active->backoff_ms, interval) * jitter(random));
      active->backoff_ms = std::min<int64_t>(active->backoff_ms * 2, interval);
      spdlog::warn("{}: heartbeat failed: {}; episodes kept for replay",
                   Describe(active->lease.key()), status.error_message());
    }
  }
  if (drain) {
    spdlog::info("the coordinator asked this worker to drain");
    Drain();
  }
}

grpc::Status Worker::SendStudyRows(const v1::LeaseKey& key, const StudyOutcome& study,
                                   const rpc::RetryPolicy& policy) {
  // Batches stay far below the 4 MiB message limit and the coordinator's
  // 1000 rows per call.
  constexpr size_t kMaxBatchBytes = 1 << 20;
  constexpr int kMaxBatchRows = 500;
  size_t next_cell = 0, next_reference = 0;
  while (next_cell < study.cells.size() || next_reference < study.references.size()) {
    v1::HeartbeatRequest request;
    request.set_worker_id(options_.worker_id);
    *request.mutable_lease() = key;
    size_t bytes = 0;
    int rows = 0;
    while (rows < kMaxBatchRows && bytes < kMaxBatchBytes) {
      if (next_reference < study.references.size()) {
        bytes += study.references[next_reference].ByteSizeLong();
        *request.add_study_references() = study.references[next_reference++];
      } else if (next_cell < study.cells.size()) {
        bytes += study.cells[next_cell].ByteSizeLong();
        *request.add_study_cells() = study.cells[next_cell++];
      } else {
        break;
      }
      ++rows;
    }
    const grpc::Status status =
        rpc::CallWithRetry(policy, options_.token, [&](grpc::ClientContext* context) {
          v1::HeartbeatResponse response;
          return stub_->Heartbeat(context, request, &response);
        });
    if (!status.ok()) return status;
  }
  return grpc::Status::OK;
}

void Worker::Finish(const std::shared_ptr<ActiveLease>& active,
                    const absl::StatusOr<TrialOutcome>& result, const StudyOutcome* study) {
  const v1::LeaseKey& key = active->lease.key();
  if (active->lost) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++summary_.dropped;
    return;
  }
  std::string failure, cancel_reason;
  std::vector<v1::EpisodeReport> unacked;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    failure = active->failure;
    cancel_reason = active->cancel_reason;
    unacked = active->unacked;
  }
  if (failure.empty() && !result.ok() && result.status().code() != absl::StatusCode::kCancelled) {
    failure = result.status().ToString();
  }
  rpc::RetryPolicy policy;
  policy.call_timeout = options_.call_timeout;
  policy.give_up_after = stopping_ ? absl::Seconds(10) : options_.orphan_timeout;
  enum class Kind { kComplete, kFail, kRelease } kind;
  grpc::Status status;
  if (!failure.empty()) {
    kind = Kind::kFail;
  } else if (!result.ok()) {
    kind = Kind::kRelease;
  } else {
    kind = Kind::kComplete;
    v1::CompleteRequest request;
    request.set_worker_id(options_.worker_id);
    *request.mutable_lease() = key;
    if (study != nullptr) {
      // Rows first (each batch a repeatable heartbeat), then the totals.
      status = SendStudyRows(key, *study, policy);
      request.set_study_cells_total(static_cast<int32_t>(study->cells.size()));
      request.set_study_references_total(static_cast<int32_t>(study->references.size()));
    } else {
      for (const auto& e : unacked) *request.add_episodes() = e;
      request.set_episodes_total(result->episodes);
      request.set_success(result->success);
      request.set_final_eval_cost(result->final_eval_cost);
    }
    if (status.ok()) {
      status = rpc::CallWithRetry(policy, options_.token, [&](grpc::ClientContext* context) {
        v1::CompleteResponse response;
        return stub_->Complete(context, request, &response);
      });
    }
    if (status.error_code() == grpc::StatusCode::INVALID_ARGUMENT ||
        status.error_code() == grpc::StatusCode::FAILED_PRECONDITION) {
      failure = absl::StrCat("the coordinator refused the completion: ", status.error_message());
      unacked.clear();
      kind = Kind::kFail;
    }
  }
  if (kind == Kind::kFail) {
    v1::FailRequest request;
    request.set_worker_id(options_.worker_id);
    *request.mutable_lease() = key;
    for (const auto& e : unacked) *request.add_episodes() = e;
    request.set_error(failure);
    status = rpc::CallWithRetry(policy, options_.token, [&](grpc::ClientContext* context) {
      v1::FailResponse response;
      return stub_->Fail(context, request, &response);
    });
    if (status.error_code() == grpc::StatusCode::INVALID_ARGUMENT) {
      request.clear_episodes();  // keep the verdict even if an episode is refused
      status = rpc::CallWithRetry(policy, options_.token, [&](grpc::ClientContext* context) {
        v1::FailResponse response;
        return stub_->Fail(context, request, &response);
      });
    }
  } else if (kind == Kind::kRelease) {
    v1::ReleaseRequest request;
    request.set_worker_id(options_.worker_id);
    *request.mutable_lease() = key;
    request.set_reason(cancel_reason.empty() ? "cancelled" : cancel_reason);
    status = rpc::CallWithRetry(policy, options_.token, [&](grpc::ClientContext* context) {
      v1::ReleaseResponse response;
      return stub_->Release(context, request, &response);
    });
  }
  std::lock_guard<std::mutex> lock(mutex_);
  if (!status.ok()) {
    ++summary_.dropped;
    spdlog::warn("{}: final report not accepted: {} ({})", Describe(key), status.error_message(),
                 static_cast<int>(status.error_code()));
    return;
  }
  switch (kind) {
    case Kind::kComplete:
      ++summary_.completed;
      if (study != nullptr) {
        spdlog::info("{}: study completed ({} cells, {} references)", Describe(key),
                     study->cells.size(), study->references.size());
      } else {
        spdlog::info("{}: completed (success={}, final eval cost {})", Describe(key),
                     result->success, result->final_eval_cost);
      }
      break;
    case Kind::kFail:
      ++summary_.failed;
      spdlog::warn("{}: failed: {}", Describe(key), failure);
      break;
    case Kind::kRelease:
      ++summary_.released;
      spdlog::info("{}: released ({})", Describe(key), cancel_reason);
      break;
  }
}

}  // namespace totalgrad::worker
