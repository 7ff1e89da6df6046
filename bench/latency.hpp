// Per-call latency measurement: warm-up, N individually timed calls with
// std::chrono::steady_clock, percentiles, and the clock's own overhead.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

namespace dn_bench {

struct Stats {
  double p50, p99, p999, p9999, max, mean, loop_per_call;  // [ns]
  long n;
};

// Percentile by nearest rank on a sorted sample.
inline double percentile(const std::vector<double>& sorted, double q) {
  if (sorted.empty()) return 0.0;
  const double rank = q * double(sorted.size() - 1);
  return sorted[static_cast<size_t>(rank + 0.5)];
}

inline Stats summarise(std::vector<double> ns, double loop_per_call) {
  std::sort(ns.begin(), ns.end());
  double sum = 0;
  for (double v : ns) sum += v;
  return {percentile(ns, 0.50), percentile(ns, 0.99), percentile(ns, 0.999),
          percentile(ns, 0.9999), ns.empty() ? 0.0 : ns.back(),
          ns.empty() ? 0.0 : sum / double(ns.size()), loop_per_call, long(ns.size())};
}

using Clock = std::chrono::steady_clock;

inline double ns_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::nano>(b - a).count();
}

// Times `call(i)` n times individually after `warmup` calls; `restore()` runs
// between batches of `batch` calls, outside the timed region, so every batch
// does the same work. Also times an untimed loop of the same calls.
template <class Call, class Restore>
Stats measure(Call&& call, Restore&& restore, long n, long warmup, long batch = 1000) {
  for (long i = 0; i < warmup; ++i) call(i);
  std::vector<double> ns(static_cast<size_t>(n));
  restore();
  for (long i = 0; i < n; ++i) {
    if (i % batch == 0) restore();
    const auto t0 = Clock::now();
    call(i);
    const auto t1 = Clock::now();
    ns[static_cast<size_t>(i)] = ns_between(t0, t1);
  }
  restore();
  const auto l0 = Clock::now();
  for (long i = 0; i < n; ++i) {
    if (i % batch == 0) restore();
    call(i);
  }
  const double loop = ns_between(l0, Clock::now()) / double(n);
  return summarise(std::move(ns), loop);
}

// The cost of the timing itself: two back-to-back clock reads.
inline Stats clock_overhead(long n) {
  std::vector<double> ns(static_cast<size_t>(n));
  for (long i = 0; i < n; ++i) {
    const auto t0 = Clock::now();
    const auto t1 = Clock::now();
    ns[static_cast<size_t>(i)] = ns_between(t0, t1);
  }
  return summarise(std::move(ns), 0.0);
}

inline void print_json(const std::string& name, const Stats& s, const char* extra = "") {
  std::printf(
      "{\"name\": \"%s\", \"n\": %ld, \"p50_ns\": %.1f, \"p99_ns\": %.1f, \"p999_ns\": %.1f, "
      "\"p9999_ns\": %.1f, \"max_ns\": %.1f, \"mean_ns\": %.2f, \"loop_ns_per_call\": %.2f%s}\n",
      name.c_str(), s.n, s.p50, s.p99, s.p999, s.p9999, s.max, s.mean, s.loop_per_call, extra);
  std::fflush(stdout);
}

}  // namespace dn_bench
