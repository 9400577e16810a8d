// The coordinator's clock, injected so lease logic can be tested without
// waiting. Lease expiry is judged on this clock only, never on a worker's.
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
  // Milliseconds since the Unix epoch.
  virtual int64_t NowMs() = 0;
};

// The wall clock (what is stored in the database is wall time, so people can
// read it; leases are long enough that an NTP step of a few seconds is harmless).
class SystemClock final : public Clock {
 public:
  int64_t NowMs() override;
};

// A clock that moves only when told to (tests).
class FakeClock final : public Clock {
 public:
  explicit FakeClock(int64_t start_ms = 1'700'000'000'000) : now_ms_(start_ms) {}
  int64_t NowMs() override { return now_ms_.load(); }
  void AdvanceMs(int64_t ms) { now_ms_ += ms; }
  void SetMs(int64_t ms) { now_ms_ = ms; }

 private:
  std::atomic<int64_t> now_ms_;
};

}  // namespace totalgrad::scheduler

#endif  // TOTALGRAD_SERVER_SCHEDULER_CLOCK_H_
