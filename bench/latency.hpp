// Per-call latency measurement: warm-up, N individually timed calls with
// std::chrono::steady_clock, percentiles, and the clock's own overhead.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
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

// Per-call latency without a clock read around every call: batches of `batch`
// calls timed together, each call's input chosen by the previous call's output
// (call(i, dep) returns a dependency token that is always 0 but that the CPU must
// wait for, see zero_dep), so the calls cannot overlap: this is their latency, not
// their throughput. The statistics are over the batches' per-call means, so the
// tails (p99 and beyond) are those of batch means, not of single calls; the clock
// pair costs clock_overhead / batch per call (~0.3 ns for batch 100), included.
template <class Call>
Stats measure_chained(Call&& call, long n, long warmup, long batch = 100) {
  long dep = 0;
  for (long i = 0; i < warmup; ++i) dep = call(i, dep);
  const long nb = std::max(1L, n / batch);
  std::vector<double> ns(static_cast<size_t>(nb));
  const auto l0 = Clock::now();
  for (long b = 0; b < nb; ++b) {
    const auto t0 = Clock::now();
    for (long k = 0; k < batch; ++k) dep = call(b * batch + k, dep);
    ns[static_cast<size_t>(b)] = ns_between(t0, Clock::now()) / double(batch);
  }
  const double loop = ns_between(l0, Clock::now()) / double(nb * batch);
  volatile long keep = dep;
  (void)keep;
  return summarise(std::move(ns), loop);
}

// 0, computed from the bits of v: a data dependency the compiler cannot fold away
// (g_zero is volatile) and that costs the CPU one AND after v is known.
inline volatile uint32_t g_zero = 0;
inline long zero_dep(float v) {
  uint32_t b;
  std::memcpy(&b, &v, sizeof b);
  return long(b & g_zero);
}
inline long zero_dep(double v) { return zero_dep(float(v)); }

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
