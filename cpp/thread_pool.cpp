#include "thread_pool.hpp"

namespace socialnav {

ThreadPool::ThreadPool(int threads) {
  for (int w = 1; w < threads; ++w) workers_.emplace_back([this, w] { worker_loop(w); });
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  start_cv_.notify_all();
  for (auto& t : workers_) t.join();
}

namespace {
inline void chunk(int n, int parts, int part, int& begin, int& end) {
  begin = static_cast<int>(static_cast<long>(n) * part / parts);
  end = static_cast<int>(static_cast<long>(n) * (part + 1) / parts);
}
}  // namespace

void ThreadPool::run(int n, void* ctx, Trampoline call) {
  const int parts = size();
  if (parts == 1 || n < 2 * parts) {
    call(ctx, 0, n, 0);
    return;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    job_ctx_ = ctx;
    job_call_ = call;
    job_n_ = n;
    pending_ = parts - 1;
    ++generation_;
  }
  start_cv_.notify_all();
  int begin, end;
  chunk(n, parts, 0, begin, end);
  call(ctx, begin, end, 0);
  std::unique_lock<std::mutex> lock(mutex_);
  done_cv_.wait(lock, [this] { return pending_ == 0; });
  job_ctx_ = nullptr;
  job_call_ = nullptr;
}

void ThreadPool::worker_loop(int worker) {
  long seen = 0;
  for (;;) {
    void* ctx;
    Trampoline call;
    int n;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      start_cv_.wait(lock, [&] { return stop_ || generation_ != seen; });
      if (stop_) return;
      seen = generation_;
      ctx = job_ctx_;
      call = job_call_;
      n = job_n_;
    }
    int begin, end;
    chunk(n, size(), worker, begin, end);
    call(ctx, begin, end, worker);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (--pending_ == 0) done_cv_.notify_one();
    }
  }
}

}  // namespace socialnav
