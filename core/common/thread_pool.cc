#include "core/common/thread_pool.h"

#include <pthread.h>
#include <time.h>

#include <algorithm>

namespace totalgrad {
namespace {

double ClockSeconds(clockid_t clock) {
  timespec ts;
  if (clock_gettime(clock, &ts) != 0) return 0.0;
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

}  // namespace

double ThreadCpuSeconds() { return ClockSeconds(CLOCK_THREAD_CPUTIME_ID); }

ThreadPool::ThreadPool(int threads) {
  const int extra = threads > 1 ? threads - 1 : 0;
  worker_clock_ids_.assign(extra, 0);
  workers_.reserve(extra);
  for (int w = 0; w < extra; ++w) {
    workers_.emplace_back([this] { WorkerLoop(); });
    clockid_t clock;
    if (pthread_getcpuclockid(workers_.back().native_handle(), &clock) == 0)
      worker_clock_ids_[w] = static_cast<uint64_t>(clock);
  }
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
    ++generation_;
  }
  work_ready_.notify_all();
  for (std::thread& t : workers_) t.join();
}

void ThreadPool::RunTasks() {
  for (;;) {
    int task;
    const std::function<void(int)>* fn;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (next_task_ >= tasks_) return;
      task = next_task_++;
      fn = fn_;
    }
    (*fn)(task);
    bool last;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      last = --unfinished_ == 0;
    }
    if (last) work_done_.notify_all();
  }
}

void ThreadPool::WorkerLoop() {
  uint64_t seen = 0;
  for (;;) {
    {
      std::unique_lock<std::mutex> lock(mutex_);
      work_ready_.wait(lock, [&] { return generation_ != seen; });
      seen = generation_;
      if (stopping_) return;
    }
    RunTasks();
  }
}

void ThreadPool::ParallelFor(int tasks, const std::function<void(int)>& fn) {
  if (tasks <= 0) return;
  if (workers_.empty() || tasks == 1) {
    for (int t = 0; t < tasks; ++t) fn(t);
    return;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    fn_ = &fn;
    tasks_ = tasks;
    next_task_ = 0;
    unfinished_ = tasks;
    ++generation_;
  }
  work_ready_.notify_all();
  RunTasks();
  std::unique_lock<std::mutex> lock(mutex_);
  work_done_.wait(lock, [&] { return unfinished_ == 0; });
  fn_ = nullptr;
  tasks_ = 0;
}

void ParallelForBlocks(ThreadPool* pool, int64_t n, int64_t block,
                       const std::function<void(int64_t, int64_t)>& fn) {
  if (n <= 0) return;
  const int64_t blocks = (n + block - 1) / block;
  auto run = [&](int b) {
    const int64_t begin = static_cast<int64_t>(b) * block;
    fn(begin, std::min(n, begin + block));
  };
  if (pool == nullptr || pool->size() == 1 || blocks == 1) {
    for (int64_t b = 0; b < blocks; ++b) run(static_cast<int>(b));
    return;
  }
  pool->ParallelFor(static_cast<int>(blocks), run);
}

double ThreadPool::WorkerCpuSeconds() const {
  double total = 0;
  for (uint64_t id : worker_clock_ids_)
    if (id != 0) total += ClockSeconds(static_cast<clockid_t>(id));
  return total;
}

}  // namespace totalgrad
