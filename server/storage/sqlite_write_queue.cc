// SqliteStore's writes: group commit on the one writer connection.
//
// Why: with synchronous=FULL every COMMIT is an fsync of the WAL, and a job
// costs about five writes (lease, one heartbeat per episode, completion), so
// one transaction per write caps the coordinator at the disk's fsync rate
// divided by five, however many cores and workers there are. Writes that
// arrive while a commit is under way wait in a queue; the thread whose write
// is at the front then runs every queued write (up to kMaxWritesPerCommit)
// in one transaction and one COMMIT makes them all durable. This is
// leveldb's writer queue (DBImpl::Write) with SQLite savepoints in place of
// its write batches: each write runs inside a savepoint of its own, so a
// write that fails is rolled back alone and the others in its group commit.
//
// What each caller sees is what one transaction per write gave: OK only
// after the COMMIT that holds its changes returned (durable), an error only
// with none of its changes stored. When the transaction itself ends early
// (SQLite rolls it back on some I/O errors and a full disk) or the COMMIT
// fails, every write of the group is told so and nothing of it is stored.
#include <sqlite3.h>

#include <algorithm>
#include <chrono>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/synchronization/mutex.h"
#include "server/storage/sqlite_internal.h"
#include "server/storage/sqlite_store.h"

namespace totalgrad::storage {

using internal::Db;
using internal::IsDatabaseFailure;
using internal::SteadyMs;

namespace internal {

int64_t SteadyMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

bool IsDatabaseFailure(const absl::Status& status) {
  switch (status.code()) {
    case absl::StatusCode::kUnavailable:
    case absl::StatusCode::kDataLoss:
    case absl::StatusCode::kInternal:
    case absl::StatusCode::kResourceExhausted:
      return true;
    default:
      return false;
  }
}

}  // namespace internal

// One caller's write while it waits in write_queue_ (on the caller's stack).
struct SqliteStore::QueuedWrite {
  explicit QueuedWrite(const std::function<absl::Status(Db&)>* body) : body(body) {}
  const std::function<absl::Status(Db&)>* const body;
  absl::Status status;
  // Set, under queue_mutex_, by the thread that committed this write's group.
  bool done = false;
  absl::CondVar wake;
};

absl::Status SqliteStore::InWriteTransaction(const std::function<absl::Status(Db&)>& body) {
  if (lock_fd_ < 0) {
    return absl::FailedPreconditionError(
        absl::StrCat(path_, " is open read-only here; writes go through its coordinator"));
  }
  QueuedWrite mine(&body);
  queue_mutex_.Lock();
  write_queue_.push_back(&mine);
  while (!mine.done && write_queue_.front() != &mine) mine.wake.Wait(&queue_mutex_);
  if (mine.done) {
    queue_mutex_.Unlock();
    return mine.status;
  }
  // At the front: commit the writes queued so far. Later arrivals queue
  // behind them and form the next group while this one commits.
  const size_t group_size =
      std::min(write_queue_.size(), static_cast<size_t>(kMaxWritesPerCommit));
  const std::vector<QueuedWrite*> group(write_queue_.begin(),
                                        write_queue_.begin() + static_cast<long>(group_size));
  queue_mutex_.Unlock();
  {
    absl::MutexLock lock(&write_mutex_);
    CommitGroupLocked(group);
  }
  queue_mutex_.Lock();
  // Only the front's thread removes entries, so the group is still the front.
  write_queue_.erase(write_queue_.begin(), write_queue_.begin() + static_cast<long>(group_size));
  for (QueuedWrite* write : group) {
    if (write == &mine) continue;
    write->done = true;
    write->wake.Signal();
  }
  if (!write_queue_.empty()) write_queue_.front()->wake.Signal();
  queue_mutex_.Unlock();
  return mine.status;
}

absl::Status SqliteStore::BeginLocked(bool* lock_busy) {
  // IMMEDIATE takes the write lock up front: a deferred transaction that reads
  // then writes can fail with SQLITE_BUSY without the busy handler being used.
  lock_wait_since_ms_.store(SteadyMs());
  absl::Status status = writer_.Exec("BEGIN IMMEDIATE");
  lock_wait_since_ms_.store(0);
  // Busy is another connection's lock, not a failure of the disk: the next
  // write may succeed, so it is not remembered for CheckWritable.
  *lock_busy = !status.ok() && sqlite3_errcode(writer_.raw()) == SQLITE_BUSY;
  if (*lock_busy) {
    status = absl::UnavailableError(
        absl::StrCat("the database's write lock on ", path_,
                     " is held by another process or connection; gave up after ",
                     options_.busy_timeout_ms, " ms (", status.message(), ")"));
  }
  return status;
}

void SqliteStore::CommitGroupLocked(const std::vector<QueuedWrite*>& group) {
  // The outcome of the transaction as a whole: OK if it committed.
  absl::Status transaction = CheckFileIdentityLocked();
  bool lock_busy = false;
  if (transaction.ok()) transaction = BeginLocked(&lock_busy);
  if (transaction.ok() && group.size() == 1) {
    // Alone: no savepoint needed, the transaction is the write's.
    transaction = (*group[0]->body)(writer_);
    group[0]->status = transaction;
  } else if (transaction.ok()) {
    for (QueuedWrite* write : group) {
      absl::Status status = writer_.Exec("SAVEPOINT queued_write");
      if (status.ok()) status = (*write->body)(writer_);
      if (status.ok()) status = writer_.Exec("RELEASE queued_write");
      write->status = status;
      if (status.ok()) continue;
      // SQLite ends the whole transaction on some errors (a full disk, I/O);
      // otherwise only this write's changes are undone.
      if (sqlite3_get_autocommit(writer_.raw()) == 0) {
        absl::Status undone = writer_.Exec("ROLLBACK TO queued_write");
        if (undone.ok()) undone = writer_.Exec("RELEASE queued_write");
        if (undone.ok()) continue;
        status = undone;
      }
      transaction = status;
      break;
    }
  }
  if (transaction.ok()) transaction = writer_.Exec("COMMIT");
  if (!transaction.ok()) {
    (void)writer_.Exec("ROLLBACK");  // fails harmlessly where the transaction already ended
    // Nothing of the group is stored: a write that succeeded inside it (or
    // never ran) is told why. One that failed keeps its own error.
    const absl::Status lost(
        transaction.code(),
        absl::StrCat(group.size() > 1 ? "the transaction carrying this write failed: " : "",
                     transaction.message()));
    for (QueuedWrite* write : group) {
      if (write->status.ok()) write->status = lost;
    }
    if (IsDatabaseFailure(transaction) && !lock_busy) {
      last_write_error_ = transaction;
      last_failure_or_probe_ms_ = SteadyMs();
    }
    return;
  }
  last_write_error_ = absl::OkStatus();
  last_commit_ms_ = SteadyMs();
  write_counts_.commits += 1;
  for (const QueuedWrite* write : group) write_counts_.writes += write->status.ok() ? 1 : 0;
}

WriteCounts SqliteStore::write_counts() {
  absl::MutexLock lock(&write_mutex_);
  return write_counts_;
}

}  // namespace totalgrad::storage
