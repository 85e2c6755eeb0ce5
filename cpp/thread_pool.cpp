#include "thread_pool.hpp"

#include <chrono>

namespace socialnav {

ThreadPool::ThreadPool(int threads) : shares_(threads > 1 ? threads : 1) {
  for (int w = 1; w < threads; ++w) workers_.emplace_back([this, w] { worker_loop(w); });
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_.store(true);
    generation_.fetch_add(1);  // ends the spins of workers waiting for a job
  }
  start_cv_.notify_all();
  for (auto& t : workers_) t.join();
}

namespace {

// The caller of parallel_for, once out of chunks, usually waits only for the workers' last chunks:
// it spins briefly before blocking, since being woken costs tens of microseconds per call (a batched
// step makes several). Measured on 2 cores (benchmarks/bench_world.py): caller spin 50 us.
constexpr auto kCallerSpin = std::chrono::microseconds(50);

// A worker that finished a job spins this long for the next one before it sleeps. A batched step is
// a few jobs (a policy's actions, the world's step, its refill and observation) with some Python
// between them; a sleeping worker takes long to wake where idle CPUs halt (a virtual machine without
// guest halt-polling). Measured on the 2-core VM, a 256-slot observe job after a 20-200 us gap: 55-81 us
// with no worker spin, 14-24 us with this one. Spinning workers only pay on one pool: every World and
// native policy shares the process's pool (socialnav/sim/pool.py); workers of two pools would spin
// against each other's busy ones (measured worse, with one pool per World, in an earlier version).
constexpr auto kWorkerSpin = std::chrono::microseconds(300);

template <typename Ready>
bool spin_for(Ready ready, std::chrono::microseconds spin) {
  const auto until = std::chrono::steady_clock::now() + spin;
  for (;;) {
    for (int i = 0; i < 64; ++i)
      if (ready()) return true;
    if (std::chrono::steady_clock::now() >= until) return false;
  }
}

}  // namespace

void ThreadPool::drain(void* ctx, Trampoline call, int, int chunk, int worker) {
  const int parts = size();
  for (int k = 0; k < parts; ++k) {  // its own share first, then the others'
    Share& share = shares_[(worker + k) % parts];
    for (;;) {
      // A plain read first: an exhausted share's line is then only read, not fought over by 16 threads.
      if (k && share.next.load(std::memory_order_relaxed) >= share.end) break;
      const int begin = share.next.fetch_add(chunk, std::memory_order_relaxed);
      if (begin >= share.end) break;
      call(ctx, begin, begin + chunk < share.end ? begin + chunk : share.end, worker);
    }
  }
}

void ThreadPool::run(int n, void* ctx, Trampoline call) {
  const int parts = size();
  if (parts == 1 || n < 2 * parts) {
    call(ctx, 0, n, 0);
    return;
  }
  // 16 chunks per share: enough to even out a late or slow thread, few enough that 16 threads do not
  // spend the job fighting over the shares' counters. With the plain read in drain, this made 16-thread
  // world steps 5-11 % faster than 64 per share (benchmarks/results/gpu/README.md, runs 12-13).
  const int chunk = n / (16 * parts) > 1 ? n / (16 * parts) : 1;
  std::lock_guard<std::mutex> one_job(run_mutex_);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    job_ctx_ = ctx;
    job_call_ = call;
    job_n_ = n;
    job_chunk_ = chunk;
    for (int p = 0; p < parts; ++p) {
      shares_[p].next.store(static_cast<int>(static_cast<long>(n) * p / parts), std::memory_order_relaxed);
      shares_[p].end = static_cast<int>(static_cast<long>(n) * (p + 1) / parts);
    }
    pending_.store(parts - 1);
    generation_.fetch_add(1);
  }
  start_cv_.notify_all();
  drain(ctx, call, n, chunk, 0);
  if (!spin_for([this] { return pending_.load(std::memory_order_acquire) == 0; }, kCallerSpin)) {
    std::unique_lock<std::mutex> lock(mutex_);
    done_cv_.wait(lock, [this] { return pending_.load() == 0; });
  }
}

void ThreadPool::worker_loop(int worker) {
  long seen = 0;
  for (;;) {
    // A worker that sees the new job while spinning starts it at once, without mutex_: workers that
    // all took it to read the job queued on it one after the other at the start of each job, and
    // the caller waits for the last of them.
    if (!spin_for([&] { return generation_.load(std::memory_order_acquire) != seen; }, kWorkerSpin)) {
      std::unique_lock<std::mutex> lock(mutex_);
      start_cv_.wait(lock, [&] { return generation_.load(std::memory_order_acquire) != seen; });
    }
    if (stop_.load(std::memory_order_acquire)) return;
    seen = generation_.load(std::memory_order_acquire);
    drain(job_ctx_, job_call_, job_n_, job_chunk_, worker);
    if (pending_.fetch_sub(1, std::memory_order_acq_rel) == 1) {
      // Taking the mutex orders this notify after a caller that found pending_ > 0 started waiting.
      std::lock_guard<std::mutex> lock(mutex_);
      done_cv_.notify_one();
    }
  }
}

}  // namespace socialnav
