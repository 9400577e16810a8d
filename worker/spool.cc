#include "worker/spool.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace totalgrad::worker {
namespace {

absl::Status ErrnoError(int error, const std::string& what) {
  const std::string message = absl::StrCat(what, ": ", std::strerror(error));
  if (error == EACCES || error == EPERM || error == EROFS) {
    return absl::PermissionDeniedError(message);
  }
  return absl::InternalError(message);
}

std::string HostName() {
  char buffer[256] = {};
  if (gethostname(buffer, sizeof(buffer) - 1) != 0) return "unknown-host";
  return buffer;
}

// Writes `bytes` to `path` atomically: temporary file, fsync, rename, fsync
// of the directory.
absl::Status WriteFileAtomically(const std::string& directory, const std::string& path,
                                 const std::string& bytes) {
  // Unique per write: two threads may spool the same attempt at once.
  static std::atomic<uint64_t> writes{0};
  const std::string temporary = absl::StrCat(path, ".tmp.", getpid(), ".", writes++);
  const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd < 0) return ErrnoError(errno, absl::StrCat("cannot create ", temporary));
  size_t written = 0;
  while (written < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + written, bytes.size() - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      const int error = errno;
      ::close(fd);
      ::unlink(temporary.c_str());
      return ErrnoError(error, absl::StrCat("cannot write ", temporary));
    }
    written += static_cast<size_t>(n);
  }
  if (::fsync(fd) != 0) {
    const int error = errno;
    ::close(fd);
    ::unlink(temporary.c_str());
    return ErrnoError(error, absl::StrCat("cannot fsync ", temporary));
  }
  ::close(fd);
  if (::rename(temporary.c_str(), path.c_str()) != 0) {
    const int error = errno;
    ::unlink(temporary.c_str());
    return ErrnoError(error, absl::StrCat("cannot rename ", temporary, " to ", path));
  }
  const int dir_fd = ::open(directory.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dir_fd >= 0) {
    ::fsync(dir_fd);
    ::close(dir_fd);
  }
  return absl::OkStatus();
}

}  // namespace

std::string EscapeWorkerId(const std::string& worker_id) {
  std::string escaped;
  for (unsigned char c : worker_id) {
    const bool keep = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                      c == '.' || c == '_' || c == '-';
    if (keep) {
      escaped.push_back(static_cast<char>(c));
    } else {
      absl::StrAppendFormat(&escaped, "%%%02X", c);
    }
  }
  return escaped;
}

absl::StatusOr<std::unique_ptr<Spool>> Spool::Open(const std::string& state_dir,
                                                   const std::string& worker_id) {
  // "id-" keeps ids like "." or ".." from naming a directory above.
  const std::string directory = absl::StrCat(state_dir, "/id-", EscapeWorkerId(worker_id));
  std::error_code created;
  std::filesystem::create_directories(state_dir, created);  // parents too (~/.local/state)
  for (const std::string& dir : {state_dir, directory, absl::StrCat(directory, "/spool")}) {
    if (::mkdir(dir.c_str(), 0700) != 0 && errno != EEXIST) {
      return ErrnoError(errno, absl::StrCat("cannot create the worker state directory ", dir));
    }
  }
  const std::string lock_path = absl::StrCat(directory, "/lock");
  const int fd = ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0600);
  if (fd < 0) return ErrnoError(errno, absl::StrCat("cannot open ", lock_path));
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int error = errno;
    std::string holder;
    std::ifstream in(lock_path);
    std::getline(in, holder);
    ::close(fd);
    if (error == EWOULDBLOCK) {
      return absl::FailedPreconditionError(absl::StrCat(
          "worker id '", worker_id, "' is already in use on this host by another worker process (",
          holder.empty() ? "holder unknown" : holder, "; lock ", lock_path,
          "); every worker needs its own --worker-id"));
    }
    return ErrnoError(error, absl::StrCat("cannot lock ", lock_path));
  }
  // Who holds it, for the message above (the lock, not this text, is what counts).
  const std::string holder = absl::StrCat(
      "pid ", getpid(), " on host ", HostName(), " since ",
      std::chrono::duration_cast<std::chrono::seconds>(
          std::chrono::system_clock::now().time_since_epoch())
          .count(),
      " (unix time)\n");
  if (::ftruncate(fd, 0) == 0) {
    (void)!::pwrite(fd, holder.data(), holder.size(), 0);
  }
  return std::unique_ptr<Spool>(new Spool(directory, fd));
}

Spool::~Spool() {
  if (lock_fd_ >= 0) ::close(lock_fd_);  // closing releases the flock
}

std::string Spool::PathOf(const v1::LeaseKey& key) const {
  return absl::StrCat(directory_, "/spool/job-", key.job_id(), "-attempt-", key.attempt(), ".pb");
}

absl::Status Spool::Put(const v1::SpooledAttempt& attempt) {
  std::string bytes;
  if (!attempt.SerializeToString(&bytes)) {
    return absl::InternalError("cannot serialise a spooled attempt");
  }
  return WriteFileAtomically(absl::StrCat(directory_, "/spool"), PathOf(attempt.lease()), bytes);
}

absl::Status Spool::Remove(const v1::LeaseKey& key) {
  const std::string path = PathOf(key);
  if (::unlink(path.c_str()) != 0 && errno != ENOENT) {
    return ErrnoError(errno, absl::StrCat("cannot remove ", path));
  }
  return absl::OkStatus();
}

std::vector<v1::SpooledAttempt> Spool::List(std::vector<std::string>* skipped) const {
  std::vector<v1::SpooledAttempt> attempts;
  std::error_code error;
  for (const auto& entry :
       std::filesystem::directory_iterator(absl::StrCat(directory_, "/spool"), error)) {
    const std::string path = entry.path().string();
    if (entry.path().extension() != ".pb") continue;  // temporaries of a crashed write
    std::ifstream in(path, std::ios::binary);
    std::ostringstream bytes;
    bytes << in.rdbuf();
    v1::SpooledAttempt attempt;
    if (!in || !attempt.ParseFromString(bytes.str()) ||
        attempt.format_version() != kSpoolFormatVersion) {
      if (skipped != nullptr) skipped->push_back(path);
      continue;
    }
    attempts.push_back(std::move(attempt));
  }
  std::sort(attempts.begin(), attempts.end(), [](const auto& a, const auto& b) {
    return std::make_pair(a.lease().job_id(), a.lease().attempt()) <
           std::make_pair(b.lease().job_id(), b.lease().attempt());
  });
  return attempts;
}

}  // namespace totalgrad::worker
