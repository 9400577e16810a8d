#include "runtime/clock.h"

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <mutex>
#include <thread>

#include "absl/time/clock.h"
#include "absl/time/time.h"

namespace totalgrad {
namespace {

// Releases the mutex of each SystemClock::AwaitUntil at its deadline, so the
// waiter's condition (which includes "the deadline has passed") is
// re-evaluated then. Why not Mutex::AwaitWithDeadline: this abseil
// (20220623) times its waits on CLOCK_REALTIME, so a wall-clock step back
// would stretch every waiting deadline by the step; this thread waits on
// std::chrono::steady_clock, which never steps, as the std::condition_variable
// waits it replaces did.
//
// Never blocks on a waiter's mutex (TryLock, retried every millisecond until
// the waiter has gone): a waiter holds its mutex when it registers and when
// it leaves, so blocking here while holding mutex_ could deadlock. A failed
// TryLock means another thread holds the mutex, and its Unlock re-evaluates
// the condition anyway. A registered mutex is alive: the waiter removes its
// entry before AwaitUntil returns.
class DeadlineWaker {
 public:
  static DeadlineWaker& Get() {
    static DeadlineWaker* const waker = new DeadlineWaker;  // never destroyed: its thread runs on
    return *waker;
  }

  uint64_t Add(absl::Mutex* mu, int64_t deadline_ms) {
    std::lock_guard<std::mutex> lock(mutex_);
    const uint64_t id = next_id_++;
    waiters_[id] = Waiter{mu, deadline_ms};
    changed_.notify_one();
    return id;
  }

  void Remove(uint64_t id) {
    std::lock_guard<std::mutex> lock(mutex_);
    waiters_.erase(id);
  }

 private:
  struct Waiter {
    absl::Mutex* mu;
    int64_t deadline_ms;  // on SystemClock::MonotonicMs()
  };

  DeadlineWaker() { std::thread([this] { Loop(); }).detach(); }

  static std::chrono::steady_clock::time_point At(int64_t ms) {
    return std::chrono::steady_clock::time_point(std::chrono::milliseconds(ms));
  }

  void Loop() {
    SystemClock clock;
    std::unique_lock<std::mutex> lock(mutex_);
    while (true) {
      const int64_t now = clock.MonotonicMs();
      int64_t next = INT64_MAX;
      for (auto& [id, waiter] : waiters_) {
        if (waiter.deadline_ms > now) {
          next = std::min(next, waiter.deadline_ms);
        } else {
          if (waiter.mu->TryLock()) waiter.mu->Unlock();  // the waiter re-evaluates
          next = std::min(next, now + 1);  // until it has removed itself
        }
      }
      if (next == INT64_MAX) {
        changed_.wait(lock);
      } else {
        changed_.wait_until(lock, At(next));
      }
    }
  }

  std::mutex mutex_;
  std::condition_variable changed_;
  uint64_t next_id_ = 0;
  std::map<uint64_t, Waiter> waiters_;
};

}  // namespace

int64_t SystemClock::NowMs() { return absl::ToUnixMillis(absl::Now()); }

int64_t SystemClock::MonotonicMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

bool SystemClock::AwaitUntil(absl::Mutex* mu, const absl::Condition& condition,
                             int64_t deadline_ms) {
  if (condition.Eval()) return true;
  if (MonotonicMs() >= deadline_ms) return false;
  // An untimed Await: the deadline is part of the condition, and
  // DeadlineWaker releases `mu` when it passes.
  const auto done = [&] { return condition.Eval() || MonotonicMs() >= deadline_ms; };
  const uint64_t id = DeadlineWaker::Get().Add(mu, deadline_ms);
  mu->Await(absl::Condition(&done));
  DeadlineWaker::Get().Remove(id);
  return condition.Eval();
}

bool FakeClock::AwaitUntil(absl::Mutex* mu, const absl::Condition& condition,
                           int64_t deadline_ms) {
  // Nothing releases `mu` when a test moves this clock, so the deadline is
  // re-checked every millisecond of real time as well: a waiter sees a move
  // within about 1 ms, and never returns before the clock reaches the
  // deadline unless the condition holds.
  const auto done = [&] { return condition.Eval() || monotonic_ms_.load() >= deadline_ms; };
  while (!mu->AwaitWithTimeout(absl::Condition(&done), absl::Milliseconds(1))) {
  }
  return condition.Eval();
}

}  // namespace totalgrad
