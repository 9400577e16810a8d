// The end of an attempt (worker.h): its final report (Complete, Fail or
// Release), the rows a job returns at its end, delivery with retries, and the
// spool that keeps what cannot be delivered in time, replayed by the next
// worker with this id. Leasing, running and heartbeats are in worker.cc.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <optional>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "runtime/record_proto.h"
#include "runtime/rpc_client.h"
#include "worker/worker.h"
#include "worker/worker_internal.h"

namespace totalgrad::worker {

using worker_internal::Describe;
using worker_internal::IsAuthError;
using worker_internal::IsLeaseGone;


v1::SpooledAttempt Worker::SpoolEntry(const v1::LeaseKey& key,
                                      const std::vector<v1::EpisodeReport>& unacked,
                                      const std::optional<v1::TrialCheckpoint>& checkpoint) const {
  v1::SpooledAttempt entry;
  entry.set_format_version(kSpoolFormatVersion);
  *entry.mutable_lease() = key;
  entry.set_worker_id(options_.worker_id);
  entry.set_written_unix_ms(clock_->NowMs());
  if (!unacked.empty() || checkpoint) {
    entry.mutable_pending()->set_worker_id(options_.worker_id);
    *entry.mutable_pending()->mutable_lease() = key;
    for (const auto& e : unacked) *entry.mutable_pending()->add_episodes() = e;
    if (checkpoint) *entry.mutable_pending()->mutable_checkpoint() = *checkpoint;
  }
  return entry;
}

void Worker::MarkHeldInSpool(const v1::LeaseKey& key) {
  if (spool_ == nullptr) return;
  v1::SpooledAttempt entry = SpoolEntry(key, {});
  entry.mutable_release()->set_worker_id(options_.worker_id);
  *entry.mutable_release()->mutable_lease() = key;
  entry.mutable_release()->set_reason(
      "held by an earlier process with this worker id that ended without reporting it");
  const absl::Status written = spool_->Put(entry);
  if (!written.ok()) {
    spdlog::warn("{}: marking the lease held in the spool failed ({}); should this process "
                 "die, the lease is lost only after the lease timeout",
                 Describe(key), written.ToString());
  }
}

void Worker::ForgetHeldInSpool(const v1::LeaseKey& key) {
  if (spool_ == nullptr) return;
  const absl::Status removed = spool_->Remove(key);
  if (!removed.ok()) spdlog::warn("{}", removed.ToString());
}

bool Worker::KeepInSpool(const v1::SpooledAttempt& entry, const std::string& why) {
  if (spool_ == nullptr) {
    spdlog::warn("{}: {}; no --state-dir to keep it in: dropped", Describe(entry.lease()), why);
    return false;
  }
  v1::SpooledAttempt stamped = entry;
  stamped.set_written_unix_ms(clock_->NowMs());
  const absl::Status written = spool_->Put(stamped);
  if (!written.ok()) {
    spdlog::error("{}: {}; keeping it in the spool failed: {}", Describe(entry.lease()), why,
                  written.ToString());
    return false;
  }
  spdlog::warn("{}: {}; kept in {} for the next worker with id '{}' on this host",
               Describe(entry.lease()), why, spool_->directory(), options_.worker_id);
  return true;
}

int Worker::SpoolUnfinished() {
  std::vector<v1::SpooledAttempt> entries;
  {
    absl::MutexLock lock(&mutex_);
    if (spool_ == nullptr) return 0;
    for (const auto& [job, active] : active_) {
      v1::SpooledAttempt entry =
          SpoolEntry(active->lease.key(), active->unacked, active->checkpoint);
      entry.mutable_release()->set_worker_id(options_.worker_id);
      *entry.mutable_release()->mutable_lease() = active->lease.key();
      entry.mutable_release()->set_reason("worker stopped before the trial finished");
      entries.push_back(std::move(entry));
    }
    for (const auto& [job, entry] : finishing_) entries.push_back(entry);
  }
  int kept = 0;
  for (const auto& entry : entries) {
    if (KeepInSpool(entry, "the worker is exiting")) ++kept;
  }
  absl::MutexLock lock(&mutex_);
  summary_.spooled += kept;
  return kept;
}

grpc::Status Worker::SendReturnedRows(const v1::LeaseKey& key, const JobOutcome& outcome,
                                      const rpc::RetryPolicy& policy) {
  // The core's records as the wire's rows, by name (record_proto.h), each
  // keyed by its position; references first, as the study computed them.
  std::vector<v1::StudyReferenceRow> references(outcome.study_references.size());
  for (size_t i = 0; i < references.size(); ++i) {
    references[i].set_index(static_cast<int>(i));
    record_proto::RecordToProto(study::ReferenceFields(), outcome.study_references[i],
                                &references[i]);
  }
  std::vector<v1::StudyCellRow> cells(outcome.study_cells.size());
  for (size_t i = 0; i < cells.size(); ++i) {
    cells[i].set_index(static_cast<int>(i));
    record_proto::RecordToProto(study::CellFields(), outcome.study_cells[i], &cells[i]);
  }
  // Batches stay far below the 4 MiB message limit and the coordinator's
  // 1000 rows per call.
  constexpr size_t kMaxBatchBytes = 1 << 20;
  constexpr int kMaxBatchRows = 500;
  size_t next_cell = 0, next_reference = 0;
  while (next_cell < cells.size() || next_reference < references.size()) {
    v1::HeartbeatRequest request;
    request.set_worker_id(options_.worker_id);
    *request.mutable_lease() = key;
    size_t bytes = 0;
    int rows = 0;
    while (rows < kMaxBatchRows && bytes < kMaxBatchBytes) {
      if (next_reference < references.size()) {
        bytes += references[next_reference].ByteSizeLong();
        *request.add_study_references() = std::move(references[next_reference++]);
      } else if (next_cell < cells.size()) {
        bytes += cells[next_cell].ByteSizeLong();
        *request.add_study_cells() = std::move(cells[next_cell++]);
      } else {
        break;
      }
      ++rows;
    }
    const grpc::Status status = rpc::CallWithRetry(
        policy, options_.token,
        [&](grpc::ClientContext* context) {
          v1::HeartbeatResponse response;
          return stub_->Heartbeat(context, request, &response);
        },
        &give_up_, &calls_);
    if (!status.ok()) return status;
  }
  return grpc::Status::OK;
}

rpc::RetryPolicy Worker::FinalReportPolicy() const {
  rpc::RetryPolicy policy;
  policy.call_timeout = options_.call_timeout;
  policy.give_up_after = options_.orphan_timeout;
  int64_t drain_started_ms = 0;
  {
    absl::MutexLock lock(&mutex_);
    drain_started_ms = drain_started_ms_;
  }
  if (draining_) {
    // Bounded by the drain: what is not delivered by then is spooled.
    const int64_t left = drain_started_ms + absl::ToInt64Milliseconds(options_.drain_timeout) +
                         absl::ToInt64Milliseconds(options_.report_grace) - clock_->MonotonicMs();
    policy.give_up_after = absl::Milliseconds(std::max<int64_t>(0, left));
    policy.call_timeout = std::min(policy.call_timeout,
                                   absl::Milliseconds(std::max<int64_t>(100, left)));
  }
  return policy;
}

Worker::Delivery Worker::Deliver(const v1::SpooledAttempt& attempt, const rpc::RetryPolicy& policy,
                                 rpc::CallRegistry* registry) {
  Delivery delivery;
  const auto call = [&](const auto& send) {
    return rpc::CallWithRetry(policy, options_.token, send, &give_up_, registry);
  };
  if (attempt.has_pending() &&
      (attempt.pending().episodes_size() > 0 || attempt.pending().study_cells_size() > 0 ||
       attempt.pending().study_references_size() > 0 || attempt.pending().has_checkpoint())) {
    delivery.status = call([&](grpc::ClientContext* context) {
      v1::HeartbeatResponse response;
      return stub_->Heartbeat(context, attempt.pending(), &response);
    });
    if (!delivery.status.ok()) return delivery;
  }
  v1::FailRequest fail;
  if (attempt.has_complete()) {
    delivery.kind = Delivery::Kind::kComplete;
    delivery.status = call([&](grpc::ClientContext* context) {
      v1::CompleteResponse response;
      return stub_->Complete(context, attempt.complete(), &response);
    });
    if (delivery.status.error_code() != grpc::StatusCode::INVALID_ARGUMENT &&
        delivery.status.error_code() != grpc::StatusCode::FAILED_PRECONDITION) {
      return delivery;
    }
    // A completion the coordinator will never accept: the attempt fails with the reason.
    delivery.failure =
        absl::StrCat("the coordinator refused the completion: ", delivery.status.error_message());
    fail.set_worker_id(attempt.complete().worker_id());
    *fail.mutable_lease() = attempt.complete().lease();
    fail.set_error(delivery.failure);
  } else if (attempt.has_fail()) {
    fail = attempt.fail();
  } else if (attempt.has_release()) {
    delivery.kind = Delivery::Kind::kRelease;
    delivery.status = call([&](grpc::ClientContext* context) {
      v1::ReleaseResponse response;
      return stub_->Release(context, attempt.release(), &response);
    });
    return delivery;
  } else {
    delivery.status = grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "no final report");
    return delivery;
  }
  delivery.kind = Delivery::Kind::kFail;
  delivery.status = call([&](grpc::ClientContext* context) {
    v1::FailResponse response;
    return stub_->Fail(context, fail, &response);
  });
  if (delivery.status.error_code() == grpc::StatusCode::INVALID_ARGUMENT) {
    fail.clear_episodes();  // keep the verdict even if an episode is refused
    delivery.status = call([&](grpc::ClientContext* context) {
      v1::FailResponse response;
      return stub_->Fail(context, fail, &response);
    });
  }
  return delivery;
}

v1::SpooledAttempt Worker::FinalReport(const v1::LeaseKey& key,
                                       const absl::StatusOr<JobOutcome>& result,
                                       const EndedAttempt& ended) const {
  // Data first (the checkpoint too: a later attempt resumes from it), then
  // the verdict.
  v1::SpooledAttempt entry = SpoolEntry(key, {}, ended.checkpoint);
  if (!ended.failure.empty()) {
    v1::FailRequest* fail = entry.mutable_fail();
    fail->set_worker_id(options_.worker_id);
    *fail->mutable_lease() = key;
    for (const auto& e : ended.unacked) *fail->add_episodes() = e;
    fail->set_error(ended.failure);
  } else if (!result.ok()) {
    entry = SpoolEntry(key, ended.unacked, ended.checkpoint);  // the data first, then the release
    v1::ReleaseRequest* release = entry.mutable_release();
    release->set_worker_id(options_.worker_id);
    *release->mutable_lease() = key;
    release->set_reason(ended.cancel_reason.empty() ? "cancelled" : ended.cancel_reason);
    release->set_never_started(ended.never_started);
  } else {
    // One completion for every kind: the streamed rows not yet acknowledged
    // and the checkpoint ride in it; every table's total and the verdict
    // are sent, and the coordinator's kind decides which count.
    v1::CompleteRequest* complete = entry.mutable_complete();
    complete->set_worker_id(options_.worker_id);
    *complete->mutable_lease() = key;
    for (const auto& e : ended.unacked) *complete->add_episodes() = e;
    if (ended.checkpoint) *complete->mutable_checkpoint() = *ended.checkpoint;
    entry.clear_pending();  // all of it rides in the completion
    complete->set_episodes_total(result->episodes);
    complete->set_study_cells_total(static_cast<int32_t>(result->study_cells.size()));
    complete->set_study_references_total(static_cast<int32_t>(result->study_references.size()));
    complete->set_success(result->success);
    complete->set_final_eval_cost(result->final_eval_cost);
  }
  return entry;
}

void Worker::Finish(const std::shared_ptr<ActiveLease>& active,
                    const absl::StatusOr<JobOutcome>& result) {
  const v1::LeaseKey& key = active->lease.key();
  EndedAttempt ended;
  bool lost = false;
  {
    // Take the lease away from the heartbeat thread; from here on it is a
    // final report in finishing_ (which SpoolUnfinished sees too).
    absl::MutexLock lock(&mutex_);
    const auto no_beat_in_flight = [&] { return !active->beat_in_flight; };
    mutex_.Await(absl::Condition(&no_beat_in_flight));
    active_.erase(key.job_id());
    lost = active->lost;
    if (lost) {
      ++summary_.dropped;
    } else {
      ended.failure = active->failure;
      ended.cancel_reason = active->cancel_reason;
      ended.never_started = active->never_started;
      ended.unacked = active->unacked;
      ended.checkpoint = active->checkpoint;
    }
  }
  if (lost) {
    ForgetHeldInSpool(key);
    return;
  }
  if (ended.failure.empty() && !result.ok() &&
      result.status().code() != absl::StatusCode::kCancelled) {
    ended.failure = result.status().ToString();
  }
  v1::SpooledAttempt entry = FinalReport(key, result, ended);
  const bool returned_rows =
      result.ok() && (!result->study_cells.empty() || !result->study_references.empty());
  {
    absl::MutexLock lock(&mutex_);
    finishing_[key.job_id()] = entry;
  }
  const rpc::RetryPolicy policy = FinalReportPolicy();
  Delivery delivery;
  if (ended.failure.empty() && returned_rows) {
    // Returned rows first (each batch a repeatable heartbeat), then the totals.
    delivery.kind = Delivery::Kind::kComplete;
    delivery.status = SendReturnedRows(key, *result, policy);
    if (!delivery.status.ok() && !IsLeaseGone(delivery.status.error_code()) &&
        !IsAuthError(delivery.status.error_code())) {
      // Returned rows are not spooled (they can be large; a job that returns
      // them re-runs from the start anyway): give the job back instead.
      entry = SpoolEntry(key, {});
      entry.mutable_release()->set_worker_id(options_.worker_id);
      *entry.mutable_release()->mutable_lease() = key;
      entry.mutable_release()->set_reason("the job's rows could not be delivered");
      absl::MutexLock lock(&mutex_);
      finishing_[key.job_id()] = entry;
    }
  }
  if (delivery.status.ok()) delivery = Deliver(entry, policy, &calls_);
  const grpc::Status& status = delivery.status;
  if (!delivery.failure.empty()) ended.failure = delivery.failure;
  if (IsAuthError(status.error_code())) {
    const bool kept = KeepInSpool(entry, "the coordinator refused the token");
    FailFatally(WorkerExit::kAuthRefused,
                absl::StrCat("the coordinator refused this worker's token: ", status.error_message()));
    absl::MutexLock lock(&mutex_);
    finishing_.erase(key.job_id());
    ++(kept ? summary_.spooled : summary_.dropped);
    return;
  }
  // Delivered, or refused because the lease ended: nothing is left to hand
  // over (any other failure is spooled by CountFinalReport, replacing the mark).
  if (status.ok() || IsLeaseGone(status.error_code())) ForgetHeldInSpool(key);
  absl::MutexLock lock(&mutex_);
  finishing_.erase(key.job_id());
  CountFinalReport(key, result, ended, delivery, entry);
}

void Worker::CountFinalReport(const v1::LeaseKey& key, const absl::StatusOr<JobOutcome>& result,
                              const EndedAttempt& ended, const Delivery& delivery,
                              const v1::SpooledAttempt& entry) {
  const grpc::Status& status = delivery.status;
  if (!status.ok()) {
    if (IsLeaseGone(status.error_code())) {
      ++summary_.dropped;
      spdlog::warn("{}: the coordinator no longer holds this lease ({}); the final report is "
                   "dropped and the job re-runs",
                   Describe(key), status.error_message());
    } else if (KeepInSpool(entry, absl::StrCat("the final report could not be delivered (",
                                               status.error_message(), ")"))) {
      ++summary_.spooled;
    } else {
      ++summary_.dropped;
    }
    return;
  }
  switch (delivery.kind) {
    case Delivery::Kind::kComplete:
      ++summary_.completed;
      spdlog::info("{}: completed ({} episodes, {} study cells, {} study references; "
                   "success={}, final eval cost {})",
                   Describe(key), result->episodes, result->study_cells.size(),
                   result->study_references.size(), result->success, result->final_eval_cost);
      break;
    case Delivery::Kind::kFail:
      ++summary_.failed;
      spdlog::warn("{}: failed: {}", Describe(key), ended.failure);
      break;
    case Delivery::Kind::kRelease:
      ++summary_.released;
      spdlog::info("{}: released ({})", Describe(key),
                   ended.cancel_reason.empty() ? entry.release().reason() : ended.cancel_reason);
      break;
  }
}

void Worker::ReplaySpool() {
  std::vector<std::string> skipped;
  const std::vector<v1::SpooledAttempt> entries = spool_->List(&skipped);
  for (const std::string& path : skipped) {
    spdlog::warn("spool file {} is unreadable or of another format version; left in place", path);
  }
  if (entries.empty()) return;
  spdlog::info("replaying {} attempts kept in {} by an earlier worker with id '{}'",
               entries.size(), spool_->directory(), options_.worker_id);
  rpc::RetryPolicy policy;
  policy.call_timeout = options_.call_timeout;
  policy.give_up_after = options_.orphan_timeout;
  for (const v1::SpooledAttempt& entry : entries) {
    const Delivery delivery = Deliver(entry, policy, &replay_calls_);
    const grpc::Status& status = delivery.status;
    if (IsAuthError(status.error_code())) {
      FailFatally(WorkerExit::kAuthRefused,
                  absl::StrCat("the coordinator refused this worker's token: ",
                               status.error_message()));
      return;  // the spool stays for a worker with a valid token
    }
    if (!status.ok() && !IsLeaseGone(status.error_code())) {
      spdlog::warn("{}: replay not delivered ({}); the spool is kept for later",
                   Describe(entry.lease()), status.error_message());
      return;  // draining, or the coordinator is unreachable: try again next start
    }
    const absl::Status removed = spool_->Remove(entry.lease());
    if (!removed.ok()) spdlog::warn("{}", removed.ToString());
    absl::MutexLock lock(&mutex_);
    if (status.ok()) {
      ++summary_.replayed;
      spdlog::info("{}: spooled results delivered ({})", Describe(entry.lease()),
                   delivery.kind == Delivery::Kind::kComplete ? std::string("completed")
                   : delivery.kind == Delivery::Kind::kFail
                       ? std::string("failed")
                       : absl::StrCat("released: ", entry.release().reason()));
    } else {
      ++summary_.dropped;
      spdlog::warn("{}: its lease ended before the spooled results could be delivered ({}); "
                   "dropped: the job re-runs",
                   Describe(entry.lease()), status.error_message());
    }
  }
}

}  // namespace totalgrad::worker
