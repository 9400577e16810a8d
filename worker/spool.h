// The worker's local state directory: a host-local lock per worker id, and
// the spool of results that could not be delivered before the worker had to
// exit (drain timeout, a second SIGTERM, an auth error).
//
//   <state_dir>/<escaped worker id>/lock                      flock'd while the worker runs
//   <state_dir>/<escaped worker id>/spool/job-J-attempt-A.pb  one v1::SpooledAttempt each
//
// The lock makes a second process with the same worker id on this host
// refuse to start (naming the holder), and proves to the coordinator that an
// earlier process with this id has exited (WorkerIdentity.takes_over). The
// next worker with the same id replays the spool (Worker::Run): the
// coordinator accepts what belongs to a lease that is still valid and
// refuses the rest with ABORTED, which is then dropped with a log line.
//
// Files are written to a temporary name, fsync'd and renamed, so a crash
// leaves either the old file or the new one, never half of one.
//
// Threading: Put/Remove/List may be called from any thread (each file is
// written whole; the same attempt written twice keeps the later version).
#ifndef TOTALGRAD_WORKER_SPOOL_H_
#define TOTALGRAD_WORKER_SPOOL_H_

#include <memory>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "totalgrad/v1/worker_spool.pb.h"

namespace totalgrad::worker {

inline constexpr int kSpoolFormatVersion = 1;

class Spool {
 public:
  // Creates <state_dir>/<escaped worker_id>/ (mode 0700) if needed and takes
  // its lock. FailedPrecondition naming the holder (pid and host written in
  // the lock file) if another process holds it; PermissionDenied/Internal
  // naming the path if the directory cannot be created or locked.
  static absl::StatusOr<std::unique_ptr<Spool>> Open(const std::string& state_dir,
                                                     const std::string& worker_id);
  ~Spool();  // releases the lock
  Spool(const Spool&) = delete;
  Spool& operator=(const Spool&) = delete;

  // Stores `attempt` under its lease key (replacing an earlier version).
  absl::Status Put(const v1::SpooledAttempt& attempt);
  // Forgets the attempt (no error if absent).
  absl::Status Remove(const v1::LeaseKey& key);
  // Every stored attempt, oldest lease first. A file that cannot be parsed
  // or has another format version is skipped with its path in `skipped`
  // (left on disk for a person to look at).
  std::vector<v1::SpooledAttempt> List(std::vector<std::string>* skipped = nullptr) const;

  const std::string& directory() const { return directory_; }

 private:
  Spool(std::string directory, int lock_fd) : directory_(std::move(directory)), lock_fd_(lock_fd) {}
  std::string PathOf(const v1::LeaseKey& key) const;

  const std::string directory_;
  const int lock_fd_;
};

// A worker id as a file name: [A-Za-z0-9._-] kept, every other byte as %XX.
std::string EscapeWorkerId(const std::string& worker_id);

}  // namespace totalgrad::worker

#endif  // TOTALGRAD_WORKER_SPOOL_H_
