// SqliteStore's group commit (sqlite_write_queue.cc): writes that queue while
// a commit runs share the next transaction; a failing write is undone alone;
// a transaction that ends early or a COMMIT that fails stores nothing of its
// group and tells every write of it.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <atomic>
#include <filesystem>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/synchronization/mutex.h"
#include "server/storage/sqlite_internal.h"
#include "server/storage/sqlite_store.h"
#include "tests/service/store_fixture.h"

namespace totalgrad::storage {

// Reaches SqliteStore's write path with bodies of the test's own.
class SqliteStoreTestPeer {
 public:
  static absl::Status Write(SqliteStore& store,
                            const std::function<absl::Status(internal::Db&)>& body) {
    return store.InWriteTransaction(body);
  }
  static size_t Queued(SqliteStore& store) {
    absl::MutexLock lock(&store.queue_mutex_);
    return store.write_queue_.size();
  }
};

namespace {

absl::Status InsertMeta(internal::Db& db, const std::string& key) {
  return db.Exec(absl::StrCat("INSERT INTO meta(key, value) VALUES('", key, "', 'x')"));
}

class WriteQueueTest : public ::totalgrad::testing::FreshStoreTest {
 protected:
  void TearDown() override {
    for (std::thread& thread : threads_) thread.join();
    FreshStoreTest::TearDown();
  }

  // Starts a write whose body blocks until ReleaseBlocker(): the writes
  // started after it queue behind its transaction and form the next group.
  void StartBlocker() {
    threads_.emplace_back([this] {
      blocker_status_ = SqliteStoreTestPeer::Write(*store_, [this](internal::Db& db) {
        blocker_running_ = true;
        while (!release_blocker_) std::this_thread::yield();
        return InsertMeta(db, "blocker");
      });
    });
    while (!blocker_running_) std::this_thread::yield();
  }
  void ReleaseBlocker() { release_blocker_ = true; }

  // Starts a write on a thread of its own and waits until it has queued, so
  // the writes of a group run in the order they were started.
  void StartQueuedWrite(std::function<absl::Status(internal::Db&)> body, absl::Status* status) {
    const size_t before = SqliteStoreTestPeer::Queued(*store_);
    threads_.emplace_back([this, body = std::move(body), status] {
      *status = SqliteStoreTestPeer::Write(*store_, body);
    });
    while (SqliteStoreTestPeer::Queued(*store_) != before + 1) std::this_thread::yield();
  }
  void JoinAll() {
    for (std::thread& thread : threads_) thread.join();
    threads_.clear();
  }
  bool Stored(const std::string& key) {
    int64_t count = -1;
    const absl::Status status = SqliteStoreTestPeer::Write(*store_, [&](internal::Db& db) {
      auto query = internal::Statement::Prepare(db, "SELECT COUNT(*) FROM meta WHERE key = ?");
      if (!query.ok()) return query.status();
      query->Bind(1, key);
      absl::StatusOr<bool> row = query->Step();
      if (!row.ok()) return row.status();
      count = *row ? query->ColumnInt(0) : -1;
      return absl::OkStatus();
    });
    EXPECT_TRUE(status.ok()) << status;
    return count == 1;
  }

  std::vector<std::thread> threads_;
  std::atomic<bool> blocker_running_{false};
  std::atomic<bool> release_blocker_{false};
  absl::Status blocker_status_;
};

TEST_F(WriteQueueTest, WritesQueuedDuringACommitShareTheNextTransaction) {
  const WriteCounts before = store_->write_counts();
  StartBlocker();
  std::vector<absl::Status> statuses(5);
  for (int i = 0; i < 5; ++i) {
    StartQueuedWrite([i](internal::Db& db) { return InsertMeta(db, absl::StrCat("w", i)); },
                     &statuses[i]);
  }
  ReleaseBlocker();
  JoinAll();
  ASSERT_TRUE(blocker_status_.ok()) << blocker_status_;
  for (const absl::Status& status : statuses) EXPECT_TRUE(status.ok()) << status;
  const WriteCounts after = store_->write_counts();
  EXPECT_EQ(after.writes - before.writes, 6);
  // The blocker's transaction, then one for the five that queued behind it.
  EXPECT_EQ(after.commits - before.commits, 2);
  for (int i = 0; i < 5; ++i) EXPECT_TRUE(Stored(absl::StrCat("w", i))) << i;
}

TEST_F(WriteQueueTest, AFailingWriteIsUndoneAloneAndItsGroupCommits) {
  StartBlocker();
  absl::Status first, failing, last;
  StartQueuedWrite([](internal::Db& db) { return InsertMeta(db, "first"); }, &first);
  StartQueuedWrite(
      [](internal::Db& db) {
        absl::Status inserted = InsertMeta(db, "failing");
        if (!inserted.ok()) return inserted;
        return absl::InvalidArgumentError("refused after writing");
      },
      &failing);
  StartQueuedWrite([](internal::Db& db) { return InsertMeta(db, "last"); }, &last);
  ReleaseBlocker();
  JoinAll();
  EXPECT_TRUE(first.ok()) << first;
  EXPECT_EQ(failing.code(), absl::StatusCode::kInvalidArgument) << failing;
  EXPECT_EQ(failing.message(), "refused after writing");
  EXPECT_TRUE(last.ok()) << last;
  EXPECT_TRUE(Stored("first"));
  EXPECT_FALSE(Stored("failing"));
  EXPECT_TRUE(Stored("last"));
  // A failing write in a group does not make the store look unwritable.
  EXPECT_TRUE(store_->CheckWritable().ok());
}

TEST_F(WriteQueueTest, WhenTheTransactionEndsEarlyNothingOfItsGroupIsStored) {
  StartBlocker();
  absl::Status before_it, ending, after_it;
  StartQueuedWrite([](internal::Db& db) { return InsertMeta(db, "before"); }, &before_it);
  StartQueuedWrite(
      [](internal::Db& db) {
        // As SQLite does on a full disk or an I/O error inside a statement.
        absl::Status ended = db.Exec("ROLLBACK");
        if (!ended.ok()) return ended;
        return absl::ResourceExhaustedError("database or disk is full");
      },
      &ending);
  StartQueuedWrite([](internal::Db& db) { return InsertMeta(db, "after"); }, &after_it);
  ReleaseBlocker();
  JoinAll();
  EXPECT_EQ(ending.code(), absl::StatusCode::kResourceExhausted) << ending;
  for (const absl::Status* status : {&before_it, &after_it}) {
    EXPECT_EQ(status->code(), absl::StatusCode::kResourceExhausted) << *status;
    EXPECT_NE(status->message().find("the transaction carrying this write failed"),
              std::string::npos)
        << *status;
  }
  EXPECT_FALSE(Stored("before"));
  EXPECT_FALSE(Stored("after"));
  EXPECT_TRUE(Stored("blocker"));
}

int RefuseCommit(void*) { return 1; }

TEST_F(WriteQueueTest, AFailedCommitFailsEveryWriteOfItsGroup) {
  StartBlocker();
  absl::Status first, hooked, last;
  StartQueuedWrite([](internal::Db& db) { return InsertMeta(db, "first"); }, &first);
  StartQueuedWrite(
      [](internal::Db& db) {
        // A commit hook that returns non-zero turns the COMMIT into a rollback.
        sqlite3_commit_hook(db.raw(), &RefuseCommit, nullptr);
        return InsertMeta(db, "hooked");
      },
      &hooked);
  StartQueuedWrite([](internal::Db& db) { return InsertMeta(db, "last"); }, &last);
  ReleaseBlocker();
  JoinAll();
  for (const absl::Status* status : {&first, &hooked, &last}) {
    EXPECT_FALSE(status->ok());
    EXPECT_NE(status->message().find("the transaction carrying this write failed"),
              std::string::npos)
        << *status;
  }
  ASSERT_TRUE(SqliteStoreTestPeer::Write(*store_, [](internal::Db& db) {
                sqlite3_commit_hook(db.raw(), nullptr, nullptr);
                return absl::OkStatus();
              }).ok());
  EXPECT_FALSE(Stored("first"));
  EXPECT_FALSE(Stored("hooked"));
  EXPECT_FALSE(Stored("last"));
}

TEST_F(WriteQueueTest, ManyConcurrentWritersEachStoreEveryWriteOnce) {
  constexpr int kThreads = 16;
  constexpr int kWritesEach = 40;
  const WriteCounts before = store_->write_counts();
  std::vector<std::thread> writers;
  std::atomic<int> failures{0};
  for (int t = 0; t < kThreads; ++t) {
    writers.emplace_back([&, t] {
      for (int i = 0; i < kWritesEach; ++i) {
        const absl::Status status = SqliteStoreTestPeer::Write(*store_, [&](internal::Db& db) {
          return InsertMeta(db, absl::StrCat("t", t, "-", i));
        });
        if (!status.ok()) ++failures;
      }
    });
  }
  for (std::thread& writer : writers) writer.join();
  EXPECT_EQ(failures.load(), 0);
  const WriteCounts after = store_->write_counts();
  EXPECT_EQ(after.writes - before.writes, kThreads * kWritesEach);
  EXPECT_LE(after.commits - before.commits, kThreads * kWritesEach);
  int64_t stored = 0;
  ASSERT_TRUE(SqliteStoreTestPeer::Write(*store_, [&](internal::Db& db) {
                absl::StatusOr<int64_t> count = internal::QueryInt(
                    db, "SELECT COUNT(*) FROM meta WHERE key LIKE 't%-%' AND ? = 0", 0);
                if (!count.ok()) return count.status();
                stored = *count;
                return absl::OkStatus();
              }).ok());
  EXPECT_EQ(stored, kThreads * kWritesEach);
}

}  // namespace
}  // namespace totalgrad::storage
