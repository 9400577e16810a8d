#include "core/common/thread_pool.h"

#include <atomic>
#include <set>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace totalgrad {
namespace thread_pool_test {

TEST(ThreadPool, RunsEveryTaskExactlyOnce) {
  for (int threads : {1, 2, 3, 8}) {
    ThreadPool pool(threads);
    EXPECT_EQ(pool.size(), threads);
    for (int tasks : {0, 1, 2, 7, 100}) {
      std::vector<std::atomic<int>> runs(tasks);
      pool.ParallelFor(tasks, [&](int t) { runs[t].fetch_add(1); });
      for (int t = 0; t < tasks; ++t) EXPECT_EQ(runs[t].load(), 1) << threads << " " << t;
    }
  }
}

TEST(ThreadPool, SizeOneRunsInOrderOnTheCaller) {
  ThreadPool pool(1);
  std::vector<int> order;
  const std::thread::id caller = std::this_thread::get_id();
  bool all_on_caller = true;
  pool.ParallelFor(5, [&](int t) {
    order.push_back(t);
    all_on_caller = all_on_caller && std::this_thread::get_id() == caller;
  });
  EXPECT_EQ(order, (std::vector<int>{0, 1, 2, 3, 4}));
  EXPECT_TRUE(all_on_caller);
  EXPECT_EQ(pool.WorkerCpuSeconds(), 0.0);
}

TEST(ThreadPool, UsesTheWorkersAndCountsTheirCpuTime) {
  ThreadPool pool(2);
  std::mutex mutex;
  std::set<std::thread::id> seen;
  // Long enough tasks that the worker claims some of them.
  pool.ParallelFor(16, [&](int) {
    volatile double x = 0;
    for (int i = 0; i < 2000000; ++i) x = x + 1e-9 * i;
    std::lock_guard<std::mutex> lock(mutex);
    seen.insert(std::this_thread::get_id());
  });
  EXPECT_EQ(seen.size(), 2u);
  EXPECT_GT(pool.WorkerCpuSeconds(), 0.0);
}

TEST(ThreadPool, ManyBatchesInARow) {
  ThreadPool pool(3);
  long total = 0;
  for (int batch = 0; batch < 2000; ++batch) {
    std::vector<long> part(4, 0);
    pool.ParallelFor(4, [&](int t) { part[t] = t + batch; });
    for (long v : part) total += v;
  }
  long expected = 0;
  for (int batch = 0; batch < 2000; ++batch) expected += 6 + 4L * batch;
  EXPECT_EQ(total, expected);
}

}  // namespace thread_pool_test
}  // namespace totalgrad
