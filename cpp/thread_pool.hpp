// A fixed pool of worker threads that runs one index range at a time in parallel.
// Workers are created once; a parallel_for allocates nothing and returns when all chunks ran.
#pragma once

#include <condition_variable>
#include <mutex>
#include <type_traits>
#include <thread>
#include <vector>

namespace socialnav {

class ThreadPool {
 public:
  explicit ThreadPool(int threads);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int size() const { return static_cast<int>(workers_.size()) + 1; }

  // Calls fn(begin, end, worker) over [0, n) split into size() contiguous chunks; the calling
  // thread runs chunk 0. `worker` indexes per-thread scratch space. The callable is passed by
  // reference through a plain function pointer, so a call allocates nothing.
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

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable start_cv_;
  std::condition_variable done_cv_;
  void* job_ctx_ = nullptr;
  Trampoline job_call_ = nullptr;
  int job_n_ = 0;
  long generation_ = 0;
  int pending_ = 0;
  bool stop_ = false;
};

}  // namespace socialnav
