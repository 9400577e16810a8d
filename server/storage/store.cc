// The names of the store's enums (store.h), as stored in the database, and
// NewSweep's walk over its listed and generated jobs.
#include "server/storage/store.h"

#include "server/storage/job_kinds.h"

namespace totalgrad::storage {

int64_t NewSweep::job_count() const {
  return static_cast<int64_t>(jobs.size()) + (generated_jobs ? generated_jobs->size() : 0);
}

int64_t NewSweep::episodes_expected() const {
  int64_t episodes = generated_jobs ? generated_jobs->episodes_expected() : 0;
  for (const NewJob& job : jobs) episodes += job.episodes_expected;
  return episodes;
}

absl::Status NewSweep::ForEachJob(const std::function<absl::Status(const NewJob&)>& visit) const {
  for (const NewJob& job : jobs) {
    if (absl::Status status = visit(job); !status.ok()) return status;
  }
  return generated_jobs ? generated_jobs->ForEach(visit) : absl::OkStatus();
}

absl::string_view ToString(SweepState state) {
  switch (state) {
    case SweepState::kRunning: return "running";
    case SweepState::kPaused: return "paused";
    case SweepState::kCancelled: return "cancelled";
  }
  return "unknown";
}
absl::string_view ToString(JobState state) {
  switch (state) {
    case JobState::kQueued: return "queued";
    case JobState::kRunning: return "running";
    case JobState::kCompleted: return "completed";
    case JobState::kFailed: return "failed";
    case JobState::kCancelled: return "cancelled";
  }
  return "unknown";
}
absl::string_view ToString(AttemptState state) {
  switch (state) {
    case AttemptState::kRunning: return "running";
    case AttemptState::kCompleted: return "completed";
    case AttemptState::kFailed: return "failed";
    case AttemptState::kLeaseLost: return "lease_lost";
    case AttemptState::kReleased: return "released";
    case AttemptState::kCancelled: return "cancelled";
  }
  return "unknown";
}
absl::string_view ToString(JobKind kind) { return KindInfo(kind).name; }
std::optional<SweepState> ParseSweepState(absl::string_view text) {
  for (SweepState s : {SweepState::kRunning, SweepState::kPaused, SweepState::kCancelled}) {
    if (ToString(s) == text) return s;
  }
  return std::nullopt;
}
std::optional<JobState> ParseJobState(absl::string_view text) {
  for (JobState s : {JobState::kQueued, JobState::kRunning, JobState::kCompleted,
                     JobState::kFailed, JobState::kCancelled}) {
    if (ToString(s) == text) return s;
  }
  return std::nullopt;
}
std::optional<AttemptState> ParseAttemptState(absl::string_view text) {
  for (AttemptState s : {AttemptState::kRunning, AttemptState::kCompleted, AttemptState::kFailed,
                         AttemptState::kLeaseLost, AttemptState::kReleased,
                         AttemptState::kCancelled}) {
    if (ToString(s) == text) return s;
  }
  return std::nullopt;
}

}  // namespace totalgrad::storage
