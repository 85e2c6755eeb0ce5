// A fixed pool of worker threads that runs one index range at a time in parallel.
// Workers are created once; a parallel_for allocates nothing and returns when all chunks ran.
#pragma once

#include <atomic>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <type_traits>
#include <vector>

namespace socialnav {

class ThreadPool {
 public:
  explicit ThreadPool(int threads);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int size() const { return static_cast<int>(workers_.size()) + 1; }

  // Calls fn(begin, end, worker) over contiguous chunks covering [0, n) exactly once; the calling
  // thread takes part. Each thread owns a contiguous share of [0, n) (the same share every call, so
  // the slots it steps stay in its cache from one call to the next) and works through it in chunks;
  // a thread that runs out steals the remaining chunks of the others, so one that the OS deschedules
  // or that wakes late does not hold the call up. Callers must not depend on which thread runs which
  // index (every use computes each index independently).
  // `worker` indexes per-thread scratch space. The callable is passed by reference through a plain
  // function pointer, so a call allocates nothing.
  template <typename F>
  void parallel_for(int n, F&& fn) {
    using Fn = std::remove_reference_t<F>;
    run(n, const_cast<void*>(static_cast<const void*>(&fn)),
        [](void* ctx, int begin, int end, int worker) { (*static_cast<Fn*>(ctx))(begin, end, worker); });
  }

 private:
  using Trampoline = void (*)(void*, int, int, int);
  void run(int n, void* ctx, Trampoline call);
  void worker_loop(int worker);
  void drain(void* ctx, Trampoline call, int n, int chunk, int worker);

  struct alignas(64) Share {   // one cache line each: threads bump their own counter
    std::atomic<int> next{0};  // first index of the share not handed out yet
    int end = 0;
  };

  std::vector<std::thread> workers_;
  std::mutex run_mutex_;  // one job at a time: Python threads may share a pool (the GIL is released)
  std::mutex mutex_;
  std::condition_variable start_cv_;
  std::condition_variable done_cv_;
  void* job_ctx_ = nullptr;
  Trampoline job_call_ = nullptr;
  int job_n_ = 0;
  int job_chunk_ = 1;
  std::vector<Share> shares_;  // one per thread
  // The job_* fields and the shares are written before generation_ is bumped (under mutex_, so that
  // a worker about to block cannot miss the change) and read by a worker after it sees the new
  // generation: the bump publishes them, and a worker that saw it while spinning reads them without
  // taking mutex_. They are not written again before every worker has decremented pending_.
  std::atomic<long> generation_{0};
  std::atomic<int> pending_{0};
  std::atomic<bool> stop_{false};
};

}  // namespace socialnav
