// The clocks' AwaitUntil (runtime/clock.h): the waits behind the
// worker's heartbeats and drain deadlines, the scheduler's long polls and the
// coordinator's lease loop. SystemClock's deadline is kept by its own
// steady-clock thread (abseil's timed waits follow the wall clock), so these
// check that it fires, that a condition made true by another thread ends the
// wait early, and that many waiters on one mutex each get their own deadline.
#include "runtime/clock.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#include "absl/synchronization/mutex.h"

namespace totalgrad {
namespace clock_test {

struct Flag {
  absl::Mutex mu;
  bool set ABSL_GUARDED_BY(mu) = false;
};

TEST(SystemClockTest, AwaitUntilReturnsFalseAtTheDeadline) {
  SystemClock clock;
  Flag flag;
  absl::MutexLock lock(&flag.mu);
  const int64_t start = clock.MonotonicMs();
  EXPECT_FALSE(clock.AwaitUntil(&flag.mu, absl::Condition(&flag.set), start + 100));
  const int64_t waited = clock.MonotonicMs() - start;
  EXPECT_GE(waited, 100);
  EXPECT_LT(waited, 5000);  // woken, not left waiting for ever
}

TEST(SystemClockTest, AwaitUntilReturnsTrueWhenAnotherThreadSetsTheCondition) {
  SystemClock clock;
  Flag flag;
  std::thread setter([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    absl::MutexLock lock(&flag.mu);
    flag.set = true;  // no notification: releasing the mutex re-evaluates the condition
  });
  const int64_t start = clock.MonotonicMs();
  {
    absl::MutexLock lock(&flag.mu);
    EXPECT_TRUE(clock.AwaitUntil(&flag.mu, absl::Condition(&flag.set), start + 60'000));
  }
  EXPECT_LT(clock.MonotonicMs() - start, 30'000);
  setter.join();
}

TEST(SystemClockTest, AwaitUntilChecksTheConditionFirstAndAPastDeadlineAtOnce) {
  SystemClock clock;
  Flag flag;
  absl::MutexLock lock(&flag.mu);
  EXPECT_FALSE(clock.AwaitUntil(&flag.mu, absl::Condition(&flag.set), clock.MonotonicMs() - 1));
  flag.set = true;
  EXPECT_TRUE(clock.AwaitUntil(&flag.mu, absl::Condition(&flag.set), clock.MonotonicMs() + 60'000));
}

// Waiters with different deadlines on one mutex (the worker's slot,
// heartbeat and deadline threads share one): each returns at its own.
TEST(SystemClockTest, ManyWaitersOnOneMutexEachMeetTheirDeadline) {
  SystemClock clock;
  Flag flag;
  const int64_t start = clock.MonotonicMs();
  std::vector<int64_t> waited(8, -1);
  std::vector<std::thread> threads;
  for (int i = 0; i < 8; ++i) {
    threads.emplace_back([&, i] {
      absl::MutexLock lock(&flag.mu);
      const bool set = clock.AwaitUntil(&flag.mu, absl::Condition(&flag.set), start + 20 * (i + 1));
      EXPECT_FALSE(set);
      waited[i] = clock.MonotonicMs() - start;
    });
  }
  for (auto& t : threads) t.join();
  for (int i = 0; i < 8; ++i) {
    EXPECT_GE(waited[i], 20 * (i + 1)) << "waiter " << i;
    EXPECT_LT(waited[i], 5000) << "waiter " << i;
  }
}

// FakeClock: a wait ends when another thread moves the clock to the
// deadline, not before, however much real time passes.
TEST(FakeClockTest, AwaitUntilEndsWhenTheClockReachesTheDeadline) {
  FakeClock clock;
  Flag flag;
  std::atomic<bool> returned{false};
  const int64_t deadline = clock.MonotonicMs() + 60'000;
  std::thread waiter([&] {
    absl::MutexLock lock(&flag.mu);
    EXPECT_FALSE(clock.AwaitUntil(&flag.mu, absl::Condition(&flag.set), deadline));
    returned = true;
  });
  clock.AdvanceMs(59'999);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));  // time to (wrongly) return
  EXPECT_FALSE(returned.load()) << "returned before the fake deadline";
  clock.StepWallMs(3'600'000);  // the wall clock does not count
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_FALSE(returned.load()) << "returned on a wall-clock step";
  clock.AdvanceMs(1);
  waiter.join();
  EXPECT_TRUE(returned.load());
}

TEST(FakeClockTest, AwaitUntilReturnsTrueWhenTheConditionIsSet) {
  FakeClock clock;
  Flag flag;
  std::thread setter([&] {
    absl::MutexLock lock(&flag.mu);
    flag.set = true;
  });
  {
    absl::MutexLock lock(&flag.mu);
    EXPECT_TRUE(clock.AwaitUntil(&flag.mu, absl::Condition(&flag.set), clock.MonotonicMs() + 1));
  }
  setter.join();
}

}  // namespace clock_test
}  // namespace totalgrad
