#include "server/storage/sqlite_db.h"

#include <sqlite3.h>

#include <cmath>
#include <unordered_map>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"

namespace totalgrad::storage::internal {

// Released statements by their SQL text. The keys are never erased, so a
// Statement may hold a pointer to its key. SQL built with values in it (a
// view's name) would grow the map without bound: past kMaxTexts distinct
// texts, a new text is compiled and finalised as before.
class StatementCache {
 public:
  static constexpr size_t kMaxTexts = 256;
  static constexpr size_t kMaxFreePerText = 4;

  ~StatementCache() {
    for (auto& [sql, statements] : free_) {
      for (sqlite3_stmt* stmt : statements) sqlite3_finalize(stmt);
    }
  }

  // A released statement of `sql`, or null; *key is the cache's copy of the
  // text (null when the cache is full and does not know it).
  sqlite3_stmt* Take(absl::string_view sql, const std::string** key) {
    auto it = free_.find(std::string(sql));
    if (it == free_.end()) {
      if (free_.size() >= kMaxTexts) {
        *key = nullptr;
        return nullptr;
      }
      it = free_.emplace(std::string(sql), std::vector<sqlite3_stmt*>()).first;
    }
    *key = &it->first;
    if (it->second.empty()) return nullptr;
    sqlite3_stmt* stmt = it->second.back();
    it->second.pop_back();
    return stmt;
  }

  // Takes back a statement that was reset and cleared.
  void Give(const std::string& key, sqlite3_stmt* stmt) {
    std::vector<sqlite3_stmt*>& statements = free_[key];
    if (statements.size() >= kMaxFreePerText) {
      sqlite3_finalize(stmt);
      return;
    }
    statements.push_back(stmt);
  }

 private:
  std::unordered_map<std::string, std::vector<sqlite3_stmt*>> free_;
};

absl::Status SqliteError(int code, absl::string_view context, absl::string_view detail) {
  const std::string message = absl::StrCat("sqlite: ", context, ": ", detail, " (code ", code, ")");
  switch (code & 0xff) {
    case SQLITE_BUSY:
    case SQLITE_LOCKED:
      return absl::UnavailableError(message);
    case SQLITE_CORRUPT:
    case SQLITE_NOTADB:
      return absl::DataLossError(message);
    case SQLITE_FULL:
      return absl::UnavailableError(absl::StrCat("the disk is full; nothing was committed: ", message));
    case SQLITE_IOERR:
    case SQLITE_READONLY:
      return absl::UnavailableError(
          absl::StrCat("the disk failed or became read-only; nothing was committed: ", message));
    case SQLITE_CANTOPEN:
    case SQLITE_PERM:
      return absl::FailedPreconditionError(message);
    case SQLITE_CONSTRAINT:
      if (code == SQLITE_CONSTRAINT_PRIMARYKEY || code == SQLITE_CONSTRAINT_UNIQUE) {
        return absl::AlreadyExistsError(message);
      }
      return absl::InternalError(
          absl::StrCat("a value the service should have refused reached the database: ", message));
    default:
      return absl::InternalError(message);
  }
}

absl::StatusOr<Db> Db::Open(const std::string& path, bool create, int busy_timeout_ms) {
  sqlite3* raw = nullptr;
  const int flags = SQLITE_OPEN_READWRITE | (create ? SQLITE_OPEN_CREATE : 0) | SQLITE_OPEN_NOMUTEX;
  const int rc = sqlite3_open_v2(path.c_str(), &raw, flags, nullptr);
  if (rc != SQLITE_OK) {
    const std::string detail = raw ? sqlite3_errmsg(raw) : sqlite3_errstr(rc);
    sqlite3_close(raw);
    return SqliteError(rc, absl::StrCat("open ", path), detail);
  }
  sqlite3_extended_result_codes(raw, 1);
  sqlite3_busy_timeout(raw, busy_timeout_ms);
  return Db(raw);
}

absl::StatusOr<Db> Db::OpenReadOnly(const std::string& path, int busy_timeout_ms) {
  sqlite3* raw = nullptr;
  const int rc =
      sqlite3_open_v2(path.c_str(), &raw, SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX, nullptr);
  if (rc != SQLITE_OK) {
    const std::string detail = raw ? sqlite3_errmsg(raw) : sqlite3_errstr(rc);
    sqlite3_close(raw);
    return SqliteError(rc, absl::StrCat("open ", path, " read-only"), detail);
  }
  sqlite3_extended_result_codes(raw, 1);
  sqlite3_busy_timeout(raw, busy_timeout_ms);
  return Db(raw);
}

Db::Db(sqlite3* db) : db_(db), cache_(std::make_unique<StatementCache>()) {}
Db::Db(Db&& other) noexcept
    : db_(std::exchange(other.db_, nullptr)), cache_(std::move(other.cache_)) {}
Db& Db::operator=(Db&& other) noexcept {
  if (this != &other) {
    Close();
    db_ = std::exchange(other.db_, nullptr);
    cache_ = std::move(other.cache_);
  }
  return *this;
}
Db::~Db() { Close(); }

void Db::Close() {
  cache_.reset();  // finalises the cached statements
  // sqlite3_close fails only with unfinalised statements, which RAII rules
  // out (Statements do not outlive their Db).
  if (db_) sqlite3_close(db_);
  db_ = nullptr;
}

absl::Status Db::Exec(absl::string_view sql) {
  char* error = nullptr;
  const std::string text(sql);
  const int rc = sqlite3_exec(db_, text.c_str(), nullptr, nullptr, &error);
  if (rc != SQLITE_OK) {
    const std::string detail = error ? error : sqlite3_errmsg(db_);
    sqlite3_free(error);
    return SqliteError(rc, text.substr(0, 60), detail);
  }
  return absl::OkStatus();
}

int64_t Db::LastInsertRowId() const { return sqlite3_last_insert_rowid(db_); }
int Db::Changes() const { return sqlite3_changes(db_); }

absl::StatusOr<Statement> Statement::Prepare(const Db& db, absl::string_view sql) {
  const std::string* key = nullptr;
  StatementCache* cache = db.cache_.get();
  if (cache != nullptr) {
    if (sqlite3_stmt* cached = cache->Take(sql, &key); cached != nullptr) {
      return Statement(cached, db.raw(), cache, key);
    }
  }
  sqlite3_stmt* stmt = nullptr;
  const int rc = sqlite3_prepare_v3(db.raw(), sql.data(), static_cast<int>(sql.size()),
                                    key != nullptr ? SQLITE_PREPARE_PERSISTENT : 0, &stmt,
                                    nullptr);
  if (rc != SQLITE_OK) {
    sqlite3_finalize(stmt);
    return SqliteError(rc, absl::StrCat("prepare ", sql.substr(0, 60)), sqlite3_errmsg(db.raw()));
  }
  return Statement(stmt, db.raw(), key != nullptr ? cache : nullptr, key);
}

Statement::Statement(Statement&& other) noexcept
    : stmt_(std::exchange(other.stmt_, nullptr)),
      db_(other.db_),
      cache_(other.cache_),
      cached_sql_(other.cached_sql_),
      bind_error_(other.bind_error_) {}
Statement& Statement::operator=(Statement&& other) noexcept {
  if (this != &other) {
    Release();
    stmt_ = std::exchange(other.stmt_, nullptr);
    db_ = other.db_;
    cache_ = other.cache_;
    cached_sql_ = other.cached_sql_;
    bind_error_ = other.bind_error_;
  }
  return *this;
}
Statement::~Statement() { Release(); }

void Statement::Release() {
  if (stmt_ == nullptr) return;
  if (cache_ != nullptr && cached_sql_ != nullptr) {
    // A reset statement holds no lock and no read transaction; its bindings
    // (checkpoint blobs among them) are freed.
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
    cache_->Give(*cached_sql_, stmt_);
  } else {
    sqlite3_finalize(stmt_);
  }
  stmt_ = nullptr;
}

Statement& Statement::Bind(int index, int64_t value) {
  const int rc = sqlite3_bind_int64(stmt_, index, value);
  if (rc != SQLITE_OK && bind_error_ == 0) bind_error_ = rc;
  return *this;
}
Statement& Statement::Bind(int index, double value) {
  if (std::isnan(value)) return BindNull(index);
  const int rc = sqlite3_bind_double(stmt_, index, value);
  if (rc != SQLITE_OK && bind_error_ == 0) bind_error_ = rc;
  return *this;
}
Statement& Statement::Bind(int index, absl::string_view value) {
  const int rc =
      sqlite3_bind_text64(stmt_, index, value.data(), value.size(), SQLITE_TRANSIENT, SQLITE_UTF8);
  if (rc != SQLITE_OK && bind_error_ == 0) bind_error_ = rc;
  return *this;
}
Statement& Statement::BindBlob(int index, absl::string_view bytes) {
  const int rc = sqlite3_bind_blob64(stmt_, index, bytes.data(), bytes.size(), SQLITE_TRANSIENT);
  if (rc != SQLITE_OK && bind_error_ == 0) bind_error_ = rc;
  return *this;
}
Statement& Statement::BindNull(int index) {
  const int rc = sqlite3_bind_null(stmt_, index);
  if (rc != SQLITE_OK && bind_error_ == 0) bind_error_ = rc;
  return *this;
}

absl::StatusOr<bool> Statement::Step() {
  if (bind_error_ != 0) {
    return SqliteError(bind_error_, absl::string_view(sqlite3_sql(stmt_)).substr(0, 60), "bind failed");
  }
  const int rc = sqlite3_step(stmt_);
  if (rc == SQLITE_ROW) return true;
  if (rc == SQLITE_DONE) return false;
  return SqliteError(rc, absl::string_view(sqlite3_sql(stmt_)).substr(0, 60), sqlite3_errmsg(db_));
}

absl::Status Statement::Run() {
  while (true) {
    absl::StatusOr<bool> row = Step();
    if (!row.ok()) return row.status();
    if (!*row) return absl::OkStatus();
  }
}

void Statement::Reset() {
  sqlite3_reset(stmt_);
  sqlite3_clear_bindings(stmt_);
  bind_error_ = 0;
}

int64_t Statement::ColumnInt(int column) const { return sqlite3_column_int64(stmt_, column); }
double Statement::ColumnDouble(int column) const {
  if (sqlite3_column_type(stmt_, column) == SQLITE_NULL) return std::nan("");
  return sqlite3_column_double(stmt_, column);
}
std::string Statement::ColumnText(int column) const {
  const unsigned char* text = sqlite3_column_text(stmt_, column);
  const int bytes = sqlite3_column_bytes(stmt_, column);
  return text ? std::string(reinterpret_cast<const char*>(text), bytes) : std::string();
}
std::string Statement::ColumnBlob(int column) const {
  const void* blob = sqlite3_column_blob(stmt_, column);
  const int bytes = sqlite3_column_bytes(stmt_, column);
  return blob ? std::string(static_cast<const char*>(blob), bytes) : std::string();
}
bool Statement::ColumnIsNull(int column) const {
  return sqlite3_column_type(stmt_, column) == SQLITE_NULL;
}

}  // namespace totalgrad::storage::internal
