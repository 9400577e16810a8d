#include "server/storage/sqlite_store.h"

#include <fcntl.h>
#include <sqlite3.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <filesystem>
#include <set>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "runtime/status_macros.h"
#include "server/storage/sqlite_internal.h"
#include "server/storage/sqlite_schema.h"

namespace totalgrad::storage {

using internal::Db;
using internal::IsDatabaseFailure;
using internal::SteadyMs;
using internal::kSchemaVersion;
using internal::Migrate;
using internal::Statement;

namespace {


std::string HostName() {
  char buffer[256] = {};
  if (gethostname(buffer, sizeof(buffer) - 1) != 0) return "unknown-host";
  return buffer;
}

std::string ErrnoText(int error) { return std::strerror(error); }

// The exclusive lock beside the database. Returns its descriptor, and in
// *recorded what the previous holder wrote (empty if nothing).
absl::StatusOr<int> TakeLock(const std::string& path, std::string* recorded) {
  const std::string lock_path = absl::StrCat(path, ".lock");
  const int fd = ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0600);
  if (fd < 0) {
    return absl::FailedPreconditionError(absl::StrCat(
        "cannot open the lock file ", lock_path, ": ", ErrnoText(errno),
        " (the database's directory must be writable)"));
  }
  char buffer[4096];
  const ssize_t n = ::pread(fd, buffer, sizeof(buffer) - 1, 0);
  recorded->assign(buffer, n > 0 ? static_cast<size_t>(n) : 0);
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int error = errno;
    ::close(fd);
    if (error == EWOULDBLOCK) {
      std::string holder = recorded->substr(0, recorded->find('\n'));
      return absl::FailedPreconditionError(absl::StrCat(
          "database ", path, " is in use by another coordinator (",
          holder.empty() ? "holder unknown" : holder, "; lock file ", lock_path,
          "); stop it first, or use a copy (--backup) for reading"));
    }
    return absl::FailedPreconditionError(
        absl::StrCat("cannot lock ", lock_path, ": ", ErrnoText(error)));
  }
  return fd;
}

// Rewrites the lock file: who holds it, and which file is the database.
void RecordHolder(int fd, const std::string& path, uint64_t device, uint64_t inode) {
  const auto now = std::chrono::duration_cast<std::chrono::seconds>(
                       std::chrono::system_clock::now().time_since_epoch())
                       .count();
  const std::string text =
      absl::StrCat("pid ", getpid(), " on host ", HostName(), " since unix time ", now,
                   "\ndatabase ", path, " device:inode ", device, ":", inode, "\n");
  if (::ftruncate(fd, 0) == 0) (void)!::pwrite(fd, text.data(), text.size(), 0);
  ::fsync(fd);
}

// What is at `path` before anything is written to it.
enum class FileKind { kMissing, kEmpty, kEmptySqlite, kTotalgrad, };
struct Inspection {
  FileKind kind = FileKind::kMissing;
  int64_t version = 0;
};

// Looks at the file through a read-only connection. FailedPrecondition for a
// foreign file or a newer schema (nothing is written in either case).
absl::StatusOr<Inspection> InspectFile(const std::string& path, int busy_timeout_ms) {
  Inspection inspection;
  struct stat st;
  if (::stat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) return inspection;
    return absl::FailedPreconditionError(absl::StrCat("cannot stat ", path, ": ", ErrnoText(errno)));
  }
  if (!S_ISREG(st.st_mode)) {
    return absl::FailedPreconditionError(absl::StrCat(path, " is not a regular file"));
  }
  if (st.st_size == 0) {
    inspection.kind = FileKind::kEmpty;
    return inspection;
  }
  {
    char header[16] = {};
    std::ifstream in(path, std::ios::binary);
    in.read(header, sizeof(header));
    if (!in || std::memcmp(header, "SQLite format 3", 16) != 0) {
      return absl::FailedPreconditionError(absl::StrCat(
          path, " is not an SQLite database (a foreign file); refusing to touch it. Give --db a "
                "new path, or the right one"));
    }
  }
  ASSIGN_OR_RETURN(Db reader, Db::OpenReadOnly(path, busy_timeout_ms));
  ASSIGN_OR_RETURN(Statement version, Statement::Prepare(reader, "PRAGMA user_version"));
  ASSIGN_OR_RETURN(bool row, version.Step());
  inspection.version = row ? version.ColumnInt(0) : 0;
  ASSIGN_OR_RETURN(Statement tables, Statement::Prepare(reader, "SELECT COUNT(*) FROM sqlite_schema"));
  ASSIGN_OR_RETURN(row, tables.Step());
  const int64_t table_count = row ? tables.ColumnInt(0) : 0;
  if (inspection.version == 0) {
    if (table_count != 0) {
      return absl::FailedPreconditionError(absl::StrCat(
          path, " is an SQLite database but not a totalgrad one (it has tables and no totalgrad "
                "schema version); refusing to touch it"));
    }
    inspection.kind = FileKind::kEmptySqlite;
    return inspection;
  }
  if (inspection.version > kSchemaVersion) {
    return absl::FailedPreconditionError(absl::StrCat(
        path, " has totalgrad schema version ", inspection.version, "; this build reads version ",
        kSchemaVersion, " and older (the file was not changed): use a newer build"));
  }
  inspection.kind = FileKind::kTotalgrad;
  return inspection;
}

// Copies the database at `source` (read through `reader`) into `target`.
absl::StatusOr<int64_t> CopyDatabase(Db& source, const std::string& target, int busy_timeout_ms) {
  std::error_code error;
  if (std::filesystem::exists(target, error)) {
    return absl::AlreadyExistsError(absl::StrCat("backup target ", target, " already exists"));
  }
  // Copy into a temporary name and rename, so a crash never leaves a
  // half-written file under the requested name.
  const std::string temporary = absl::StrCat(target, ".partial");
  std::filesystem::remove(temporary, error);
  absl::Status status;
  {
    ASSIGN_OR_RETURN(Db destination, Db::Open(temporary, /*create=*/true, busy_timeout_ms));
    sqlite3_backup* backup = sqlite3_backup_init(destination.raw(), "main", source.raw(), "main");
    if (backup == nullptr) {
      return internal::SqliteError(sqlite3_errcode(destination.raw()), "backup init",
                                   sqlite3_errmsg(destination.raw()));
    }
    // One step copies everything from one read snapshot: the copy is
    // consistent even while the writer keeps committing.
    const int rc = sqlite3_backup_step(backup, -1);
    sqlite3_backup_finish(backup);
    if (rc != SQLITE_DONE) {
      status = internal::SqliteError(rc, "backup step", sqlite3_errstr(rc));
    } else {
      status = destination.Exec("PRAGMA journal_mode=DELETE");
    }
  }
  if (!status.ok()) {
    std::filesystem::remove(temporary, error);
    return status;
  }
  std::filesystem::rename(temporary, target, error);
  if (error) {
    return absl::InternalError(absl::StrCat("backup: rename ", temporary, " -> ", target, ": ",
                                            error.message()));
  }
  const auto size = std::filesystem::file_size(target, error);
  return error ? int64_t{0} : static_cast<int64_t>(size);
}


}  // namespace

absl::StatusOr<std::unique_ptr<SqliteStore>> SqliteStore::Open(const std::string& path,
                                                               const SqliteStoreOptions& options) {
  std::string recorded;
  ASSIGN_OR_RETURN(const int lock_fd, TakeLock(path, &recorded));
  // From here on the lock must be released on every error.
  absl::StatusOr<std::unique_ptr<SqliteStore>> opened = [&]()
      -> absl::StatusOr<std::unique_ptr<SqliteStore>> {
    ASSIGN_OR_RETURN(Inspection inspection, InspectFile(path, options.busy_timeout_ms));
    const bool recorded_database = recorded.find("\ndatabase ") != std::string::npos;
    switch (inspection.kind) {
      case FileKind::kMissing:
        if (recorded_database && !options.init) {
          return absl::FailedPreconditionError(absl::StrCat(
              "database ", path, " is missing, but its lock file records that a coordinator used "
              "a database there (", recorded.substr(recorded.find("\ndatabase ") + 1,
                                                    recorded.size()),
              "); it was deleted or moved. Restore it (e.g. from a backup), or pass --init to "
              "start a new, empty database"));
        }
        break;
      case FileKind::kEmpty:
      case FileKind::kEmptySqlite:
        if (!options.init) {
          return absl::FailedPreconditionError(absl::StrCat(
              path, " is ", inspection.kind == FileKind::kEmpty ? "an empty (0-byte) file"
                                                                : "an SQLite database without tables",
              ", not a totalgrad database; pass --init to initialise it as a new one"));
        }
        break;
      case FileKind::kTotalgrad:
        break;
    }
    ASSIGN_OR_RETURN(Db writer, Db::Open(path, /*create=*/true, options.busy_timeout_ms));
    // WAL lets the reader connection (and backups) run while the writer
    // commits; FULL makes every commit survive power loss, which matters more
    // than write speed here (a trial costs CPU-hours, a commit a millisecond).
    RETURN_IF_ERROR(writer.Exec("PRAGMA journal_mode=WAL"));
    RETURN_IF_ERROR(writer.Exec("PRAGMA synchronous=FULL"));
    // OFF while the schema is created or migrated (a migration may rebuild a
    // referenced table; internal::Migrate checks every key itself), ON after.
    RETURN_IF_ERROR(writer.Exec("PRAGMA foreign_keys=OFF"));
    {
      ASSIGN_OR_RETURN(Statement mode, Statement::Prepare(writer, "PRAGMA journal_mode"));
      ASSIGN_OR_RETURN(bool row, mode.Step());
      if (!row || mode.ColumnText(0) != "wal") {
        return absl::FailedPreconditionError(
            absl::StrCat("sqlite: ", path, " cannot use WAL journaling (journal_mode is '",
                         row ? mode.ColumnText(0) : "", "'); is it on a network file system?"));
      }
    }
    if (options.check_integrity_on_open) {
      ASSIGN_OR_RETURN(Statement check, Statement::Prepare(writer, "PRAGMA quick_check"));
      ASSIGN_OR_RETURN(bool row, check.Step());
      if (!row || check.ColumnText(0) != "ok") {
        return absl::DataLossError(absl::StrCat("sqlite: ", path, " failed its integrity check: ",
                                                row ? check.ColumnText(0) : "no answer"));
      }
    }
    if (inspection.kind != FileKind::kTotalgrad) {
      RETURN_IF_ERROR(writer.Exec("BEGIN IMMEDIATE"));
      absl::Status created = writer.Exec(internal::SchemaText());
      if (created.ok()) created = Migrate(writer, 1);
      if (created.ok()) created = writer.Exec("COMMIT");
      if (!created.ok()) {
        (void)writer.Exec("ROLLBACK");
        return created;
      }
    } else if (inspection.version < kSchemaVersion) {
      // An older totalgrad database: first a copy of it as it is (an older
      // build refuses the migrated file, and a migration is a one-way step),
      // then the migration in one transaction (all or nothing).
      std::string backup = absl::StrCat(path, ".schema-v", inspection.version, "-backup");
      for (int n = 1; std::filesystem::exists(backup); ++n) {
        backup = absl::StrCat(path, ".schema-v", inspection.version, "-backup.", n);
      }
      absl::StatusOr<int64_t> copied = BackupFile(path, backup);
      if (!copied.ok()) {
        return absl::Status(copied.status().code(),
                            absl::StrCat(path, ": not migrating from schema version ",
                                         inspection.version, ": the backup copy failed: ",
                                         copied.status().message()));
      }
      RETURN_IF_ERROR(writer.Exec("BEGIN IMMEDIATE"));
      absl::Status migrated = Migrate(writer, inspection.version);
      if (migrated.ok()) migrated = writer.Exec("COMMIT");
      if (!migrated.ok()) {
        (void)writer.Exec("ROLLBACK");
        return absl::Status(migrated.code(),
                            absl::StrCat(path, ": migrating from schema version ",
                                         inspection.version, " to ", kSchemaVersion,
                                         " failed: ", migrated.message()));
      }
    }
    RETURN_IF_ERROR(writer.Exec("PRAGMA foreign_keys=ON"));
    if (options.max_page_count > 0) {
      RETURN_IF_ERROR(
          writer.Exec(absl::StrCat("PRAGMA max_page_count=", options.max_page_count)));
    }
    ASSIGN_OR_RETURN(Db reader, Db::Open(path, /*create=*/false, options.busy_timeout_ms));
    RETURN_IF_ERROR(reader.Exec("PRAGMA foreign_keys=ON"));
    struct stat st;
    if (::stat(path.c_str(), &st) != 0) {
      return absl::FailedPreconditionError(
          absl::StrCat("cannot stat ", path, " after opening it: ", ErrnoText(errno)));
    }
    RecordHolder(lock_fd, path, st.st_dev, st.st_ino);
    return std::unique_ptr<SqliteStore>(new SqliteStore(path, options, std::move(writer),
                                                        std::move(reader), lock_fd, st.st_dev,
                                                        st.st_ino));
  }();
  if (!opened.ok()) ::close(lock_fd);
  return opened;
}

absl::StatusOr<std::unique_ptr<SqliteStore>> SqliteStore::OpenReadOnly(const std::string& path) {
  const SqliteStoreOptions options;
  ASSIGN_OR_RETURN(Inspection inspection, InspectFile(path, options.busy_timeout_ms));
  if (inspection.kind != FileKind::kTotalgrad) {
    return absl::FailedPreconditionError(absl::StrCat(
        path, inspection.kind == FileKind::kMissing ? " does not exist"
                                                     : " is not a totalgrad database",
        " (nothing to read)"));
  }
  if (inspection.version != kSchemaVersion) {
    return absl::FailedPreconditionError(absl::StrCat(
        path, " has schema version ", inspection.version, "; this build reads version ",
        kSchemaVersion,
        inspection.version < kSchemaVersion
            ? ": start a coordinator of this build on it once (it migrates the file, keeping a "
              "copy of the old one), or read it with the build that wrote it"
            : ": use a newer build"));
  }
  ASSIGN_OR_RETURN(Db writer, Db::OpenReadOnly(path, options.busy_timeout_ms));
  ASSIGN_OR_RETURN(Db reader, Db::OpenReadOnly(path, options.busy_timeout_ms));
  struct stat st;
  if (::stat(path.c_str(), &st) != 0) {
    return absl::FailedPreconditionError(
        absl::StrCat("cannot stat ", path, " after opening it: ", ErrnoText(errno)));
  }
  return std::unique_ptr<SqliteStore>(new SqliteStore(path, options, std::move(writer),
                                                      std::move(reader), /*lock_fd=*/-1,
                                                      st.st_dev, st.st_ino));
}

absl::StatusOr<int64_t> SqliteStore::BackupFile(const std::string& path, const std::string& target) {
  const int busy_timeout_ms = SqliteStoreOptions{}.busy_timeout_ms;
  ASSIGN_OR_RETURN(Inspection inspection, InspectFile(path, busy_timeout_ms));
  if (inspection.kind != FileKind::kTotalgrad) {
    return absl::FailedPreconditionError(
        absl::StrCat(path, " is not a totalgrad database (missing or empty); nothing to back up"));
  }
  ASSIGN_OR_RETURN(Db source, Db::OpenReadOnly(path, busy_timeout_ms));
  return CopyDatabase(source, target, busy_timeout_ms);
}

SqliteStore::SqliteStore(std::string path, SqliteStoreOptions options, Db writer, Db reader,
                         int lock_fd, uint64_t device, uint64_t inode)
    : path_(std::move(path)),
      options_(options),
      lock_fd_(lock_fd),
      device_(device),
      inode_(inode),
      writer_(std::move(writer)),
      reader_(std::move(reader)) {}

SqliteStore::~SqliteStore() {
  {
    absl::MutexLock lock(&write_mutex_);
    // Fold the WAL back into the main file so a copied file is complete
    // (not into a file that replaced ours; never from a read-only view).
    if (lock_fd_ >= 0 && file_error_.ok() && CheckFileIdentityLocked().ok()) {
      (void)writer_.Exec("PRAGMA wal_checkpoint(TRUNCATE)");
    }
    writer_ = Db();
  }
  {
    absl::MutexLock lock(&read_mutex_);
    reader_ = Db();
  }
  if (lock_fd_ >= 0) ::close(lock_fd_);  // releases the lock last, after both connections closed
}

absl::Status SqliteStore::CheckFileIdentityLocked() {
  if (!file_error_.ok()) return file_error_;
  struct stat st;
  std::string problem;
  if (::stat(path_.c_str(), &st) != 0) {
    problem = absl::StrCat("was deleted (", ErrnoText(errno), ")");
  } else if (st.st_dev != device_ || st.st_ino != inode_) {
    problem = absl::StrCat("was replaced by another file (device:inode ", device_, ":", inode_,
                           " when opened, now ", st.st_dev, ":", st.st_ino, ")");
  }
  if (problem.empty()) return absl::OkStatus();
  file_error_ = absl::UnavailableError(absl::StrCat(
      "database file ", path_, " ", problem,
      " while the coordinator was running; nothing is acknowledged any more (it would be lost "
      "with the old file). Restore the file and restart the coordinator"));
  return file_error_;
}

absl::Status SqliteStore::CheckWritable() {
  if (!write_mutex_.TryLock()) {
    // A write transaction is running. It is a sign of health unless it has
    // been waiting for SQLite's write lock (held by another connection or
    // process) for a while; the probe must not queue behind it either way.
    const int64_t waiting_since = lock_wait_since_ms_.load();
    const int64_t waited = waiting_since > 0 ? SteadyMs() - waiting_since : 0;
    if (waited >= kWriteLockWaitReportMs) {
      return absl::UnavailableError(absl::StrCat(
          "a write has waited ", waited, " ms for the database's write lock on ", path_,
          " (another process or connection holds it)"));
    }
    return absl::OkStatus();
  }
  absl::Status status = CheckWritableLocked();
  write_mutex_.Unlock();
  return status;
}

absl::Status SqliteStore::CheckWritableLocked() {
  RETURN_IF_ERROR(CheckFileIdentityLocked());
  const int64_t now = SteadyMs();
  constexpr int64_t kProbeIntervalMs = 5000;
  if (last_write_error_.ok() && now - last_commit_ms_ < kProbeIntervalMs) return absl::OkStatus();
  if (!last_write_error_.ok() && now - last_failure_or_probe_ms_ < kProbeIntervalMs) {
    return absl::UnavailableError(
        absl::StrCat("the last database commit failed: ", last_write_error_.message()));
  }
  // Find out with a commit of our own, waiting only briefly for the write
  // lock: a probe answers, it does not queue.
  last_failure_or_probe_ms_ = now;
  sqlite3_busy_timeout(writer_.raw(), static_cast<int>(kWriteLockWaitReportMs));
  absl::Status probe = writer_.Exec("BEGIN IMMEDIATE");
  sqlite3_busy_timeout(writer_.raw(), options_.busy_timeout_ms);
  if (!probe.ok() && sqlite3_errcode(writer_.raw()) == SQLITE_BUSY) {
    // Busy is not a failure of the disk: the next write may well succeed, so
    // it is not remembered as last_write_error_.
    return absl::UnavailableError(absl::StrCat(
        "the database's write lock on ", path_, " is held by another process or connection (",
        probe.message(), ")"));
  }
  if (probe.ok()) {
    probe = [&]() ABSL_EXCLUSIVE_LOCKS_REQUIRED(write_mutex_) -> absl::Status {
      ASSIGN_OR_RETURN(Statement upsert,
                       Statement::Prepare(writer_, "INSERT INTO meta(key, value) VALUES('health_probe', ?) "
                                                   "ON CONFLICT(key) DO UPDATE SET value = excluded.value"));
      upsert.Bind(1, std::to_string(now));
      RETURN_IF_ERROR(upsert.Run());
      return writer_.Exec("COMMIT");
    }();
    if (!probe.ok()) (void)writer_.Exec("ROLLBACK");
  }
  if (!probe.ok()) {
    last_write_error_ = probe;
    return absl::UnavailableError(absl::StrCat("a probe commit failed: ", probe.message()));
  }
  last_write_error_ = absl::OkStatus();
  last_commit_ms_ = now;
  return absl::OkStatus();
}

absl::StatusOr<std::string> SqliteStore::DescribeSettings() {
  absl::MutexLock lock(&write_mutex_);
  std::string description;
  for (const char* pragma : {"journal_mode", "synchronous", "foreign_keys", "busy_timeout"}) {
    ASSIGN_OR_RETURN(Statement query, Statement::Prepare(writer_, absl::StrCat("PRAGMA ", pragma)));
    ASSIGN_OR_RETURN(bool row, query.Step());
    absl::StrAppend(&description, description.empty() ? "" : " ", pragma, "=",
                    row ? query.ColumnText(0) : "?");
  }
  return description;
}

absl::Status SqliteStore::Ping() {
  absl::MutexLock lock(&read_mutex_);
  ASSIGN_OR_RETURN(Statement query,
                   Statement::Prepare(reader_, "SELECT COUNT(*) FROM sqlite_master"));
  ASSIGN_OR_RETURN(bool row, query.Step());
  if (!row) return absl::InternalError("SELECT COUNT(*) FROM sqlite_master returned no row");
  return absl::OkStatus();
}



absl::StatusOr<StoreCounts> SqliteStore::Counts() {
  absl::MutexLock lock(&read_mutex_);
  ASSIGN_OR_RETURN(Statement query, Statement::Prepare(reader_, R"sql(
SELECT (SELECT COUNT(*) FROM sweeps),
       (SELECT COUNT(*) FROM jobs WHERE state = 'queued'),
       (SELECT COUNT(*) FROM jobs WHERE state = 'running'))sql"));
  ASSIGN_OR_RETURN(bool row, query.Step());
  StoreCounts counts;
  if (row) {
    counts.sweeps = static_cast<int>(query.ColumnInt(0));
    counts.jobs_queued = static_cast<int>(query.ColumnInt(1));
    counts.jobs_running = static_cast<int>(query.ColumnInt(2));
  }
  return counts;
}

absl::StatusOr<int64_t> SqliteStore::Backup(const std::string& path) {
  ASSIGN_OR_RETURN(Db source, Db::OpenReadOnly(path_, options_.busy_timeout_ms));
  return CopyDatabase(source, path, options_.busy_timeout_ms);
}

absl::StatusOr<std::unique_ptr<Store>> OpenStoreForWriting(const std::string& path) {
  absl::StatusOr<std::unique_ptr<SqliteStore>> store = SqliteStore::Open(path);
  if (!store.ok()) return store.status();
  return std::unique_ptr<Store>(*std::move(store));
}

absl::StatusOr<std::unique_ptr<Store>> OpenStoreReadOnly(const std::string& path) {
  absl::StatusOr<std::unique_ptr<SqliteStore>> store = SqliteStore::OpenReadOnly(path);
  if (!store.ok()) return store.status();
  return std::unique_ptr<Store>(*std::move(store));
}

}  // namespace totalgrad::storage
