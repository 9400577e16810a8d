// A thin RAII layer over the SQLite C API, internal to server/storage: this
// folder is the only place in the project that includes sqlite3.h.
//
// Every statement is prepared and every value bound as a parameter; no SQL is
// ever built from data. Errors are absl::Status: Unavailable for
// SQLITE_BUSY/LOCKED (retryable), DataLoss for SQLITE_CORRUPT/NOTADB,
// Unavailable also for SQLITE_FULL, SQLITE_IOERR and SQLITE_READONLY (the
// disk is full or failing: nothing was committed and a retry may succeed once
// it is fixed, so a worker keeps its results and retries), AlreadyExists for
// a violated PRIMARY KEY or UNIQUE constraint, Internal for any other
// constraint (validation should have refused the value first) and anything
// else; each message names the statement's purpose and SQLite's own text.
//
// Statements are cached per connection: Prepare hands out a statement of the
// same SQL text that an earlier Statement of this Db released (reset, its
// bindings cleared) instead of compiling the text again. Compiling was a
// third of the coordinator's CPU per job (issue 28: callgrind of
// service_load_bench, the job row query alone a quarter). A Statement in use
// is never handed out twice: a second Prepare of the same text while the
// first is alive compiles another.
//
// Threading: a Db and its Statements must be used by one thread at a time
// (callers hold a mutex). Statements must not outlive their Db.
#ifndef TOTALGRAD_SERVER_STORAGE_SQLITE_DB_H_
#define TOTALGRAD_SERVER_STORAGE_SQLITE_DB_H_

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include "absl/strings/string_view.h"

#include "absl/status/status.h"
#include "absl/status/statusor.h"

struct sqlite3;
struct sqlite3_stmt;

namespace totalgrad::storage::internal {

class StatementCache;  // sqlite_db.cc

// Maps an SQLite result code to a canonical status carrying `context`.
absl::Status SqliteError(int code, absl::string_view context, absl::string_view detail);

class Db {
 public:
  // Opens (creating if asked) the database file at `path`. Sets busy_timeout.
  static absl::StatusOr<Db> Open(const std::string& path, bool create, int busy_timeout_ms);
  // Opens an existing database for reading only: nothing this connection
  // does can change the file.
  static absl::StatusOr<Db> OpenReadOnly(const std::string& path, int busy_timeout_ms);
  Db() = default;
  Db(Db&& other) noexcept;
  Db& operator=(Db&& other) noexcept;
  Db(const Db&) = delete;
  Db& operator=(const Db&) = delete;
  ~Db();

  // Runs SQL text with no parameters and no results (pragmas, DDL, BEGIN).
  absl::Status Exec(absl::string_view sql);
  sqlite3* raw() const { return db_; }
  int64_t LastInsertRowId() const;
  // Rows changed by the last INSERT/UPDATE/DELETE.
  int Changes() const;

 private:
  friend class Statement;
  explicit Db(sqlite3* db);
  // Finalises the cached statements, then closes the connection.
  void Close();
  sqlite3* db_ = nullptr;
  // On the heap so that its address, which Statements hold, survives a move.
  std::unique_ptr<StatementCache> cache_;
};

// One prepared statement. Bind* take 1-based parameter indexes, Column*
// 0-based column indexes (SQLite's convention).
class Statement {
 public:
  static absl::StatusOr<Statement> Prepare(const Db& db, absl::string_view sql);
  Statement(Statement&& other) noexcept;
  Statement& operator=(Statement&& other) noexcept;
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  ~Statement();

  Statement& Bind(int index, int64_t value);
  Statement& Bind(int index, int value) { return Bind(index, static_cast<int64_t>(value)); }
  // NaN binds NULL.
  Statement& Bind(int index, double value);
  Statement& Bind(int index, absl::string_view value);
  Statement& Bind(int index, const char* value) { return Bind(index, absl::string_view(value)); }
  Statement& Bind(int index, const std::string& value) { return Bind(index, absl::string_view(value)); }
  Statement& BindNull(int index);
  Statement& BindBlob(int index, absl::string_view bytes);

  // Advances. true: a row is available; false: done. Binding errors are
  // reported here too.
  absl::StatusOr<bool> Step();
  // Steps to completion, expecting no rows.
  absl::Status Run();
  // Makes the statement ready to run again and clears its bindings.
  void Reset();

  int64_t ColumnInt(int column) const;
  // NULL reads as NaN.
  double ColumnDouble(int column) const;
  std::string ColumnText(int column) const;
  std::string ColumnBlob(int column) const;
  bool ColumnIsNull(int column) const;

 private:
  Statement(sqlite3_stmt* stmt, sqlite3* db, StatementCache* cache, const std::string* sql)
      : stmt_(stmt), db_(db), cache_(cache), cached_sql_(sql) {}
  // Gives the statement back to the cache it came from, or finalises it.
  void Release();
  sqlite3_stmt* stmt_ = nullptr;
  sqlite3* db_ = nullptr;
  StatementCache* cache_ = nullptr;        // null: not cached, finalised on release
  const std::string* cached_sql_ = nullptr;  // the cache's key, owned by the cache
  int bind_error_ = 0;  // first failing sqlite3_bind_* code
};

}  // namespace totalgrad::storage::internal

#endif  // TOTALGRAD_SERVER_STORAGE_SQLITE_DB_H_
