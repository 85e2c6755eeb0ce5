// The native thread pool's cost per job (issue #32's 16-core question), without the world around it.
// A job is a parallel_for over `slots` indices of light work, as the world's passes are over its
// episode slots; between jobs the caller works alone for `gap_us` (the Python between a step's passes).
// Prints, per thread count, microseconds per job (the gap left out), what it loses against a perfect
// split of the 1-thread time, and the time of an empty job; the last line is one JSON object.
//   g++ -std=c++17 -O2 -Icpp benchmarks/gpu/pool_latency.cpp cpp/thread_pool.cpp -lpthread -o /tmp/pool
//   /tmp/pool 1 2 4 8 16
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "thread_pool.hpp"

namespace {

using Clock = std::chrono::steady_clock;

void spin_us(double us) {
  const auto until = Clock::now() + std::chrono::duration<double, std::micro>(us);
  while (Clock::now() < until) {
  }
}

// Microseconds per job of `jobs` jobs: parallel_for over `slots` indices of ~`work_ns` each.
double per_job_us(socialnav::ThreadPool& pool, int slots, int jobs, double gap_us, std::vector<double>& data,
                  int work = 40) {
  const auto start = Clock::now();
  for (int j = 0; j < jobs; ++j) {
    pool.parallel_for(slots, [&](int begin, int end, int) {
      for (int i = begin; i < end; ++i) {
        double x = data[i];
        for (int k = 0; k < work; ++k) x = std::sqrt(x + 1.0);  // 40: ~0.15 us per slot, a light pass
        data[i] = x;
      }
    });
    spin_us(gap_us);
  }
  return std::chrono::duration<double, std::micro>(Clock::now() - start).count() / jobs - gap_us;
}

}  // namespace

int main(int argc, char** argv) {
  const int slots = 4096, jobs = 1500;
  const double gap_us = 20.0;
  std::vector<int> threads;
  for (int i = 1; i < argc; ++i) threads.push_back(std::atoi(argv[i]));
  if (threads.empty()) threads = {1, 2};
  std::vector<double> data(slots, 1.0);
  std::string json = "{\"slots\": " + std::to_string(slots) + ", \"gap_us\": 20, \"us_per_job\": {";
  double one = 0.0;
  for (size_t t = 0; t < threads.size(); ++t) {
    socialnav::ThreadPool pool(threads[t]);
    per_job_us(pool, slots, 200, gap_us, data);  // warm-up: threads started and spinning
    double best = 1e30;
    for (int r = 0; r < 3; ++r) best = std::min(best, per_job_us(pool, slots, jobs, gap_us, data));
    if (threads[t] == 1) one = best;
    double empty = 1e30;  // the same jobs with no work: the hand-out and the wait for the workers alone
    for (int r = 0; r < 3; ++r) empty = std::min(empty, per_job_us(pool, slots, jobs, gap_us, data, 0));
    const double lost = one > 0 ? best - one / threads[t] : 0.0;
    std::printf("%2d threads: %8.2f us per job, speed-up %.2f, %.2f us lost per job; empty job %.2f us\n", threads[t],
                best, one > 0 ? one / best : 1.0, lost, empty);
    json += (t ? ", \"" : "\"") + std::to_string(threads[t]) + "\": {\"us\": " + std::to_string(best) +
            ", \"lost_us\": " + std::to_string(lost) + ", \"empty_job_us\": " + std::to_string(empty) + "}";
  }
  std::printf("%s}}\n", json.c_str());
}
