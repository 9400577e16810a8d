#include "server/service/archive_spool.h"

#include <stdlib.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

#include "absl/strings/str_cat.h"

namespace totalgrad::service {

ArchiveSpool::~ArchiveSpool() {
  if (!path_.empty()) ::unlink(path_.c_str());
}

namespace {

bool InMemory(const std::string& database) {
  return database.empty() || database == ":memory:";
}

// Where the spool of `database` goes, and how its name starts.
std::filesystem::path SpoolDirectory(const std::string& database) {
  if (InMemory(database)) return std::filesystem::temp_directory_path();
  return std::filesystem::absolute(database).parent_path();
}
std::string SpoolPrefix(const std::string& database) {
  const std::string file =
      InMemory(database) ? "memory" : std::filesystem::path(database).filename().string();
  return absl::StrCat(".", file, ".import-");
}

}  // namespace

int ArchiveSpool::RemoveLeftovers(const std::string& database) {
  if (InMemory(database)) return 0;  // the temporary directory is shared
  const std::string prefix = SpoolPrefix(database);
  int removed = 0;
  std::error_code error;
  for (const auto& entry : std::filesystem::directory_iterator(SpoolDirectory(database), error)) {
    if (entry.path().filename().string().rfind(prefix, 0) != 0) continue;
    if (std::filesystem::remove(entry.path(), error)) ++removed;
  }
  return removed;
}

absl::Status ArchiveSpool::Open(const std::string& database) {
  const std::filesystem::path directory = SpoolDirectory(database);
  std::string name = (directory / (SpoolPrefix(database) + "XXXXXX")).string();
  const int fd = ::mkstemp(name.data());
  if (fd < 0) {
    return absl::InternalError(absl::StrCat("cannot create a file in ", directory.string(),
                                            " to receive the archive: ", std::strerror(errno)));
  }
  ::close(fd);
  path_ = name;
  out_.open(path_, std::ios::binary | std::ios::trunc);
  if (!out_) return absl::InternalError(absl::StrCat("cannot write ", path_));
  return absl::OkStatus();
}

absl::Status ArchiveSpool::DiskRefused() const {
  return absl::ResourceExhaustedError(absl::StrCat(
      "cannot keep the archive while importing it (", path_, "): is the disk full?"));
}

absl::Status ArchiveSpool::Append(const std::string& data) {
  out_.write(data.data(), static_cast<std::streamsize>(data.size()));
  if (!out_) return DiskRefused();
  bytes_ += data.size();
  return absl::OkStatus();
}

absl::Status ArchiveSpool::Close() {
  out_.close();
  if (!out_) return DiskRefused();
  return absl::OkStatus();
}

absl::StatusOr<std::ifstream> ArchiveSpool::Read() const {
  std::ifstream in(path_, std::ios::binary);
  if (!in) return absl::InternalError(absl::StrCat("cannot read back ", path_));
  return in;
}

}  // namespace totalgrad::service
