// Soak: a very long run of the quarter car with the default neural damper (the 3-30-1
// model of export/dn_model_default.h, float) and on-off skyhook, in the HIL
// configuration of `dampnet bench` (RK4, damper once per step, linearised acceleration
// coupling), on a random road generated on the fly in constant memory. Per window of
// steps it records: the latency distribution of dn_loop_step (every step timed with
// the TSC), the state's bounds, the energy balance, the process's RSS.
//
// Usage: dn_soak [--steps N] [--window W] [--speed V] [--seed S] [--csv FILE]
//                [--eval per_step|per_stage] [--accel linear|implicit|explicit]
// Output: one CSV row per window (FILE, default soak_windows.csv) and a summary
// (key = value lines) on stdout. Exit 1 when a check fails (see `checks` below).
//
// Road: the thesis's rough road's roughness as a stationary random process, so
// that it never repeats: ISO 8608 shape (displacement PSD Gd(n0) (n/n0)^-2, n0 = 0.1
// cycle/m) with a low-frequency cut at n_min = 1/92 cycle/m (the 92 m base profile's
// longest wave) and a high one at n_max = 2.83 cycle/m (the ISO band's top), driven at
// V m/s: the Ornstein-Uhlenbeck process dz = -a z dt + s dW, a = 2 pi n_min V, sampled
// exactly at the step (z_{k+1} = e^{-a dt} z_k + sigma sqrt(1 - e^{-2 a dt}) N(0,1)),
// with stationary RMS sigma = 0.016 m (the thesis road's RMS; Gd(n0) = 1.8e-4 m^3,
// ISO class C), then a first-order low-pass at 2 pi n_max V (exact for the sample
// held over the step), whose output is the road z_r; its rate v_r is the central
// difference of the neighbouring samples (Catmull-Rom: the loop's Hermite road is smooth).
// Normal variates from std::mt19937_64 and a Box-Muller transform: the road costs
// O(1) memory however long the run.
//
// Energy: with z from static equilibrium (gravity and f_static cancel),
//   E = 1/2 m_s v_s^2 + 1/2 m_us v_us^2 + 1/2 k_s (z_s - z_us)^2 + 1/2 k_t (z_us - z_r)^2
//   dE/dt = P_road - F v,   P_road = -k_t (z_us - z_r) v_r   (c_t = 0),
// so residual = E(t) - E(0) - W_road + W_damper must stay at the integration error.
// W_damper: the force is held over the step (per_step), so its work is F dx exactly
// (dx the step's change of z_s - z_us); per_stage: trapezoid of F v (2nd order only).
// W_road: see road_work() (exact in z_r v_r, 4th order in z_us v_r).
#include <x86intrin.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "dampnet/dampnet.h"
#include "dn_model_default.h"

namespace {

// Latency histogram in TSC cycles: exact bins below kLinear cycles, then 64 bins
// per power of two (1.6 % resolution) up to 2^40 cycles. Constant memory.
struct Histogram {
  static constexpr int kLinear = 8192, kSub = 64, kOct = 27;
  std::vector<uint64_t> bins = std::vector<uint64_t>(kLinear + kSub * kOct, 0);
  uint64_t n = 0, max = 0;
  double sum = 0;
  void add(uint64_t c) {
    ++n;
    sum += double(c);
    max = std::max(max, c);
    if (c < uint64_t(kLinear)) {
      ++bins[size_t(c)];
      return;
    }
    const int oct = 63 - __builtin_clzll(c) - 13;  // c >= 2^13
    const int sub = int((c >> (oct + 13 - 6)) & (kSub - 1));
    ++bins[size_t(kLinear + std::min(oct, kOct - 1) * kSub + sub)];
  }
  // Lower edge of a bin [cycles].
  double edge(size_t b) const {
    if (b < size_t(kLinear)) return double(b);
    const size_t k = b - kLinear;
    const int oct = int(k / kSub), sub = int(k % kSub);
    return std::ldexp(1.0 + sub / double(kSub), oct + 13);
  }
  double quantile(double q) const {
    const uint64_t rank = uint64_t(q * double(n - 1));
    uint64_t acc = 0;
    for (size_t b = 0; b < bins.size(); ++b) {
      acc += bins[b];
      if (acc > rank) return edge(b);
    }
    return double(max);
  }
  void clear() {  // in place: no allocation, no new pages touched
    std::fill(bins.begin(), bins.end(), 0);
    n = max = 0;
    sum = 0;
  }
};

std::string loadavg() {
  char buf[128] = {0};
  FILE* f = std::fopen("/proc/loadavg", "r");
  if (f) {
    if (!std::fgets(buf, sizeof buf, f)) buf[0] = 0;
    std::fclose(f);
  }
  std::string s(buf);
  while (!s.empty() && s.back() == '\n') s.pop_back();
  return s;
}

long rss_kb() {
  FILE* f = std::fopen("/proc/self/statm", "r");
  long pages = 0, resident = 0;
  if (f) {
    if (std::fscanf(f, "%ld %ld", &pages, &resident) != 2) resident = 0;
    std::fclose(f);
  }
  return resident * 4;  // 4 KiB pages
}

// The road: OU process (roughness) through a first-order low-pass (see the top),
// sampled at the step; the rate at a sample is the central difference of its
// neighbours (one sample of look-ahead), so that the loop's cubic Hermite road between
// samples is the smooth Catmull-Rom spline through them.
struct Road {
  std::mt19937_64 rng;
  double keep_ou, noise, keep_lp, h;
  double z_ou = 0, z_lp = 0;
  double z_prev = 0, z_cur = 0, z_next = 0;  // samples k-1, k, k+1
  bool has_spare = false;
  double spare = 0;
  Road(uint64_t seed, double speed, double dt, double rms) : rng(seed), h(dt) {
    const double a = 2 * M_PI * speed / 92.0;  // n_min = 1/92 cycle/m
    keep_ou = std::exp(-a * dt);
    noise = rms * std::sqrt(-std::expm1(-2 * a * dt));
    keep_lp = std::exp(-2 * M_PI * 2.83 * speed * dt);  // n_max = 2.83 cycle/m
    z_ou = rms * normal();  // start in the stationary distribution
    z_lp = z_ou;
    z_prev = sample();
    z_cur = sample();
    z_next = sample();
  }
  double uniform() { return (double(rng() >> 11) + 0.5) * 0x1.0p-53; }  // (0, 1)
  double normal() {
    if (has_spare) {
      has_spare = false;
      return spare;
    }
    const double r = std::sqrt(-2 * std::log(uniform())), p = 2 * M_PI * uniform();
    spare = r * std::sin(p);
    has_spare = true;
    return r * std::cos(p);
  }
  double sample() {
    z_lp = z_ou + (z_lp - z_ou) * keep_lp;
    z_ou = keep_ou * z_ou + noise * normal();
    return z_lp;
  }
  // The current sample (z_r, v_r).
  dn_loop_input now() const { return {z_cur, (z_next - z_prev) / (2 * h), 0.0}; }
  // Advance one step; the road and its rate at the step's end.
  dn_loop_input next() {
    z_prev = z_cur;
    z_cur = z_next;
    z_next = sample();
    return now();
  }
};

const char* arg(int argc, char** argv, const char* key, const char* def) {
  for (int i = 1; i + 1 < argc; ++i)
    if (std::strcmp(argv[i], key) == 0) return argv[i + 1];
  return def;
}

// An enum setting by its dampnet.h name (the lists' one spelling); -1 for an unknown name.
#define DN_SOAK_ROW_(id, value, name, doc) {name, value},
struct NamedValue {
  const char* name;
  int value;
};
constexpr NamedValue kEvals[] = {DN_DAMPER_EVAL_LIST(DN_SOAK_ROW_)};
constexpr NamedValue kAccels[] = {DN_ACCEL_FEATURE_LIST(DN_SOAK_ROW_)};
#undef DN_SOAK_ROW_
template <std::size_t N>
int by_name(const NamedValue (&table)[N], const std::string& name) {
  for (const auto& row : table)
    if (name == row.name) return row.value;
  return -1;
}

}  // namespace

int main(int argc, char** argv) {
  const double steps_d = std::atof(arg(argc, argv, "--steps", "1e9"));
  const double window_d = std::atof(arg(argc, argv, "--window", "1e7"));
  const long long n_steps = (long long)steps_d, window = (long long)window_d;
  const double speed = std::atof(arg(argc, argv, "--speed", "20"));
  const uint64_t seed = std::strtoull(arg(argc, argv, "--seed", "1"), nullptr, 10);
  const std::string csv_path = arg(argc, argv, "--csv", "soak_windows.csv");
  const std::string eval = arg(argc, argv, "--eval", "per_step");
  const std::string accel = arg(argc, argv, "--accel", "linear");
  const int eval_value = by_name(kEvals, eval), accel_value = by_name(kAccels, accel);
  if (eval_value < 0 || accel_value < 0) {
    std::fprintf(stderr, "dn_soak: error: unknown --eval '%s' or --accel '%s' (dampnet.h's "
                 "DN_DAMPER_EVAL_LIST / DN_ACCEL_FEATURE_LIST names)\n", eval.c_str(), accel.c_str());
    return 2;
  }
  if (n_steps < 1 || window < 1 || !(speed > 0)) {
    std::fprintf(stderr, "dn_soak: error: --steps, --window and --speed must be positive\n");
    return 2;
  }
  const long rss_start = rss_kb();
  const std::string load_start = loadavg();

  const dn_mlp_desc desc = DN_MODEL_DEFAULT_DESC_INIT;
  const char* const features[3] = {"velocity", "acceleration", "voltage"};
  dn_mlp* mlp = nullptr;
  dn_damper* damper = nullptr;
  dn_vehicle veh;
  dn_vehicle_default(&veh);
  veh.integrator = DN_INT_RK4;
  veh.damper_eval = eval_value;
  veh.accel_feature = accel_value;
  dn_controller ctrl;
  dn_controller_default(&ctrl, DN_CTRL_SKYHOOK_ONOFF);
  dn_loop_model* lm = nullptr;
  dn_loop_data* ld = nullptr;
  int st = dn_mlp_create(&desc, &mlp);
  if (st == DN_OK) st = dn_damper_create_neural(mlp, features, 3, nullptr, nullptr, 0, DN_PRECISION_FLOAT, &damper);
  if (st == DN_OK) st = dn_loop_model_create(&veh, damper, &ctrl, &lm);
  if (st == DN_OK) st = dn_loop_data_create(lm, &ld);
  if (st != DN_OK) {
    std::fprintf(stderr, "dn_soak: error: set-up failed: %s\n", dn_status_str(st));
    return 2;
  }
  // The model's force range [N] (the output's mapminmax range) for the spike count.
  const double f_lo = desc.out_offset, f_hi = desc.out_offset + 2.0 / desc.out_gain;
  const double f_margin = 0.5 * (f_hi - f_lo);  // a "spike": beyond the range by half its width

  const double rms = 0.016, dt = veh.dt;
  Road road(seed, speed, dt, rms);
  double s[DN_LOOP_STATE_SIZE];
  dn_loop_get_state(ld, s);
  const dn_loop_input r0 = road.now();
  s[5] = r0.z_r;  // z_r, v_r at t = 0; the car starts at rest at equilibrium on it
  s[6] = r0.v_r;
  s[1] = s[3] = r0.z_r;  // both masses on the road's level: no initial spring energy
  dn_loop_set_state(ld, s);

  auto energy = [&](const double* x) {
    return 0.5 * veh.m_s * x[2] * x[2] + 0.5 * veh.m_us * x[4] * x[4] +
           0.5 * veh.k_s * (x[1] - x[3]) * (x[1] - x[3]) + 0.5 * veh.k_t * (x[3] - x[5]) * (x[3] - x[5]);
  };
  // Road work over a step from state a to state b: P_road = -k_t z_us v_r + k_t z_r v_r;
  // the second term integrates exactly over the Hermite road (k_t (z_r1^2 - z_r0^2) / 2),
  // the first by the end-corrected trapezoid (Euler-Maclaurin, 4th order): g = z_us v_r,
  // g' = v_us v_r + z_us a_r with the Hermite road's one-sided accelerations a_r.
  auto road_work = [&](const double* a, const double* b) {
    const double h = veh.dt, dz = b[5] - a[5];
    const double ar0 = 6 * dz / (h * h) - (4 * a[6] + 2 * b[6]) / h;
    const double ar1 = -6 * dz / (h * h) + (2 * a[6] + 4 * b[6]) / h;
    const double g0 = a[3] * a[6], g1 = b[3] * b[6];
    const double gp0 = a[4] * a[6] + a[3] * ar0, gp1 = b[4] * b[6] + b[3] * ar1;
    const double int_g = 0.5 * h * (g0 + g1) - h * h / 12.0 * (gp1 - gp0);
    return -veh.k_t * int_g + 0.5 * veh.k_t * (b[5] * b[5] - a[5] * a[5]);
  };
  const double e0 = energy(s);

  FILE* csv = std::fopen(csv_path.c_str(), "w");
  if (!csv) {
    std::fprintf(stderr, "dn_soak: error: cannot write %s\n", csv_path.c_str());
    return 2;
  }
  std::fprintf(csv,
               "window,step_end,t_end_s,p50_ns,p99_ns,p999_ns,max_ns,mean_ns,rss_kb,energy_J,"
               "road_work_J,damper_work_J,residual_J,residual_window_J,max_abs_z_s_m,max_abs_z_us_m,"
               "max_abs_v_s_m_s,max_abs_force_N,max_abs_z_r_m,rms_z_r_m,n_errors,n_saturated,"
               "n_unconverged,n_fallback,n_spikes\n");

  // TSC frequency: calibrated against steady_clock over the whole run (printed), and a
  // first estimate over 200 ms for the windows' figures.
  using Clock = std::chrono::steady_clock;
  auto calibrate = [](Clock::time_point t0, uint64_t c0) {
    const auto t1 = Clock::now();
    const uint64_t c1 = __rdtsc();
    return double(c1 - c0) / std::chrono::duration<double, std::nano>(t1 - t0).count();
  };
  const auto cal_t0 = Clock::now();
  const uint64_t cal_c0 = __rdtsc();
  while (Clock::now() - cal_t0 < std::chrono::milliseconds(200)) {
  }
  const double ghz = calibrate(cal_t0, cal_c0);

  Histogram hist, total_hist;
  double w_road = 0, w_damper = 0, resid_prev = 0;
  double max_res = 0;
  long long n_err = 0, n_sat = 0, n_unconv = 0, n_fallback = 0, n_spike = 0;
  double mx_zs = 0, mx_zus = 0, mx_vs = 0, mx_f = 0, mx_zr = 0, sum_zr2 = 0;
  double all_mx_zs = 0, all_mx_zus = 0, all_mx_vs = 0, all_mx_f = 0, all_mx_zr = 0;
  long long all_err = 0, all_sat = 0, all_unconv = 0, all_fallback = 0, all_spike = 0;
  long rss_max = 0, rss_first_window = 0;
  double worst_p999 = 0, best_p999 = 1e300;
  double s1[DN_LOOP_STATE_SIZE];
  dn_loop_out out;
  const bool per_step = veh.damper_eval == DN_EVAL_PER_STEP;
  const auto run_t0 = Clock::now();
  const uint64_t run_c0 = __rdtsc();
  long long k = 0;
  int win = 0;
  bool state_ok = true;
  while (k < n_steps) {
    const dn_loop_input in = road.next();
    const uint64_t c0 = __rdtsc();
    st = dn_loop_step(lm, ld, &in, &out);
    const uint64_t c1 = __rdtsc();
    hist.add(c1 - c0);
    ++k;
    if (st < 0) {
      ++n_err;  // state unchanged: the road moved on without the car (counted, reported)
      s[5] = in.z_r;
      s[6] = in.v_r;
      dn_loop_set_state(ld, s);
      continue;
    }
    if (st & DN_W_SATURATED) ++n_sat;
    if (st & DN_W_ACCEL_UNCONVERGED) ++n_unconv;
    if (st & DN_W_ACCEL_FALLBACK) ++n_fallback;  // the linearised step kept the explicit value
    dn_loop_get_state(ld, s1);
    // Energy flows over the step [J].
    w_road += road_work(s, s1);
    if (per_step) {
      w_damper += out.force * ((s1[1] - s1[3]) - (s[1] - s[3]));
    } else {
      double nxt;
      dn_loop_out o2;
      const dn_loop_input none{in.z_r, in.v_r, 0.0};
      dn_loop_forward(lm, ld, &none, &o2);
      nxt = o2.force * o2.v;
      w_damper += 0.5 * dt * (out.force * out.v + nxt);
    }
    const double f = out.force;
    if (f < f_lo - f_margin || f > f_hi + f_margin) ++n_spike;
    mx_zs = std::max(mx_zs, std::fabs(s1[1]));
    mx_zus = std::max(mx_zus, std::fabs(s1[3]));
    mx_vs = std::max(mx_vs, std::fabs(s1[2]));
    mx_f = std::max(mx_f, std::fabs(f));
    mx_zr = std::max(mx_zr, std::fabs(s1[5]));
    sum_zr2 += s1[5] * s1[5];
    if (!(std::fabs(s1[1]) < 1.0 && std::fabs(s1[3]) < 1.0)) state_ok = false;  // 1 m: runaway
    std::memcpy(s, s1, sizeof s);

    if (k % window == 0 || k == n_steps) {
      const double e = energy(s), resid = e - e0 - w_road + w_damper;
      const long rss = rss_kb();
      if (win == 0) rss_first_window = rss;
      rss_max = std::max(rss_max, rss);
      const double p50 = hist.quantile(0.5) / ghz, p99 = hist.quantile(0.99) / ghz,
                   p999 = hist.quantile(0.999) / ghz, mx = double(hist.max) / ghz,
                   mean = hist.sum / double(hist.n) / ghz;
      worst_p999 = std::max(worst_p999, p999);
      best_p999 = std::min(best_p999, p999);
      max_res = std::max(max_res, std::fabs(resid));
      std::fprintf(csv, "%d,%lld,%.3f,%.1f,%.1f,%.1f,%.1f,%.2f,%ld,%.6e,%.6e,%.6e,%.6e,%.6e,%.6e,%.6e,%.6e,%.6e,%.6e,%.6e,%lld,%lld,%lld,%lld,%lld\n",
                   win, k, s[0], p50, p99, p999, mx, mean, rss, e, w_road, w_damper, resid,
                   resid - resid_prev, mx_zs, mx_zus, mx_vs, mx_f, mx_zr,
                   std::sqrt(sum_zr2 / double(hist.n)), n_err, n_sat, n_unconv, n_fallback, n_spike);
      std::fflush(csv);
      std::fprintf(stderr, "window %d: %lld steps, p50 %.0f p99 %.0f p99.9 %.0f max %.0f ns, RSS %ld kB, residual %.3e J\n",
                   win, k, p50, p99, p999, mx, rss, resid);
      resid_prev = resid;
      all_mx_zs = std::max(all_mx_zs, mx_zs);
      all_mx_zus = std::max(all_mx_zus, mx_zus);
      all_mx_vs = std::max(all_mx_vs, mx_vs);
      all_mx_f = std::max(all_mx_f, mx_f);
      all_mx_zr = std::max(all_mx_zr, mx_zr);
      all_err += n_err;
      all_sat += n_sat;
      all_unconv += n_unconv;
      all_fallback += n_fallback;
      all_spike += n_spike;
      for (size_t b = 0; b < hist.bins.size(); ++b) total_hist.bins[b] += hist.bins[b];
      total_hist.n += hist.n;
      total_hist.sum += hist.sum;
      total_hist.max = std::max(total_hist.max, hist.max);
      hist.clear();
      mx_zs = mx_zus = mx_vs = mx_f = mx_zr = sum_zr2 = 0;
      n_err = n_sat = n_unconv = n_fallback = n_spike = 0;
      ++win;
    }
  }
  std::fclose(csv);
  const double wall_s = std::chrono::duration<double>(Clock::now() - run_t0).count();
  const double ghz_run = calibrate(run_t0, run_c0);
  const double e_end = energy(s), resid = e_end - e0 - w_road + w_damper;
  const long rss_end = rss_kb();
  // Checks: no error step, bounded state, no spike beyond the force range, residual small
  // against the energy that flowed through (damper dissipation), RSS flat after window 0.
  const bool ok_err = all_err == 0, ok_state = state_ok, ok_spike = all_spike == 0;
  const bool ok_energy = std::fabs(resid) <= 1e-3 * std::fabs(w_damper);
  const bool ok_rss = rss_end - rss_first_window <= 64;  // kB: no growth after the start
  std::printf("steps = %lld\nwindows = %d\nwindow_steps = %lld\nsimulated_s = %.1f\nwall_s = %.1f\n"
              "ns_per_step_including_timing = %.1f\ntsc_ghz = %.4f (first estimate %.4f)\n"
              "config = RK4, damper %s, accel %s, float neural (default model %s), on-off skyhook, dt %.4g s\n"
              "road = OU roughness RMS %.3f m (n_min 1/92, n_max 2.83 cycle/m) at %.1f m/s, seed %llu; max |z_r| %.4f m\n"
              "latency_all_p50_ns = %.1f\nlatency_all_p99_ns = %.1f\nlatency_all_p999_ns = %.1f\nlatency_all_max_ns = %.1f\n"
              "window_p999_ns_min = %.1f\nwindow_p999_ns_max = %.1f\n"
              "max_abs_z_s_m = %.5f\nmax_abs_z_us_m = %.5f\nmax_abs_v_s_m_s = %.5f\nmax_abs_force_N = %.1f\n"
              "force_range_N = [%.1f, %.1f]\n"
              "energy_start_J = %.6e\nenergy_end_J = %.6e\nroad_work_J = %.6e\ndamper_work_J = %.6e\n"
              "residual_J = %.6e\nresidual_relative_to_damper_work = %.3e\nmax_abs_residual_J = %.6e\n"
              "rss_start_kb = %ld\nrss_first_window_kb = %ld\nrss_end_kb = %ld\nrss_max_kb = %ld\n"
              "errors = %lld\nsaturated_steps = %lld\nunconverged_steps = %lld\nfallback_steps = %lld\nforce_spikes = %lld\n"
              "loadavg_start = %s\nloadavg_end = %s\n"
              "checks: errors %s, bounded state %s, no force spike %s, energy residual %s, RSS flat %s\n",
              k, win, window, s[0], wall_s, wall_s * 1e9 / double(k), ghz_run, ghz,
              eval.c_str(), accel.c_str(), DN_MODEL_DEFAULT_ID, dt, rms, speed, (unsigned long long)seed,
              all_mx_zr, total_hist.quantile(0.5) / ghz, total_hist.quantile(0.99) / ghz,
              total_hist.quantile(0.999) / ghz, double(total_hist.max) / ghz, best_p999, worst_p999,
              all_mx_zs, all_mx_zus, all_mx_vs, all_mx_f, f_lo, f_hi, e0, e_end, w_road, w_damper,
              resid, resid / w_damper, max_res, rss_start, rss_first_window, rss_end, rss_max, all_err,
              all_sat, all_unconv, all_fallback, all_spike, load_start.c_str(), loadavg().c_str(), ok_err ? "ok" : "FAILED", ok_state ? "ok" : "FAILED",
              ok_spike ? "ok" : "FAILED", ok_energy ? "ok" : "FAILED", ok_rss ? "ok" : "FAILED");
  dn_loop_data_destroy(ld);
  dn_loop_model_destroy(lm);
  dn_damper_destroy(damper);
  dn_mlp_destroy(mlp);
  return ok_err && ok_state && ok_spike && ok_energy && ok_rss ? 0 : 1;
}
