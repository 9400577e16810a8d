// A small fixed pool of threads for the data-parallel loops of one trial
// (trial option `threads`, worker flag --threads-per-slot).
//
// Determinism contract: ParallelFor(tasks, fn) runs fn(0..tasks-1) exactly
// once each. Callers partition their work into tasks whose number and
// boundaries do NOT depend on the pool size (e.g. one task per GP output, or
// fixed blocks of particles), write each task's results to task-owned memory,
// and combine partial results in task order afterwards. Then the numbers are
// the same bits for any thread count, and a job gives the same result
// whichever worker runs it.
//
// Thread safety: ParallelFor must be called from one thread at a time (the
// pool's owner); fn runs concurrently on up to size() threads, the calling
// thread included. A pool of size 1 spawns no thread and runs every task on
// the caller, in order.
#ifndef TOTALGRAD_CORE_COMMON_THREAD_POOL_H_
#define TOTALGRAD_CORE_COMMON_THREAD_POOL_H_

#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace totalgrad {

class ThreadPool {
 public:
  // threads >= 1 (values below are treated as 1): the caller plus
  // threads - 1 worker threads started here and joined by the destructor.
  explicit ThreadPool(int threads);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int size() const { return static_cast<int>(workers_.size()) + 1; }

  // Runs fn(task) for every task in [0, tasks) and returns when all are done.
  // Tasks are claimed dynamically, so which thread runs a task is not fixed;
  // see the determinism contract above. fn must not throw and must not call
  // ParallelFor on the same pool.
  void ParallelFor(int tasks, const std::function<void(int)>& fn);

  // CPU seconds consumed so far by the worker threads (not the caller), so
  // that a trial can report its whole CPU cost: caller's thread CPU time +
  // this.
  double WorkerCpuSeconds() const;

 private:
  void WorkerLoop();
  // Claims and runs tasks of the current batch until none is left.
  void RunTasks();

  std::vector<std::thread> workers_;
  std::vector<uint64_t> worker_clock_ids_;  // clockid_t of each worker, for WorkerCpuSeconds
  mutable std::mutex mutex_;
  std::condition_variable work_ready_;
  std::condition_variable work_done_;
  // The current batch (guarded by mutex_ except where noted).
  const std::function<void(int)>* fn_ = nullptr;
  int tasks_ = 0;
  int next_task_ = 0;       // next unclaimed task
  int unfinished_ = 0;      // tasks not yet completed
  uint64_t generation_ = 0; // incremented per batch, wakes the workers
  bool stopping_ = false;
};

// CPU seconds of the calling thread (CLOCK_THREAD_CPUTIME_ID).
double ThreadCpuSeconds();

// Rows of particles handed to one task by the particle loops: a constant, so
// that the blocks (and any per-block partial result) never depend on the
// thread count.
constexpr int64_t kParticleBlock = 64;

// Runs fn(begin, end) for the blocks [0, block), [block, 2 block), ..., of
// [0, n) (the last may be shorter), on `pool` (may be null: in order on the
// caller). fn must only write what its block owns.
void ParallelForBlocks(ThreadPool* pool, int64_t n, int64_t block,
                       const std::function<void(int64_t, int64_t)>& fn);

}  // namespace totalgrad

#endif  // TOTALGRAD_CORE_COMMON_THREAD_POOL_H_
