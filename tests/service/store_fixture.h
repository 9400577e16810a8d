// A fresh SqliteStore in a temporary directory for each test; the directory
// is removed after a test that passed (kept for a look after one that failed).
#ifndef TOTALGRAD_TESTS_SERVICE_STORE_FIXTURE_H_
#define TOTALGRAD_TESTS_SERVICE_STORE_FIXTURE_H_

#include <gtest/gtest.h>

#include <filesystem>
#include <memory>
#include <string>

#include "server/storage/sqlite_store.h"
#include "tests/testutil/test_base.h"  // MakeTempDir

namespace totalgrad::testing {

class FreshStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = MakeTempDir();
    auto store = storage::SqliteStore::Open(dir_ + "/store.db");
    ASSERT_TRUE(store.ok()) << store.status();
    store_ = std::move(*store);
  }
  void TearDown() override {
    store_.reset();
    if (!HasFailure()) std::filesystem::remove_all(dir_);
  }

  std::string dir_;
  std::unique_ptr<storage::SqliteStore> store_;
};

}  // namespace totalgrad::testing

#endif  // TOTALGRAD_TESTS_SERVICE_STORE_FIXTURE_H_
