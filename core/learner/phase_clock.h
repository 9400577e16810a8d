// Where a trial's time goes: PhaseClock splits it into consecutive phases,
// each Lap adding the CPU and wall seconds since the previous Lap (or
// construction, or Restart) to one phase's totals. CPU time is the trial
// thread's plus its pool's worker threads'. Internal to core/learner.
#ifndef TOTALGRAD_CORE_LEARNER_PHASE_CLOCK_H_
#define TOTALGRAD_CORE_LEARNER_PHASE_CLOCK_H_

#include <chrono>

#include "core/common/thread_pool.h"

namespace totalgrad::learner {

class PhaseClock {
 public:
  // `pool` may be null (then only the calling thread counts).
  explicit PhaseClock(const ThreadPool* pool) : pool_(pool) { Restart(); }
  void Restart() {
    cpu_ = Cpu();
    wall_ = std::chrono::steady_clock::now();
  }
  void Lap(double* cpu, double* wall) {
    const double cpu_now = Cpu();
    const auto wall_now = std::chrono::steady_clock::now();
    *cpu += cpu_now - cpu_;
    *wall += std::chrono::duration<double>(wall_now - wall_).count();
    cpu_ = cpu_now;
    wall_ = wall_now;
  }

 private:
  double Cpu() const { return ThreadCpuSeconds() + (pool_ != nullptr ? pool_->WorkerCpuSeconds() : 0.0); }
  const ThreadPool* pool_;
  double cpu_ = 0;
  std::chrono::steady_clock::time_point wall_;
};

}  // namespace totalgrad::learner

#endif  // TOTALGRAD_CORE_LEARNER_PHASE_CLOCK_H_
