// The worker runtime (worker.h): leases, the slots that run them, heartbeats,
// drain and stop. How an attempt ends (its final report) is in
// worker_final_reports.cc.
#include "worker/worker.h"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cmath>
#include <random>
#include <set>
#include <thread>

#include "absl/strings/str_cat.h"
#include "absl/strings/match.h"
#include "absl/strings/ascii.h"
#include "absl/strings/str_format.h"
#include "absl/strings/strip.h"
#include "runtime/record_proto.h"
#include "runtime/rpc_client.h"
#include "worker/worker_internal.h"

namespace totalgrad::worker {
namespace {

std::string RandomInstance() {
  std::random_device device;
  std::mt19937_64 random((static_cast<uint64_t>(device()) << 32) ^ device() ^
                         static_cast<uint64_t>(getpid()));
  return absl::StrFormat("%016x", random());
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
                              std::pair{"optimisation_seconds", e.optimisation_seconds},
                              std::pair{"cpu_seconds", e.cpu_seconds}}) {
    if (std::isinf(value)) return describe(field, value);
  }
  return "";
}

v1::EpisodeReport ToReport(const EpisodeOutcome& e) {
  v1::EpisodeReport report;
  // The record by name (record_proto.h; cpu_seconds absent when NaN).
  record_proto::RecordToProto<learner::EpisodeSummary>(learner::EpisodeFields(), e, &report);
  report.set_details_json(e.details_json);
  return report;
}

}  // namespace

using worker_internal::Describe;
using worker_internal::IsAuthError;
using worker_internal::IsLeaseGone;

class Worker::Progress final : public JobProgress {
 public:
  Progress(Worker* worker, std::shared_ptr<ActiveLease> active)
      : worker_(worker), active_(std::move(active)) {}
  void OnEpisode(const EpisodeOutcome& episode) override {
    const std::string reason = NonFiniteReason(episode);
    {
      absl::MutexLock lock(&worker_->mutex_);
      if (!reason.empty()) {
        if (active_->failure.empty()) active_->failure = reason;
        active_->cancel = true;
      } else {
        active_->unacked.push_back(ToReport(episode));
        active_->has_new = true;
      }
    }
  }
  bool ShouldCancel() override { return active_->cancel.load(); }
  void OnCheckpoint(int episode, int format_version, std::string data) override {
    {
      absl::MutexLock lock(&worker_->mutex_);
      if (data.size() > kMaxCheckpointBytes) {
        // The coordinator would refuse it: the trial goes on without one.
        if (!active_->checkpoint_too_big) {
          spdlog::warn("{}: the checkpoint after episode {} is {} bytes, over {}; not sent (this "
                       "attempt cannot be resumed)",
                       Describe(active_->lease.key()), episode, data.size(), kMaxCheckpointBytes);
        }
        active_->checkpoint_too_big = true;
        return;
      }
      v1::TrialCheckpoint checkpoint;
      checkpoint.set_episode(episode);
      checkpoint.set_format_version(format_version);
      checkpoint.set_data(std::move(data));
      active_->checkpoint = std::move(checkpoint);
      active_->has_new = true;
    }
  }

 private:
  Worker* worker_;
  std::shared_ptr<ActiveLease> active_;
};

namespace {
WorkerOptions WithInstance(WorkerOptions options) {
  if (options.instance.empty()) options.instance = RandomInstance();
  return options;
}
JobRunners WithoutNull(JobRunners runners) {
  std::erase_if(runners, [](const auto& entry) { return entry.second == nullptr; });
  return runners;
}
}  // namespace

Worker::Worker(WorkerOptions options, std::shared_ptr<grpc::Channel> channel, JobRunners runners,
               Clock* clock)
    : options_(WithInstance(std::move(options))),
      stub_(v1::WorkerService::NewStub(std::move(channel))),
      runners_(WithoutNull(std::move(runners))),
      own_clock_(clock == nullptr ? std::make_unique<SystemClock>() : nullptr),
      clock_(clock == nullptr ? own_clock_.get() : clock) {
  if (options_.walltime != absl::InfiniteDuration()) {
    walltime_end_ms_ = clock_->MonotonicMs() + absl::ToInt64Milliseconds(options_.walltime);
  }
}

namespace {

// UNSPECIFIED comes from a coordinator older than job kinds: a trial.
v1::JobKind KindOf(const v1::Lease& lease) {
  return lease.kind() == v1::JOB_KIND_UNSPECIFIED ? v1::JOB_KIND_TRIAL : lease.kind();
}

// What a runner reads of a lease (without the checkpoint to resume from).
JobInput InputOf(const v1::Lease& lease) {
  JobInput job;
  for (const auto& option : lease.options()) job.options.emplace_back(option.key(), option.value());
  job.spec_json = lease.study_spec_json();
  return job;
}

}  // namespace

std::optional<std::string> Worker::OutlastsWalltime(const v1::Lease& lease) {
  if (walltime_end_ms_ < 0) return std::nullopt;
  const auto runner = runners_.find(KindOf(lease));
  if (runner == runners_.end()) return std::nullopt;
  const std::optional<double> estimate = runner->second->EstimateCpuSeconds(InputOf(lease));
  if (!estimate.has_value()) return std::nullopt;
  const double needed_seconds = *estimate * options_.speed_factor;
  const double left_seconds = (walltime_end_ms_ - clock_->MonotonicMs()) / 1000.0;
  if (needed_seconds <= left_seconds) return std::nullopt;
  return absl::StrCat(Describe(lease.key()), ": its cost-model estimate, ",
                      absl::SixDigits(needed_seconds), " s here (speed factor ",
                      options_.speed_factor, "), is more than the ",
                      absl::SixDigits(std::max(0.0, left_seconds)),
                      " s left of --walltime; giving it back unstarted and taking no new job");
}

Worker::~Worker() = default;

WorkerSummary Worker::Run() {
  if (!options_.state_dir.empty()) {
    absl::StatusOr<std::unique_ptr<Spool>> spool = Spool::Open(options_.state_dir, options_.worker_id);
    if (spool.ok()) {
      absl::MutexLock lock(&mutex_);  // SpoolUnfinished may run on a signal thread
      spool_ = *std::move(spool);
    } else if (spool.status().code() == absl::StatusCode::kFailedPrecondition) {
      // Another process here uses this id: running too would mix two
      // workers' leases under one name.
      absl::MutexLock lock(&mutex_);
      summary_.exit = WorkerExit::kWorkerIdInUse;
      summary_.exit_message = std::string(spool.status().message());
      spdlog::error("{}", summary_.exit_message);
      return summary_;
    } else {
      spdlog::warn("{}; running without a spool: results that cannot be delivered before the "
                   "worker exits will be dropped",
                   std::string(spool.status().message()));
    }
  }
  std::thread deadlines([this] { DeadlineLoop(); });
  if (spool_ != nullptr) ReplaySpool();
  std::thread heartbeat([this] { HeartbeatLoop(); });
  std::vector<std::thread> slots;
  for (int slot = 0; slot < options_.slots; ++slot) {
    slots.emplace_back([this, slot] { SlotLoop(slot); });
  }
  for (auto& t : slots) t.join();
  {
    absl::MutexLock lock(&mutex_);
    finished_ = true;
  }
  heartbeat.join();
  deadlines.join();
  absl::MutexLock lock(&mutex_);
  return summary_;
}

void Worker::Drain() {
  {
    absl::MutexLock lock(&mutex_);
    ++heartbeat_generation_;  // the heartbeat thread now watches the drain deadline
    if (!draining_.exchange(true)) {
      drain_started_ms_ = clock_->MonotonicMs();
      spdlog::info("draining: no new leases; running trials have {} to finish",
                   absl::FormatDuration(options_.drain_timeout));
    }
    for (grpc::ClientContext* context : acquiring_) context->TryCancel();
  }
  replay_calls_.CancelAll();
}

void Worker::Stop() {
  stopping_ = true;
  give_up_ = true;
  Drain();
  calls_.CancelAll();
  CancelAll("worker stopping");
}

void Worker::FailFatally(WorkerExit exit, const std::string& message) {
  {
    absl::MutexLock lock(&mutex_);
    if (summary_.exit != WorkerExit::kDone) return;  // the first reason is the one reported
    summary_.exit = exit;
    summary_.exit_message = message;
  }
  spdlog::error("{}; stopping now (retrying cannot help)", message);
  Stop();
}

void Worker::FillIdentity(v1::WorkerIdentity* identity) const {
  identity->set_worker_id(options_.worker_id);
  identity->set_host(options_.host);
  identity->set_build(options_.build);
  identity->set_slots(options_.slots);
  identity->set_study_jobs(runners_.count(v1::JOB_KIND_STUDY) > 0);
  identity->set_instance(options_.instance);
  // Holding the host-local lock proves any earlier process with this id here has exited.
  identity->set_takes_over(spool_ != nullptr);
}

void Worker::CancelAll(const std::string& reason) {
  {
    absl::MutexLock lock(&mutex_);
    for (auto& [job, active] : active_) {
      if (active->cancel_reason.empty()) active->cancel_reason = reason;
      active->cancel = true;
    }
  }
}

void Worker::SlotLoop(int slot) {
  thread_local std::mt19937_64 random(std::random_device{}() + slot);
  int64_t last_work_ms = clock_->MonotonicMs();
  int64_t last_answer_ms = clock_->MonotonicMs();  // the coordinator's last answer (granted or not)
  int64_t backoff_ms = 200;
  // Ends a wait between polls (draining_ is set under mutex_; stopping_ just
  // before Drain() takes it).
  const auto stopped_polling = [this] { return draining_ || stopping_; };
  while (!draining_ && !stopping_) {
    v1::AcquireLeaseRequest request;
    FillIdentity(request.mutable_worker());
    request.set_wait_ms(static_cast<int32_t>(absl::ToInt64Milliseconds(options_.acquire_wait)));
    v1::AcquireLeaseResponse response;
    grpc::ClientContext context;
    rpc::PrepareContext(&context, options_.token, options_.acquire_wait + options_.call_timeout,
                        /*wait_for_ready=*/true);
    {
      absl::MutexLock lock(&mutex_);
      if (draining_) break;
      acquiring_.push_back(&context);
    }
    const grpc::Status status = stub_->AcquireLease(&context, request, &response);
    {
      absl::MutexLock lock(&mutex_);
      acquiring_.erase(std::find(acquiring_.begin(), acquiring_.end(), &context));
    }
    if (draining_ || stopping_) {
      // A lease granted while we were cancelling the poll is given back.
      if (status.ok() && response.granted()) {
        auto active = std::make_shared<ActiveLease>();
        active->lease = response.lease();
        active->never_started = true;
        active->cancel_reason = "drain";
        Finish(active, absl::CancelledError("drain"));
      }
      break;
    }
    if (IsAuthError(status.error_code())) {
      FailFatally(WorkerExit::kAuthRefused,
                  absl::StrCat("the coordinator refused this worker's token: ",
                               status.error_message()));
      break;
    }
    if (status.error_code() == grpc::StatusCode::ALREADY_EXISTS) {
      int64_t refused_for = 0;
      {
        absl::MutexLock lock(&mutex_);
        if (id_refused_since_ms_ < 0) id_refused_since_ms_ = clock_->MonotonicMs();
        refused_for = clock_->MonotonicMs() - id_refused_since_ms_;
      }
      // A newer process took this id over: this one is the duplicate. Else
      // the other process may be a crashed predecessor whose silence has
      // not yet reached the lease timeout: wait a while before giving up.
      if (status.error_message().find("replaced by a newer process") != std::string::npos ||
          refused_for > absl::ToInt64Milliseconds(options_.worker_id_wait)) {
        FailFatally(WorkerExit::kWorkerIdInUse, status.error_message());
        break;
      }
      if (slot == 0) {
        spdlog::warn("{} (waiting up to {} for it to go away)", status.error_message(),
                     absl::FormatDuration(options_.worker_id_wait));
      }
      absl::MutexLock lock(&mutex_);
      clock_->AwaitUntil(&mutex_, absl::Condition(&stopped_polling),
                         clock_->MonotonicMs() + 2000);
      continue;
    }
    {
      absl::MutexLock lock(&mutex_);
      if (status.ok()) id_refused_since_ms_ = -1;
    }
    if (!status.ok()) {
      // Without a coordinator the worker can do nothing: give up after
      // max_unreachable (or max_idle) instead of retrying for ever.
      const int64_t silent_ms = clock_->MonotonicMs() - last_answer_ms;
      const absl::Duration limit = std::min(options_.max_unreachable, options_.max_idle);
      if (limit != absl::InfiniteDuration() && silent_ms > absl::ToInt64Milliseconds(limit)) {
        FailFatally(WorkerExit::kCoordinatorUnreachable,
                    absl::StrCat("no answer from the coordinator for ",
                                 absl::FormatDuration(absl::Milliseconds(silent_ms)),
                                 " (last error: ", status.error_message(),
                                 "); giving up (--max-unreachable ",
                                 absl::FormatDuration(options_.max_unreachable), ", --max-idle ",
                                 absl::FormatDuration(options_.max_idle), ")"));
        break;
      }
      spdlog::warn("slot {}: AcquireLease failed: {} ({}); retrying", slot, status.error_message(),
                   static_cast<int>(status.error_code()));
      std::uniform_real_distribution<double> jitter(0.8, 1.2);
      const int64_t sleep_ms = static_cast<int64_t>(backoff_ms * jitter(random));
      absl::MutexLock lock(&mutex_);
      clock_->AwaitUntil(&mutex_, absl::Condition(&stopped_polling),
                         clock_->MonotonicMs() + sleep_ms);
      backoff_ms = std::min<int64_t>(backoff_ms * 2, 10'000);
      continue;
    }
    backoff_ms = 200;
    last_answer_ms = clock_->MonotonicMs();
    if (!response.granted()) {
      if (options_.max_idle != absl::InfiniteDuration() &&
          clock_->MonotonicMs() - last_work_ms > absl::ToInt64Milliseconds(options_.max_idle)) {
        spdlog::info("slot {}: idle for {}; exiting", slot, absl::FormatDuration(options_.max_idle));
        break;
      }
      continue;
    }
    if (std::optional<std::string> too_long = OutlastsWalltime(response.lease())) {
      spdlog::info("{}", *too_long);
      auto active = std::make_shared<ActiveLease>();
      active->lease = response.lease();
      active->never_started = true;
      active->cancel_reason = "walltime";
      Finish(active, absl::CancelledError("walltime: the job's estimate exceeds the time left"));
      Drain();
      break;
    }
    RunLease(response.lease());
    last_work_ms = clock_->MonotonicMs();
  }
}

void Worker::RunLease(const v1::Lease& lease) {
  auto active = std::make_shared<ActiveLease>();
  active->lease = lease;
  active->next_beat_ms = clock_->MonotonicMs() + std::max(100, lease.heartbeat_interval_ms());
  // Before the lease is registered, so that SpoolUnfinished's fuller entry
  // (its unacknowledged episodes) always replaces this mark, never the reverse.
  MarkHeldInSpool(lease.key());
  {
    absl::MutexLock lock(&mutex_);
    active_[lease.key().job_id()] = active;
    ++heartbeat_generation_;  // the heartbeat thread plans this lease's first beat
    const int64_t drain_deadline_ms =
        drain_started_ms_ + absl::ToInt64Milliseconds(options_.drain_timeout);
    if (stopping_) {
      active->cancel = true;
      active->cancel_reason = "worker stopping";
    } else if (draining_ && clock_->MonotonicMs() >= drain_deadline_ms) {
      // Granted before the drain began but registered only after its
      // deadline (a slow thread on a busy machine): DeadlineLoop has already
      // stopped the leases it saw, so this one is stopped here, the same way,
      // instead of running unbounded.
      active->cancel = true;
      active->cancel_reason = "drain timeout";
    }
  }
  const v1::JobKind kind = KindOf(lease);
  // "trial", "study": as the coordinator's job kinds name them.
  const std::string kind_name =
      absl::AsciiStrToLower(absl::StripPrefix(v1::JobKind_Name(kind), "JOB_KIND_"));
  spdlog::info("{}: {} seed {} {}", Describe(lease.key()), lease.method(), lease.seed(),
               lease.variant());
  JobInput job = InputOf(lease);
  // The coordinator sends a checkpoint only for kinds that keep them.
  if (lease.has_resume_from() && !lease.resume_from().data().empty()) {
    if (lease.resume_from_build() == options_.build) {
      job.resume_from = lease.resume_from().data();
    } else {
      spdlog::warn("{}: not resuming from the checkpoint of attempt {} (after episode {}): it "
                   "was written by another build ({}); starting over so the results are "
                   "those of one build",
                   Describe(lease.key()), lease.resume_from_attempt(),
                   lease.resume_from().episode(), lease.resume_from_build());
    }
  }
  Progress progress(this, active);
  absl::StatusOr<JobOutcome> result;
  const auto runner = runners_.find(kind);
  try {
    if (runner == runners_.end()) {
      result = absl::FailedPreconditionError(absl::StrCat(
          "this worker cannot run ", kind_name, " jobs"));
    } else if (job.resume_from.empty()) {
      result = runner->second->Run(job, &progress);
    } else {
      spdlog::info("{}: resuming from the checkpoint of attempt {} after episode {}",
                   Describe(lease.key()), lease.resume_from_attempt(),
                   lease.resume_from().episode());
      result = runner->second->Run(job, &progress);
      if (!result.ok() && result.status().code() == absl::StatusCode::kFailedPrecondition &&
          absl::StartsWith(result.status().message(), "cannot resume")) {
        spdlog::warn("{}: {}; starting over", Describe(lease.key()),
                     std::string(result.status().message()));
        job.resume_from.clear();
        result = runner->second->Run(job, &progress);
      } else {
        absl::MutexLock lock(&mutex_);
        ++summary_.resumed;
      }
    }
  } catch (const std::exception& error) {
    result = absl::InternalError(absl::StrCat("the ", kind_name, " threw: ", error.what()));
  } catch (...) {
    result = absl::InternalError(
        absl::StrCat("the ", kind_name, " threw a non-standard exception"));
  }
  Finish(active, result);
}

void Worker::DeadlineLoop() {
  // Its own thread, so that a heartbeat stuck on an unreachable coordinator
  // cannot delay the drain deadlines.
  absl::ReleasableMutexLock lock(&mutex_);
  const auto finished_or_draining = [this] { return finished_ || draining_; };
  mutex_.Await(absl::Condition(&finished_or_draining));
  if (finished_) return;
  const int64_t drain_deadline =
      drain_started_ms_ + absl::ToInt64Milliseconds(options_.drain_timeout);
  const int64_t report_deadline = drain_deadline + absl::ToInt64Milliseconds(options_.report_grace);
  const auto finished = [this] { return finished_.load(); };
  if (clock_->AwaitUntil(&mutex_, absl::Condition(&finished), drain_deadline)) return;
  for (auto& [job, active] : active_) {
    if (!active->cancel) {
      active->cancel_reason = "drain timeout";
      active->cancel = true;
    }
  }
  if (clock_->AwaitUntil(&mutex_, absl::Condition(&finished), report_deadline)) return;
  // Whatever is still undelivered is spooled rather than waited for.
  give_up_ = true;
  lock.Release();
  calls_.CancelAll();
}

void Worker::HeartbeatLoop() {
  mutex_.Lock();  // held except while beating (Lock/Unlock: it is released mid-loop)
  while (!finished_) {
    const int64_t now = clock_->MonotonicMs();
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
      const uint64_t generation = heartbeat_generation_;
      const auto replan = [&]() ABSL_EXCLUSIVE_LOCKS_REQUIRED(mutex_) {
        if (finished_ || heartbeat_generation_ != generation) return true;
        for (auto& [job, active] : active_) {
          if (active->has_new && !active->beat_in_flight && !active->lost) return true;
        }
        return false;
      };
      clock_->AwaitUntil(&mutex_, absl::Condition(&replan), wake);
      continue;
    }
    for (auto& active : due) active->beat_in_flight = true;
    mutex_.Unlock();
    for (auto& active : due) Beat(active);
    mutex_.Lock();
    for (auto& active : due) active->beat_in_flight = false;
  }
  mutex_.Unlock();
}

void Worker::Beat(const std::shared_ptr<ActiveLease>& active) {
  v1::HeartbeatRequest request;
  request.set_worker_id(options_.worker_id);
  *request.mutable_lease() = active->lease.key();
  std::set<int> sent;
  int checkpoint_sent = -1;
  {
    absl::MutexLock lock(&mutex_);
    for (const auto& episode : active->unacked) {
      if (request.episodes_size() >= 1000) break;
      *request.add_episodes() = episode;
      sent.insert(episode.episode());
    }
    // The checkpoint only with (or after) the episode it follows.
    if (active->checkpoint && request.episodes_size() == static_cast<int>(active->unacked.size())) {
      *request.mutable_checkpoint() = *active->checkpoint;
      checkpoint_sent = active->checkpoint->episode();
    }
    active->has_new = false;
  }
  v1::HeartbeatResponse response;
  grpc::ClientContext context;
  rpc::PrepareContext(&context, options_.token, options_.call_timeout, /*wait_for_ready=*/false);
  calls_.Add(&context);
  const grpc::Status status = stub_->Heartbeat(&context, request, &response);
  calls_.Remove(&context);
  if (IsAuthError(status.error_code())) {
    FailFatally(WorkerExit::kAuthRefused,
                absl::StrCat("the coordinator refused this worker's token: ", status.error_message()));
    return;
  }
  bool drain = false;
  {
    absl::MutexLock lock(&mutex_);
    const int64_t now = clock_->MonotonicMs();
    const int64_t interval = std::max(100, active->lease.heartbeat_interval_ms());
    if (status.ok()) {
      std::erase_if(active->unacked,
                    [&](const v1::EpisodeReport& e) { return sent.count(e.episode()) > 0; });
      if (active->checkpoint && active->checkpoint->episode() == checkpoint_sent) {
        active->checkpoint.reset();  // a newer one, if it came meanwhile, stays
      }
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

}  // namespace totalgrad::worker
