// Latency of single-sample MLP forward calls (what a HIL step does), for the
// default 3-30-1 model compiled in from its generated header, and of the
// quarter-car RK4 step with that model as a float neural damper and on-off
// skyhook (the HIL budget's case), and of the full vehicle's step with four such dampers,
// through the C ABI.
// Usage: dn_bench_mlp [N]   (N timed calls per candidate, default 1e6)
// Output: one JSON line per candidate (ns), a machine-facts line first.
#include <cmath>
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "dampnet/mlp.hpp"
#include "dn_model_default.h"
#include "latency.hpp"

#ifndef DN_BENCH_FLAGS
#define DN_BENCH_FLAGS ""
#endif

namespace {

constexpr int kIn = DN_MODEL_DEFAULT_N_INPUTS, kH = DN_MODEL_DEFAULT_N_HIDDEN1;

std::string read_first(const char* path, const char* key) {
  std::ifstream f(path);
  std::string line;
  while (std::getline(f, line))
    if (!key || line.rfind(key, 0) == 0) return line;
  return "";
}

std::string json_escape(std::string s) {
  std::string out;
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    if (c != '\t' && c != '\n') out += c;
  }
  return out;
}

void machine_facts() {
  std::string cpu = read_first("/proc/cpuinfo", "model name");
  std::string flags = read_first("/proc/cpuinfo", "flags");
  std::string simd;
  for (const char* f : {" sse4_2", " avx ", " avx2", " fma", " avx512f"})
    if (flags.find(f) != std::string::npos) simd += std::string(f).substr(1, std::string(f).find_last_not_of(' '));
  std::printf("{\"machine\": {\"cpu\": \"%s\", \"simd\": \"%s\", \"compiler\": \"%s\", "
              "\"flags\": \"%s\", \"kernel\": \"%s\", \"isa\": \"%s\", \"loadavg\": \"%s\"}}\n",
              json_escape(cpu.substr(cpu.find(':') + 2)).c_str(), json_escape(simd).c_str(),
              json_escape(__VERSION__).c_str(), json_escape(DN_BENCH_FLAGS).c_str(),
#ifdef DAMPNET_USE_EIGEN
              "eigen",
#else
              "plain",
#endif
              dampnet::kernel_isa(),
              json_escape(read_first("/proc/loadavg", nullptr)).c_str());
}

// The loop an engineer writes first: std::vector storage, std::tanh, no saturation.
struct NaiveMlp {
  std::vector<double> w1, b1, w2;
  double b2;
  std::vector<double> off, gain;
  double out_off, out_gain;
  double forward(const double* x) const {
    std::vector<double> xs(kIn);
    for (int i = 0; i < kIn; ++i) xs[i] = (x[i] - off[i]) * gain[i] - 1.0;
    double y = b2;
    for (int j = 0; j < kH; ++j) {
      double s = b1[j];
      for (int i = 0; i < kIn; ++i) s += w1[j * kIn + i] * xs[i];
      y += w2[j] * std::tanh(s);
    }
    return (y + 1.0) / out_gain + out_off;
  }
};

}  // namespace

int main(int argc, char** argv) {
  const long n = argc > 1 ? std::atol(argv[1]) : 1000000;
  const long warm = std::max(1000L, n / 10);
  machine_facts();

  const dn_mlp_desc d = DN_MODEL_DEFAULT_DESC_INIT;
  static dampnet::StaticMlp<float, kIn, kH, DN_MODEL_DEFAULT_N_HIDDEN2> sf;
  static dampnet::StaticMlp<double, kIn, kH, DN_MODEL_DEFAULT_N_HIDDEN2> sd;
  static dampnet::Mlp<float> rf;
  if (sf.load(&d) || sd.load(&d) || rf.load(&d)) return 1;
  dn_mlp* cm = nullptr;
  if (dn_mlp_create(&d, &cm) != DN_OK) return 1;
  NaiveMlp naive{{d.w1, d.w1 + kIn * kH}, {d.b1, d.b1 + kH}, {d.w_out, d.w_out + kH}, d.b_out[0],
                 {d.in_offset, d.in_offset + kIn}, {d.in_gain, d.in_gain + kIn},
                 d.out_offset, d.out_gain};

  // 1024 inputs inside the training range, cycled so the branch predictor and
  // the compiler cannot learn one constant input.
  std::mt19937 rng(1);
  std::vector<double> xd(1024 * kIn);
  std::vector<float> xf(1024 * kIn);
  for (int k = 0; k < 1024; ++k)
    for (int i = 0; i < kIn; ++i) {
      std::uniform_real_distribution<double> u(d.sat_lo[i], d.sat_hi[i]);
      xd[k * kIn + i] = u(rng);
      xf[k * kIn + i] = float(xd[k * kIn + i]);
    }
  volatile double sink = 0;
  auto none = [] {};

  dn_bench::print_json("clock_overhead", dn_bench::clock_overhead(n));
  dn_bench::print_json("dampnet_static_float", dn_bench::measure([&](long i) {
    float y; sf.forward(&xf[(i & 1023) * kIn], &y); sink = y; }, none, n, warm));
  dn_bench::print_json("dampnet_static_double", dn_bench::measure([&](long i) {
    double y; sd.forward(&xd[(i & 1023) * kIn], &y); sink = y; }, none, n, warm));
  // The same calls back to back, each input chosen by the previous output (latency, no
  // clock read per call): see dn_bench::measure_chained.
  dn_bench::print_json("dampnet_static_float_chained", dn_bench::measure_chained([&](long i, long dep) {
    float y; sf.forward(&xf[((i + dep) & 1023) * kIn], &y); return dn_bench::zero_dep(y); }, n, warm));
  dn_bench::print_json("dampnet_static_double_chained", dn_bench::measure_chained([&](long i, long dep) {
    double y; sd.forward(&xd[((i + dep) & 1023) * kIn], &y); return dn_bench::zero_dep(y); }, n, warm));
  dn_bench::print_json("dampnet_runtime_float", dn_bench::measure([&](long i) {
    float y; rf.forward(&xf[(i & 1023) * kIn], &y); sink = y; }, none, n, warm));
  dn_bench::print_json("dampnet_c_abi_float", dn_bench::measure([&](long i) {
    float y; dn_mlp_forward_f(cm, &xf[(i & 1023) * kIn], &y, nullptr); sink = y; }, none, n, warm));
  // Averaged networks (issue 33: `dampnet train --average K`, K networks side by side), through
  // the C ABI: the default network's hidden layer repeated K times with its output weights
  // divided by K, so each computes the default model's force with K times the neurons (checked
  // on the 1024 inputs and hard ones: max_diff_n, infinite when a status or finiteness differs). A width beyond the library's DN_MAX_HIDDEN (64 unless its
  // build raises it; 384 in the Python module's) is refused at set-up and reported as such.
  for (const int k : {2, 6, 12}) {
    const int h = k * kH;
    std::vector<double> w1(size_t(h) * kIn), b1(h), wo(h);
    for (int j = 0; j < h; ++j) {
      for (int i = 0; i < kIn; ++i) w1[size_t(j) * kIn + i] = d.w1[(j % kH) * kIn + i];
      b1[j] = d.b1[j % kH];
      wo[j] = d.w_out[j % kH] / k;
    }
    dn_mlp_desc wd = d;
    wd.n_hidden1 = h;
    wd.w1 = w1.data();
    wd.b1 = b1.data();
    wd.w_out = wo.data();
    dn_mlp* wide = nullptr;
    const std::string name = "c_abi_float_averaged_" + std::to_string(h);
    const int st = dn_mlp_create(&wd, &wide);
    if (st != DN_OK) {
      std::printf("{\"name\": \"%s\", \"neurons\": %d, \"refused\": \"%s\"}\n", name.c_str(), h, dn_status_str(st));
      continue;
    }
    // checked on the timed inputs and on hard ones (each input far beyond its range, NaN, +-Inf):
    // the same force and status as the one network, finite
    std::vector<float> hard;
    for (const float v : {1e6f, -1e6f, NAN, INFINITY, -INFINITY})
      for (int i = 0; i < kIn; ++i) {
        hard.insert(hard.end(), xf.begin(), xf.begin() + kIn);
        hard[hard.size() - kIn + i] = v;
      }
    double max_diff = 0.0;
    const auto compare = [&](const float* x) {
      float yw, y1;
      const int sw = dn_mlp_forward_f(wide, x, &yw, nullptr), s1 = dn_mlp_forward_f(cm, x, &y1, nullptr);
      const double diff = std::fabs(double(yw) - double(y1));
      max_diff = std::max(max_diff, sw == s1 && std::isfinite(yw) ? diff : INFINITY);
    };
    for (int r = 0; r < 1024; ++r) compare(&xf[r * kIn]);
    for (size_t r = 0; r < hard.size(); r += kIn) compare(&hard[r]);
    char extra[96];
    std::snprintf(extra, sizeof extra, ", \"neurons\": %d, \"max_diff_n\": %.3g", h, max_diff);
    dn_bench::print_json(name, dn_bench::measure([&](long i) {
      float y; dn_mlp_forward_f(wide, &xf[(i & 1023) * kIn], &y, nullptr); sink = y; }, none, n, warm), extra);
    dn_mlp_destroy(wide);
  }
  dn_bench::print_json("naive_cpp_std_tanh", dn_bench::measure([&](long i) {
    sink = naive.forward(&xd[(i & 1023) * kIn]); }, none, n, warm));
  // The training envelope's bounded-time check (dn_envelope_check) on the same inputs: every
  // input in range, so every pair's bitmap is read (its worst case); half the cells marked.
  {
    static uint32_t cells[DN_ENVELOPE_MAX_PAIRS * DN_ENVELOPE_PAIR_WORDS];
    for (uint32_t& w : cells) w = 0x5555aaaau;
    const dn_envelope_desc ed{kIn, d.sat_lo, d.sat_hi, cells};
    dn_envelope* env = nullptr;
    if (dn_envelope_create(&ed, &env) != DN_OK) return 1;
    volatile uint32_t flag_sink = 0;
    dn_bench::print_json("envelope_check_c_abi", dn_bench::measure([&](long i) {
      uint32_t f; dn_envelope_check(env, &xd[(i & 1023) * kIn], &f); flag_sink = f; }, none, n, warm));
    (void)flag_sink;
    dn_envelope_destroy(env);
  }

  // The quarter-car RK4 step (damper per stage, 4 MLP evaluations) with skyhook.
  const char* const features[3] = {"velocity", "acceleration", "voltage"};
  dn_damper* damper = nullptr;
  dn_vehicle veh;
  dn_vehicle_default(&veh);
  dn_controller ctrl;
  dn_controller_default(&ctrl, DN_CTRL_SKYHOOK_ONOFF);
  dn_loop_model* lm = nullptr;
  dn_loop_data* ld = nullptr;
  if (dn_damper_create_neural(cm, features, 3, nullptr, nullptr, 0, DN_PRECISION_FLOAT, &damper) ||
      dn_loop_model_create(&veh, damper, &ctrl, &lm) || dn_loop_data_create(lm, &ld))
    return 1;
  // The damper's forward and its inverse (issue 55), float, chained as the kernel's forward
  // is: 1024 motions inside the model's range, each with a demand drawn between the forces at
  // the two control limits (reachable: the Newton search runs). The cold call starts at its
  // first-iterate grid's control (damper.hpp InverseGuess), the limits evaluated only where its
  // Newton steps do not settle it; evals_per_call reports every evaluation. Checked
  // on the same motions (residual_max_N: the largest |F(u) - demand| [N], F the damper's own
  // force at the returned u, which must equal the returned force; tests/python/
  // test_damper_inverse.py checks u against a brute-force search) and on hard inputs (NaN,
  // +-Inf, 1e6 in every motion field and the demand; the warm call's start too): a finite control
  // inside the range with a status, or an error status with the range's centre and 0 N; a bad
  // one fails the harness.
  {
    dn_real u_lo = 0, u_hi = 0;
    if (dn_damper_control_range(damper, &u_lo, &u_hi) != DN_OK) return 1;
    std::vector<dn_damper_input> motion(1024);
    std::vector<dn_real> demand(1024);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    for (int k = 0; k < 1024; ++k) {
      dn_damper_input m{};
      m.v = xd[k * kIn + 0];
      m.a = xd[k * kIn + 1];
      m.temperature = 20;
      dn_real f_lo = 0, f_hi = 0;
      m.u = u_lo;
      dn_damper_force(damper, &m, &f_lo, nullptr);
      m.u = u_hi;
      dn_damper_force(damper, &m, &f_hi, nullptr);
      m.u = xd[k * kIn + 2];
      motion[k] = m;
      demand[k] = f_lo + (f_hi - f_lo) * unit(rng);
    }
    double worst_res = 0;  // max |F(u) - demand| [N], F through dn_damper_force at the inverse's u
    long evals = 0, bad_hard = 0;
    for (int k = 0; k < 1024; ++k) {
      dn_real u = 0, f = 0, fu = 0;
      int ne = 0;
      const int st = dn_damper_inverse(damper, &motion[k], demand[k], &u, &f, &ne);
      evals += ne;  // (the limits' included, where evaluated)
      dn_damper_input g = motion[k];
      g.u = u;
      dn_damper_force(damper, &g, &fu, nullptr);
      worst_res = std::max(worst_res, st == DN_OK && fu == f ? std::fabs(double(fu) - demand[k]) : double(INFINITY));
    }
    // the cold call and the warm one (dn_damper_inverse_near, below), a hard value in each motion
    // field, the demand and (warm) the start
    auto plausible = [&](int st, dn_real u, dn_real f) {
      return st >= 0 ? std::isfinite(u) && std::isfinite(f) && u >= u_lo && u <= u_hi
                     : u == u_lo + (u_hi - u_lo) / 2 && f == 0;
    };
    const double hard_vals[5] = {NAN, INFINITY, -INFINITY, 1e6, -1e6};
    for (const double hv : hard_vals)
      for (int field = 0; field < 5; ++field) {
        dn_damper_input m = motion[0];
        dn_real dem = demand[0], start = motion[0].u;
        if (field == 0) m.v = hv;
        else if (field == 1) m.a = hv;
        else if (field == 2) m.x = hv;
        else if (field == 3) dem = hv;
        else start = hv;
        dn_real u = 0, f = 0;  // (each call before its check: an argument's order is unspecified)
        const int st_cold = dn_damper_inverse(damper, &m, dem, &u, &f, nullptr);
        if (!plausible(st_cold, u, f)) ++bad_hard;
        const int st_near = dn_damper_inverse_near(damper, &m, dem, start, &u, &f, nullptr);
        if (!plausible(st_near, u, f)) ++bad_hard;
      }
    char extra[160];
    std::snprintf(extra, sizeof extra, ", \"evals_per_call\": %.3f, \"residual_max_N\": %.3g, \"hard_bad\": %ld",
                  double(evals) / 1024.0, worst_res, bad_hard);
    dn_bench::print_json("damper_force_float_chained", dn_bench::measure_chained([&](long i, long dep) {
      dn_real f; dn_damper_force(damper, &motion[(i + dep) & 1023], &f, nullptr); return dn_bench::zero_dep(f); },
      n, warm));
    dn_bench::print_json("damper_inverse_float_chained", dn_bench::measure_chained([&](long i, long dep) {
      const long k = (i + dep) & 1023;
      dn_real u, f; dn_damper_inverse(damper, &motion[k], demand[k], &u, &f, nullptr);
      return dn_bench::zero_dep(u); }, n, warm), extra);
    if (bad_hard || !(worst_res < 1.0)) return 1;  // 1 N: the float model's rounding is ~1e-3 N

    // The inverse as a controller calls it (dn_damper_inverse_near from the last step's
    // control): a 1 kHz trajectory of 4096 steps (a whole number of periods of each tone, so
    // it wraps smoothly): velocity 0.25 m/s at 1.46 Hz + 0.05 m/s at 11 Hz, its acceleration,
    // and the demand the force at a control sweeping 90 % of the range at 0.73 Hz. Each call
    // starts from the previous call's control (the chain). Checked: the returned force is the
    // damper's at the returned control, within 1 N of the demand wherever dn_damper_inverse
    // reaches it (the default model turns back in u near v = 0, where some of these demands lie
    // outside the limits' forces: there dn_damper_inverse_near may find a control inside).
    const double period = 4.096, step = 1e-3, two_pi = 2 * M_PI;
    std::vector<dn_damper_input> traj(4096);
    std::vector<dn_real> traj_demand(4096);
    for (int k = 0; k < 4096; ++k) {
      const double t = k * step, w1 = two_pi * 6 / period, w2 = two_pi * 45 / period, w3 = two_pi * 3 / period;
      dn_damper_input m{};
      m.v = 0.25 * std::sin(w1 * t) + 0.05 * std::sin(w2 * t);
      m.a = 0.25 * w1 * std::cos(w1 * t) + 0.05 * w2 * std::cos(w2 * t);
      m.temperature = 20;
      m.u = u_lo + (u_hi - u_lo) * (0.5 + 0.45 * std::sin(w3 * t));
      dn_damper_force(damper, &m, &traj_demand[k], nullptr);
      traj[k] = m;
    }
    long warm_evals = 0;
    double warm_res = 0;
    dn_real u_prev = traj[4095].u;
    for (int k = 0; k < 4096; ++k) {
      dn_real u = 0, f = 0, fu = 0;
      int ne = 0;
      const int st = dn_damper_inverse_near(damper, &traj[k], traj_demand[k], u_prev, &u, &f, &ne);
      warm_evals += ne;
      dn_damper_input g = traj[k];
      g.u = u;
      dn_damper_force(damper, &g, &fu, nullptr);
      dn_real u_cold = 0, f_cold = 0;
      const int st_cold = dn_damper_inverse(damper, &traj[k], traj_demand[k], &u_cold, &f_cold, nullptr);
      if (st < 0 || fu != f) warm_res = INFINITY;
      else if (!(st_cold & DN_W_UNREACHABLE)) warm_res = std::max(warm_res, std::fabs(double(fu) - traj_demand[k]));
      u_prev = u;
    }
    char extra_near[160];
    std::snprintf(extra_near, sizeof extra_near, ", \"evals_per_call\": %.3f, \"residual_max_N\": %.3g, \"hard_bad\": %ld",
                  double(warm_evals) / 4096.0, warm_res, bad_hard);
    dn_real u_chain = traj[4095].u;
    dn_bench::print_json("damper_inverse_near_float_chained", dn_bench::measure_chained([&](long i, long dep) {
      const long k = (i + dep) & 4095;
      dn_real f;
      dn_damper_inverse_near(damper, &traj[k], traj_demand[k], u_chain, &u_chain, &f, nullptr);
      return dn_bench::zero_dep(u_chain); }, n, warm), extra_near);
    if (!(warm_res < 1.0)) return 1;
  }
  // A road: 20 mm of mixed 1.3 Hz and 11 Hz content, sampled at the loop's step.
  std::vector<dn_loop_input> road(4096);
  for (size_t k = 0; k < road.size(); ++k) {
    const double t = double(k + 1) * veh.dt, w1 = 2 * M_PI * 1.3, w2 = 2 * M_PI * 11.0;
    road[k] = {0.015 * std::sin(w1 * t) + 0.005 * std::sin(w2 * t),
               0.015 * w1 * std::cos(w1 * t) + 0.005 * w2 * std::cos(w2 * t), 0.0};
  }
  double saved[DN_LOOP_STATE_SIZE];
  // Timed steps that return an error (a diverged state returns early): a benchmark of those
  // would time the early return, so any makes the harness fail instead of reporting.
  long step_errors = 0;
  dn_loop_reset(lm, ld);
  for (int k = 0; k < 2000; ++k) dn_loop_step(lm, ld, &road[k & 4095], nullptr);  // settle
  dn_loop_get_state(ld, saved);
  long batch_start = 0;
  dn_bench::print_json("loop_step_rk4_neural_float_skyhook", dn_bench::measure(
      [&](long i) { step_errors += dn_loop_step(lm, ld, &road[(i - batch_start) & 4095], nullptr) < 0; },
      [&] { dn_loop_set_state(ld, saved); }, n, warm, 1000));
  veh.damper_eval = DN_EVAL_PER_STEP;
  dn_loop_model* lm1 = nullptr;
  if (dn_loop_model_create(&veh, damper, &ctrl, &lm1)) return 1;
  dn_loop_reset(lm1, ld);
  for (int k = 0; k < 2000; ++k) dn_loop_step(lm1, ld, &road[k & 4095], nullptr);
  dn_loop_get_state(ld, saved);
  dn_bench::print_json("loop_step_rk4_per_step_eval_neural_float_skyhook", dn_bench::measure(
      [&](long i) { step_errors += dn_loop_step(lm1, ld, &road[i & 4095], nullptr) < 0; },
      [&] { dn_loop_set_state(ld, saved); }, n, warm, 1000));
  // The same two with the linearised (one evaluation with its slope) and the explicit
  // acceleration feature (the cases above iterate the implicit solve: dn_accel_feature).
  dn_loop_model* variants[4] = {nullptr, nullptr, nullptr, nullptr};
  const int accel_modes[2] = {DN_ACCEL_LINEAR, DN_ACCEL_EXPLICIT};
  for (int j = 0; j < 4; ++j) {
    veh.accel_feature = accel_modes[j / 2];
    veh.damper_eval = (j % 2) ? DN_EVAL_PER_STEP : DN_EVAL_PER_STAGE;
    if (dn_loop_model_create(&veh, damper, &ctrl, &variants[j])) return 1;
  }
  const char* variant_names[4] = {"loop_step_rk4_neural_float_skyhook_linear_accel",
                                  "loop_step_rk4_per_step_eval_neural_float_skyhook_linear_accel",
                                  "loop_step_rk4_neural_float_skyhook_explicit_accel",
                                  "loop_step_rk4_per_step_eval_neural_float_skyhook_explicit_accel"};
  for (int j = 0; j < 4; ++j) {
    dn_loop_model* me = variants[j];
    dn_loop_reset(me, ld);
    for (int k = 0; k < 2000; ++k) dn_loop_step(me, ld, &road[k & 4095], nullptr);
    dn_loop_get_state(ld, saved);
    dn_bench::print_json(variant_names[j], dn_bench::measure(
        [&](long i) { step_errors += dn_loop_step(me, ld, &road[i & 4095], nullptr) < 0; },
        [&] { dn_loop_set_state(ld, saved); }, n, warm, 1000));
  }
  // The full vehicle (fullcar.hpp): four neural dampers (the same float model), on-off skyhook
  // at every corner, Magic-Formula tyres, open-loop steering; each corner its own road.
  // FULLCAR_CASE: the HIL configuration (damper and tyres once per step, linearised a).
  {
    dn_damper* corners[4] = {damper, damper, damper, damper};
    dn_controller ctrls[4] = {ctrl, ctrl, ctrl, ctrl};
    std::vector<dn_fullcar_input> froad(4096);
    for (size_t k = 0; k < froad.size(); ++k) {
      const double t = double(k + 1) * 1e-3, w1 = 2 * M_PI * 1.3, w2 = 2 * M_PI * 11.0;
      dn_fullcar_input& in = froad[k];
      for (int c = 0; c < 4; ++c) {
        const double ph = 0.9 * c;
        in.z_r[c] = 0.015 * std::sin(w1 * t + ph) + 0.005 * std::sin(w2 * t + 2 * ph);
        in.v_r[c] = 0.015 * w1 * std::cos(w1 * t + ph) + 0.005 * w2 * std::cos(w2 * t + 2 * ph);
        in.u[c] = 0.0;
      }
      in.steer = 0.03 * std::sin(2 * M_PI * 0.5 * t);
    }
    // shared: the four corners given one damper object, so their four evaluations go through
    // the kernel in one pass (fullcar.hpp, batch4); the *_four_calls cases give four damper
    // objects of the same model, evaluated one call each.
    struct FcCase {
      const char* name;
      int eval, precision;
      bool shared;
    };
    const FcCase fc_cases[5] = {
        {"fullcar_step_rk4_per_step_eval_neural_float_skyhook_linear_accel", DN_EVAL_PER_STEP, DN_PRECISION_FLOAT, true},
        {"fullcar_step_rk4_per_step_eval_neural_float_skyhook_linear_accel_four_calls", DN_EVAL_PER_STEP,
         DN_PRECISION_FLOAT, false},
        {"fullcar_step_rk4_per_step_eval_neural_double_skyhook_linear_accel", DN_EVAL_PER_STEP, DN_PRECISION_DOUBLE, true},
        {"fullcar_step_rk4_neural_float_skyhook_linear_accel", DN_EVAL_PER_STAGE, DN_PRECISION_FLOAT, true},
        {"fullcar_step_rk4_neural_float_skyhook_linear_accel_four_calls", DN_EVAL_PER_STAGE, DN_PRECISION_FLOAT, false}};
    const char* const feats[3] = {"velocity", "acceleration", "voltage"};
    double fsaved[DN_FULLCAR_STATE_SIZE];
    for (const FcCase& fc : fc_cases) {
      dn_damper* own[4] = {nullptr, nullptr, nullptr, nullptr};
      for (int c = 0; c < (fc.shared ? 1 : 4); ++c)
        if (dn_damper_create_neural(cm, feats, 3, nullptr, nullptr, 0, fc.precision, &own[c])) return 1;
      for (int c = 0; c < 4; ++c) corners[c] = own[fc.shared ? 0 : c];
      dn_fullcar_params fp;
      dn_fullcar_default(&fp);
      fp.damper_eval = fc.eval;
      fp.accel_feature = DN_ACCEL_LINEAR;
      dn_fullcar_model* fm = nullptr;
      dn_fullcar_data* fd = nullptr;
      if (dn_fullcar_model_create(&fp, corners, ctrls, nullptr, nullptr, 0, &fm) ||
          dn_fullcar_data_create(fm, &fd))
        return 1;
      for (int k = 0; k < 2000; ++k) step_errors += dn_fullcar_step(fm, fd, &froad[k & 4095], nullptr) < 0;
      dn_fullcar_get_state(fd, fsaved);
      const dn_bench::Stats warm_stats = dn_bench::measure(
          [&](long i) { step_errors += dn_fullcar_step(fm, fd, &froad[i & 4095], nullptr) < 0; },
          [&] { dn_fullcar_set_state(fd, fsaved); }, n, warm, 1000);
      // FULLCAR_CASE only: its cold-cache cost (latency.hpp, CacheEvictor), single steps each
      // right after a code sweep alone, 4 MB of data + the code sweep, 64 MB + the code sweep
      char cold[512] = "";
      if (&fc == &fc_cases[0]) {
        static dn_bench::CacheEvictor<> ev(size_t(64) << 20);
        const long reps = std::min(1000L, std::max(100L, n / 1000));
        const auto step1 = [&](long r) { step_errors += dn_fullcar_step(fm, fd, &froad[(7 * r) & 4095], nullptr) < 0; };
        const auto restore = [&] { dn_fullcar_set_state(fd, fsaved); };
        const dn_bench::ColdStats c0 = dn_bench::measure_cold(step1, restore, ev, 0, reps);
        const dn_bench::ColdStats c4 = dn_bench::measure_cold(step1, restore, ev, size_t(4) << 20, reps);
        const dn_bench::ColdStats c64 = dn_bench::measure_cold(step1, restore, ev, size_t(64) << 20, reps);
        std::snprintf(cold, sizeof cold,
                      ", \"cold_reps\": %ld, \"code_sweep_bytes\": %zu, "
                      "\"cold_code_p50_ns\": %.1f, \"cold_code_p99_ns\": %.1f, "
                      "\"cold_4mb_p50_ns\": %.1f, \"cold_4mb_p99_ns\": %.1f, "
                      "\"cold_64mb_p50_ns\": %.1f, \"cold_64mb_p99_ns\": %.1f",
                      reps, ev.code_sweep_bytes(), c0.p50, c0.p99, c4.p50, c4.p99, c64.p50, c64.p99);
      }
      dn_bench::print_json(fc.name, warm_stats, cold);
      // plausible output after the timed steps: a finite state, a body that moved
      double s[DN_FULLCAR_STATE_SIZE];
      dn_fullcar_get_state(fd, s);
      for (double x : s) step_errors += !std::isfinite(x);
      dn_fullcar_data_destroy(fd);
      dn_fullcar_model_destroy(fm);
      for (dn_damper* o : own) dn_damper_destroy(o);
    }
  }
  dn_loop_data_destroy(ld);
  dn_loop_model_destroy(lm);
  dn_loop_model_destroy(lm1);
  for (dn_loop_model* me : variants) dn_loop_model_destroy(me);
  dn_damper_destroy(damper);
  dn_mlp_destroy(cm);
  (void)sink;
  (void)batch_start;
  if (step_errors > 0) {
    std::fprintf(stderr, "dn_bench_mlp: error: %ld timed loop steps returned an error status\n", step_errors);
    return 1;
  }
  return 0;
}
