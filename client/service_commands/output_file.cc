#include "client/service_commands/output_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <vector>

#include "absl/strings/str_cat.h"

namespace totalgrad::cli {
namespace {

absl::Status SystemError(absl::string_view what, const std::string& path) {
  return absl::UnavailableError(absl::StrCat(what, " ", path, ": ", std::strerror(errno)));
}

absl::Status AlreadyThere(const std::string& path) {
  return absl::AlreadyExistsError(absl::StrCat(path, " already exists; not overwriting it"));
}

// fsync of a file or directory by name.
absl::Status SyncPath(const std::string& path, int flags) {
  const int fd = ::open(path.c_str(), flags | O_CLOEXEC);
  if (fd < 0) return SystemError("opening", path);
  const bool synced = ::fsync(fd) == 0;
  const int saved = errno;
  ::close(fd);
  errno = saved;
  return synced ? absl::OkStatus() : SystemError("syncing", path);
}

std::string DirectoryOf(const std::string& path) {
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  return parent.empty() ? "." : parent.string();
}

}  // namespace

OutputFile::OutputFile(std::string path, std::string temporary, Existing existing)
    : path_(std::move(path)), temporary_(std::move(temporary)), existing_(existing) {}

absl::StatusOr<std::unique_ptr<OutputFile>> OutputFile::Create(const std::string& path,
                                                               Existing existing, mode_t mode) {
  if (existing == Existing::kRefuse && std::filesystem::exists(path)) return AlreadyThere(path);
  std::string name = path + ".partial-XXXXXX";
  std::vector<char> buffer(name.begin(), name.end());
  buffer.push_back('\0');
  const int fd = ::mkstemp(buffer.data());
  if (fd < 0) return SystemError("cannot create a file beside", path);
  // mkstemp makes it 0600; the file gets `mode` less the umask as open(2) would.
  const mode_t mask = ::umask(0);
  ::umask(mask);
  ::fchmod(fd, mode & ~mask);
  ::close(fd);
  std::unique_ptr<OutputFile> file(new OutputFile(path, buffer.data(), existing));
  file->stream_.open(file->temporary_, std::ios::binary | std::ios::trunc);
  if (!file->stream_) return SystemError("cannot write", file->temporary_);
  return file;
}

OutputFile::~OutputFile() {
  if (committed_) return;
  stream_.close();
  std::error_code ignored;
  std::filesystem::remove(temporary_, ignored);
}

absl::Status OutputFile::Commit() {
  stream_.flush();
  const bool written = static_cast<bool>(stream_);
  stream_.close();
  if (!written || stream_.fail()) {
    return absl::UnavailableError(absl::StrCat("writing ", temporary_, " failed: ",
                                               std::strerror(errno)));
  }
  if (absl::Status synced = SyncPath(temporary_, O_RDONLY); !synced.ok()) return synced;
  if (existing_ == Existing::kReplace) {
    if (::rename(temporary_.c_str(), path_.c_str()) != 0) {
      return SystemError(absl::StrCat("renaming ", temporary_, " to"), path_);
    }
  } else {
    // link(2) fails if the name exists: no check-then-rename race.
    if (::link(temporary_.c_str(), path_.c_str()) != 0) {
      if (errno == EEXIST) return AlreadyThere(path_);
      return SystemError(absl::StrCat("linking ", temporary_, " to"), path_);
    }
    ::unlink(temporary_.c_str());
  }
  committed_ = true;
  return SyncPath(DirectoryOf(path_), O_RDONLY | O_DIRECTORY);
}

}  // namespace totalgrad::cli
