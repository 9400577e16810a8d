// Clocks, injected so that time-dependent logic (the scheduler's leases, the
// worker's heartbeats and drain deadlines) can be tested without waiting.
// Shared by the coordinator and the worker (this folder links no SQLite).
//
// Two time scales: the wall clock (what is recorded for people to read; NTP
// or an operator may step it) and the monotonic clock (never steps; every
// deadline is measured on it, never on the wall clock).
//
// Threading: implementations are safe to call from any thread.
#ifndef TOTALGRAD_RUNTIME_CLOCK_H_
#define TOTALGRAD_RUNTIME_CLOCK_H_

#include <atomic>
#include <cstdint>

#include "absl/base/thread_annotations.h"
#include "absl/synchronization/mutex.h"

namespace totalgrad {

class Clock {
 public:
  virtual ~Clock() = default;
  // Wall time, milliseconds since the Unix epoch: what is recorded for people
  // to read (submission, start and end times). May step.
  virtual int64_t NowMs() = 0;
  // Milliseconds since an arbitrary origin; never steps backwards or jumps
  // with the wall clock (CLOCK_MONOTONIC). Deadlines are measured on it.
  virtual int64_t MonotonicMs() = 0;
  // With `mu` held: waits (releasing `mu` meanwhile, as Mutex::Await does)
  // until `condition` holds or MonotonicMs() reaches `deadline_ms`, whichever
  // comes first; returns whether `condition` holds. `condition` is evaluated
  // with `mu` held, whenever `mu` is released by another thread, so it must
  // depend only on state changed under `mu` (or on this clock).
  virtual bool AwaitUntil(absl::Mutex* mu, const absl::Condition& condition, int64_t deadline_ms)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu) = 0;
};

class SystemClock final : public Clock {
 public:
  int64_t NowMs() override;        // absl::Now()
  int64_t MonotonicMs() override;  // std::chrono::steady_clock
  bool AwaitUntil(absl::Mutex* mu, const absl::Condition& condition, int64_t deadline_ms) override
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu);
};

// A clock that moves only when told to (tests). AdvanceMs moves both clocks
// (time passes); StepWallMs moves only the wall clock (an NTP step or a
// manual `date -s`); AdvanceMonotonicMs moves only the monotonic clock.
// AwaitUntil returns once another thread has moved the monotonic clock to
// the deadline (or the condition holds), however little real time passed.
class FakeClock final : public Clock {
 public:
  explicit FakeClock(int64_t start_ms = 1'700'000'000'000)
      : wall_ms_(start_ms), monotonic_ms_(1'000'000) {}
  int64_t NowMs() override { return wall_ms_.load(); }
  int64_t MonotonicMs() override { return monotonic_ms_.load(); }
  bool AwaitUntil(absl::Mutex* mu, const absl::Condition& condition, int64_t deadline_ms) override
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu);
  void AdvanceMs(int64_t ms) {
    wall_ms_ += ms;
    monotonic_ms_ += ms;
  }
  void StepWallMs(int64_t ms) { wall_ms_ += ms; }
  void AdvanceMonotonicMs(int64_t ms) { monotonic_ms_ += ms; }

 private:
  std::atomic<int64_t> wall_ms_;
  std::atomic<int64_t> monotonic_ms_;
};

}  // namespace totalgrad

#endif  // TOTALGRAD_RUNTIME_CLOCK_H_
