// What the scheduler requires of results before anything is stored: the
// values a worker sends (episodes, study rows, checkpoints, its identity),
// and the same of a sweep archive's completed jobs, so that an import takes
// over nothing Complete would have refused.
#ifndef TOTALGRAD_SERVER_SCHEDULER_RESULT_CHECKS_H_
#define TOTALGRAD_SERVER_SCHEDULER_RESULT_CHECKS_H_

#include <cstddef>
#include <optional>
#include <vector>

#include "absl/status/status.h"
#include "server/storage/store.h"

namespace totalgrad::scheduler {

// Limits on what a worker may send (checked before anything is stored).
inline constexpr int kMaxEpisodesPerCall = 1000;
inline constexpr size_t kMaxDetailsBytes = 64 * 1024;
inline constexpr size_t kMaxErrorBytes = 16 * 1024;
inline constexpr size_t kMaxWorkerIdBytes = 128;
inline constexpr int kMaxStudyRowsPerCall = 1000;
inline constexpr size_t kMaxStudyTextBytes = 16 * 1024;
inline constexpr size_t kMaxStudyVectorSize = 100000;
// Largest trial checkpoint kept (what a worker sends must fit a message).
inline constexpr size_t kMaxCheckpointBytes = 2 << 20;

// InvalidArgument naming the problem: empty or over-long id, control chars.
absl::Status ValidateWorkerIdentity(const storage::WorkerIdentity& worker);
// InvalidArgument naming the episode and field: +-Inf anywhere (NaN means
// "no value"), a NaN real cost, details_json oversized or not JSON.
absl::Status ValidateEpisode(const storage::Episode& episode);
// ValidateEpisode of each, and at most kMaxEpisodesPerCall of them.
absl::Status ValidateEpisodes(const std::vector<storage::Episode>& episodes);
// InvalidArgument naming the row: more than kMaxStudyRowsPerCall rows,
// oversized text or vectors, a negative index or count. Numbers are stored
// as they are (NaN: no value).
absl::Status ValidateStudyRows(const storage::StudyRows& rows);
// ValidateStudyRows without the per-call count (an archive's attempt holds
// the rows of many calls).
absl::Status ValidateStudyRowValues(const storage::StudyRows& rows);
// Both of the above, on a bundle of every table's rows.
absl::Status ValidateResults(const storage::JobResults& results);
// InvalidArgument unless a checkpoint (if any) has data, a format version
// and at most kMaxCheckpointBytes.
absl::Status ValidateCheckpoint(const std::optional<storage::Checkpoint>& checkpoint);
// What Complete checks of a worker's values, on the jobs a sweep archive
// marks completed (the ones an import takes over): every episode, study row
// and checkpoint of their attempts, and a finite final_eval_cost for kinds
// whose verdict is the worker's. InvalidArgument naming the job, attempt and
// value. The rows themselves (every expected one, nothing of a table the
// kind does not own) are checked by Store::ImportJobs, as by EndAttempt.
absl::Status CheckImportedJob(const storage::ImportedJob& job);

}  // namespace totalgrad::scheduler

#endif  // TOTALGRAD_SERVER_SCHEDULER_RESULT_CHECKS_H_
