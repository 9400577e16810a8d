// The coordinator's clocks, injected so lease logic can be tested without
// waiting. Lease expiry is judged on the coordinator's monotonic clock only,
// never on a worker's clock and never on the wall clock (which NTP or an
// operator may step).
//
// Threading: implementations are safe to call from any thread.
#ifndef TOTALGRAD_SERVER_SCHEDULER_CLOCK_H_
#define TOTALGRAD_SERVER_SCHEDULER_CLOCK_H_

#include <atomic>
#include <cstdint>

namespace totalgrad::scheduler {

class Clock {
 public:
  virtual ~Clock() = default;
  // Wall time, milliseconds since the Unix epoch: what is recorded for people
  // to read (submission, start and end times). May step.
  virtual int64_t NowMs() = 0;
  // Milliseconds since an arbitrary origin; never steps backwards or jumps
  // with the wall clock (CLOCK_MONOTONIC). Lease deadlines are measured on it.
  virtual int64_t MonotonicMs() = 0;
};

class SystemClock final : public Clock {
 public:
  int64_t NowMs() override;
  int64_t MonotonicMs() override;  // std::chrono::steady_clock
};

// A clock that moves only when told to (tests). AdvanceMs moves both clocks
// (time passes); StepWallMs moves only the wall clock (an NTP step or a
// manual `date -s`); AdvanceMonotonicMs moves only the monotonic clock.
class FakeClock final : public Clock {
 public:
  explicit FakeClock(int64_t start_ms = 1'700'000'000'000)
      : wall_ms_(start_ms), monotonic_ms_(1'000'000) {}
  int64_t NowMs() override { return wall_ms_.load(); }
  int64_t MonotonicMs() override { return monotonic_ms_.load(); }
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

}  // namespace totalgrad::scheduler

#endif  // TOTALGRAD_SERVER_SCHEDULER_CLOCK_H_
