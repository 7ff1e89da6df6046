// Per-call latency measurement: warm-up, N individually timed calls with
// std::chrono::steady_clock, percentiles, and the clock's own overhead.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <iterator>
#include <string>
#include <utility>
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

// ---- cold-cache cost: a call right after other work evicted the caches -----------------
//
// What a loaded machine does to a real-time step between two calls, made repeatable: before
// each timed call, (1) a data sweep reads one byte of every 64-byte line of a buffer of the
// given size (4 MB: more than a core's L2, so the shared L2/L3 lose the step's code and data;
// 64 MB: more than the L3 of most machines, and 16k pages through the TLB), then (2) a code
// sweep runs kCodeSweepFns distinct functions once each through a table of pointers (about
// 100 KB of code, several times a core's L1i, and as many indirect branches: the L1i, the
// micro-op cache and the branch predictor lose the step's code). The code sweep alone (no
// data sweep) is the "code" case: the step's data stay cached, its code does not.
// A template, so that the sweep's functions are only compiled where it is used.
template <int kCodeSweepFns = 2048>
class CacheEvictor {
 public:
  explicit CacheEvictor(size_t max_data_bytes) : buf_(max_data_bytes, 1) {}

  // Reads one byte of every 64-byte line of the first `bytes` of the buffer.
  void evict_data(size_t bytes) {
    unsigned sum = 0;
    for (size_t i = 0, e = std::min(bytes, buf_.size()); i < e; i += 64) sum += buf_[i];
    sink_ = sink_ + sum;
  }

  // Runs every function of the code sweep once, in address order.
  void evict_code() { sink_ = sink_ + run(unsigned(sink_), std::make_integer_sequence<int, kCodeSweepFns>{}); }

  // The span of the code sweep's functions [bytes]: the highest function address minus the
  // lowest, plus one function's (the functions are laid out together).
  static size_t code_sweep_bytes() { return span(std::make_integer_sequence<int, kCodeSweepFns>{}); }

 private:
  // Distinct arithmetic per function (distinct constants), so no two are folded into one.
  template <int I>
  [[gnu::noinline]] static unsigned fn(unsigned x) {
    x = x * (2u * unsigned(I) + 1u) + unsigned(I) * 2654435761u;
    x ^= x >> (1 + I % 13);
    x = x * 0x9e3779b1u + unsigned(I * 7 + 3);
    x ^= x << (1 + I % 11);
    return x + unsigned(I) * 40503u;
  }
  using Fn = unsigned (*)(unsigned);
  template <int... I>
  static unsigned run(unsigned x, std::integer_sequence<int, I...>) {
    static constexpr Fn table[] = {&fn<I>...};
    for (Fn f : table) x = f(x);
    return x;
  }
  template <int... I>
  static size_t span(std::integer_sequence<int, I...>) {
    const uintptr_t a[] = {reinterpret_cast<uintptr_t>(&fn<I>)...};
    const auto mm = std::minmax_element(std::begin(a), std::end(a));
    const uintptr_t one = a[1] > a[0] ? a[1] - a[0] : a[0] - a[1];
    return size_t(*mm.second - *mm.first + one);
  }

  std::vector<unsigned char> buf_;
  volatile unsigned sink_ = 0;
};

struct ColdStats {
  double p50, p99;  // [ns]
  long n;
};

// `reps` single calls, each timed alone after restore() (outside the timed region, before
// the eviction, so it does not warm what the eviction evicted), a data sweep of `data_bytes`
// (0: none) and the code sweep. Percentiles by nearest rank, as summarise.
template <class Call, class Restore, class Evictor>
ColdStats measure_cold(Call&& call, Restore&& restore, Evictor& ev, size_t data_bytes, long reps) {
  std::vector<double> ns(static_cast<size_t>(reps));
  for (long r = 0; r < reps; ++r) {
    restore();
    if (data_bytes) ev.evict_data(data_bytes);
    ev.evict_code();
    const auto t0 = Clock::now();
    call(r);
    const auto t1 = Clock::now();
    ns[static_cast<size_t>(r)] = ns_between(t0, t1);
  }
  std::sort(ns.begin(), ns.end());
  return {percentile(ns, 0.50), percentile(ns, 0.99), reps};
}

inline void print_json(const std::string& name, const Stats& s, const char* extra = "") {
  std::printf(
      "{\"name\": \"%s\", \"n\": %ld, \"p50_ns\": %.1f, \"p99_ns\": %.1f, \"p999_ns\": %.1f, "
      "\"p9999_ns\": %.1f, \"max_ns\": %.1f, \"mean_ns\": %.2f, \"loop_ns_per_call\": %.2f%s}\n",
      name.c_str(), s.n, s.p50, s.p99, s.p999, s.p9999, s.max, s.mean, s.loop_per_call, extra);
  std::fflush(stdout);
}

}  // namespace dn_bench
