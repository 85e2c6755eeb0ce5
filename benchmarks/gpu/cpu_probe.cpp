// Does a 16-vCPU machine give 16 cores' worth of arithmetic? (issue #32's scaling ceiling)
// Threads pinned to given CPUs each run a compute-bound loop (independent FMA chains: throughput,
// no memory) for a fixed time; prints the per-thread rate of each configuration against one thread
// alone. Two vCPUs sharing a physical core (hyper-threads the VM does not show) give about half each;
// a lower all-core frequency shows as a uniform drop with all 16 busy. Last line: one JSON object.
//   g++ -std=c++17 -O2 -mfma -pthread benchmarks/gpu/cpu_probe.cpp -o /tmp/cpu_probe && /tmp/cpu_probe
#include <pthread.h>
#include <sched.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <string>
#include <thread>
#include <vector>

namespace {

double fma_rate(double seconds) {  // giga-FMA per second of this thread
  double a[8] = {1, 2, 3, 4, 5, 6, 7, 8};
  const double m = 0.999999, c = 1e-7;
  long iters = 0;
  const auto start = std::chrono::steady_clock::now();
  double elapsed = 0;
  do {
    for (int i = 0; i < 100000; ++i)
      for (double& x : a) x = __builtin_fma(x, m, c);
    iters += 100000;
    elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  } while (elapsed < seconds);
  volatile double sink = a[0] + a[7];
  (void)sink;
  return 8.0 * iters / elapsed / 1e9;
}

std::vector<double> run_on(const std::vector<int>& cpus, double seconds) {
  std::vector<double> rates(cpus.size());
  std::vector<std::thread> threads;
  std::atomic<int> ready{0};
  for (size_t i = 0; i < cpus.size(); ++i)
    threads.emplace_back([&, i] {
      cpu_set_t set;
      CPU_ZERO(&set);
      CPU_SET(cpus[i], &set);
      pthread_setaffinity_np(pthread_self(), sizeof(set), &set);
      ready.fetch_add(1);
      while (ready.load() < static_cast<int>(cpus.size())) {
      }
      rates[i] = fma_rate(seconds);
    });
  for (auto& t : threads) t.join();
  return rates;
}

}  // namespace

int main() {
  const int n = static_cast<int>(std::thread::hardware_concurrency());
  const double s = 0.4;
  const double alone = run_on({0}, s)[0];
  std::printf("cpu 0 alone: %.2f GFMA/s\n", alone);
  std::string json =
      "{\"cpus\": " + std::to_string(n) + ", \"alone_gfma\": " + std::to_string(alone) + ", \"pair_with_0\": {";
  for (int k = 1; k < n; ++k) {
    const auto r = run_on({0, k}, s);
    std::printf("cpus 0+%d: %.2f %.2f (of alone: %.2f)\n", k, r[0], r[1], (r[0] + r[1]) / 2 / alone);
    json += (k > 1 ? ", \"" : "\"") + std::to_string(k) + "\": " + std::to_string((r[0] + r[1]) / 2 / alone);
  }
  json += "}, \"all_busy_of_alone\": {";
  for (int m : {2, 4, 8, 16}) {
    if (m > n) break;
    std::vector<int> cpus;
    for (int c = 0; c < m; ++c) cpus.push_back(c);
    const auto r = run_on(cpus, s);
    double sum = 0, lo = 1e30;
    for (double x : r) sum += x, lo = std::min(lo, x);
    std::printf("%2d busy: mean %.2f min %.2f GFMA/s per thread (%.2f of alone; total %.1fx)\n", m, sum / m, lo,
                sum / m / alone, sum / alone);
    json += (m > 2 ? ", \"" : "\"") + std::to_string(m) + "\": " + std::to_string(sum / m / alone);
  }
  std::printf("%s}}\n", json.c_str());
}
