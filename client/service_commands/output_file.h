// A file the CLI writes (an export, a sweep's archive) that appears under its
// name only complete: it is written under a temporary name in the same
// directory ("NAME.partial-XXXXXX"), then flushed, fsync'ed, renamed into
// place and the directory fsync'ed. A failed or interrupted write leaves no
// file under the final name (a run killed mid-write leaves the temporary,
// which names itself partial); a failure before Commit removes it.
//
// Threading: one object per file, used by one thread.
#ifndef TOTALGRAD_CLIENT_SERVICE_COMMANDS_OUTPUT_FILE_H_
#define TOTALGRAD_CLIENT_SERVICE_COMMANDS_OUTPUT_FILE_H_

#include <sys/types.h>

#include <fstream>
#include <memory>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace totalgrad::cli {

class OutputFile {
 public:
  enum class Existing {
    kReplace,  // an existing file of that name is replaced (atomically) at Commit
    kRefuse,   // AlreadyExists, at Create and at Commit: never written over
  };

  // Creates the temporary file beside `path` with permissions `mode` (less
  // the umask). AlreadyExists (kRefuse) naming the path; Unavailable naming
  // the path and the system's reason.
  static absl::StatusOr<std::unique_ptr<OutputFile>> Create(const std::string& path,
                                                            Existing existing, mode_t mode);
  ~OutputFile();  // removes the temporary unless committed
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  std::ostream& stream() { return stream_; }
  const std::string& path() const { return path_; }

  // Flushes and syncs the temporary, moves it to the final name and syncs
  // the directory. Unavailable naming the file and the system's reason
  // (e.g. "No space left on device"); AlreadyExists (kRefuse) if a file of
  // the final name appeared meanwhile. On error nothing is under the final
  // name that was not there before.
  absl::Status Commit();

 private:
  OutputFile(std::string path, std::string temporary, Existing existing);
  std::string path_;
  std::string temporary_;
  Existing existing_;
  std::ofstream stream_;
  bool committed_ = false;
};

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_SERVICE_COMMANDS_OUTPUT_FILE_H_
