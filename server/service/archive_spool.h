// ArchiveSpool: a sweep archive received for import (ControlService.ImportSweep),
// kept in a file while it is read.
#ifndef TOTALGRAD_SERVER_SERVICE_ARCHIVE_SPOOL_H_
#define TOTALGRAD_SERVER_SERVICE_ARCHIVE_SPOOL_H_

#include <cstddef>
#include <fstream>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace totalgrad::service {

// The archive is read twice (its opening, then its jobs; sweep_archive.h),
// so it is kept, and kept in a file so that its size bounds the disk it
// takes, not the coordinator's memory. The file lives beside the database
// (the coordinator's own disk, which the import will fill anyway) or, for an
// in-memory store, in the temporary directory; it is removed when the spool
// goes. Its name, ".<database file name>.import-XXXXXX", ties it to the
// store, so that the one process that may write the store can remove what a
// killed process left (RemoveLeftovers). Not thread-safe.
class ArchiveSpool {
 public:
  ArchiveSpool() = default;
  ArchiveSpool(const ArchiveSpool&) = delete;
  ArchiveSpool& operator=(const ArchiveSpool&) = delete;
  ~ArchiveSpool();

  // Removes the spools an earlier process left beside the store at
  // `database` (killed mid-import). Call only while holding the store for
  // writing (its lock keeps every other writer, hence every other importer,
  // out). Returns how many it removed.
  static int RemoveLeftovers(const std::string& database);

  // Creates the file for the store at `database` (a path, ":memory:" or "").
  // Internal error naming the directory if it cannot.
  absl::Status Open(const std::string& database);
  // ResourceExhausted if the disk refuses the bytes (the import stores nothing).
  absl::Status Append(const std::string& data);
  // Ends writing (ResourceExhausted as Append); then Read opens the received
  // bytes from their start, as often as needed.
  absl::Status Close();
  absl::StatusOr<std::ifstream> Read() const;
  size_t bytes() const { return bytes_; }

 private:
  absl::Status DiskRefused() const;

  std::string path_;
  std::ofstream out_;
  size_t bytes_ = 0;
};

}  // namespace totalgrad::service

#endif  // TOTALGRAD_SERVER_SERVICE_ARCHIVE_SPOOL_H_
