// Latency of single-sample MLP forward calls (what a HIL step does), for the
// default 3-30-1 model compiled in from its generated header.
// Usage: dn_bench_mlp [N]   (N timed calls per candidate, default 1e6)
// Output: one JSON line per candidate (ns), a machine-facts line first.
#include <cmath>
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
              "\"flags\": \"%s\", \"kernel\": \"%s\", \"loadavg\": \"%s\"}}\n",
              json_escape(cpu.substr(cpu.find(':') + 2)).c_str(), json_escape(simd).c_str(),
              json_escape(__VERSION__).c_str(), json_escape(DN_BENCH_FLAGS).c_str(),
#ifdef DAMPNET_USE_EIGEN
              "eigen",
#else
              "plain",
#endif
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
  dn_bench::print_json("dampnet_runtime_float", dn_bench::measure([&](long i) {
    float y; rf.forward(&xf[(i & 1023) * kIn], &y); sink = y; }, none, n, warm));
  dn_bench::print_json("dampnet_c_abi_float", dn_bench::measure([&](long i) {
    float y; dn_mlp_forward_f(cm, &xf[(i & 1023) * kIn], &y, nullptr); sink = y; }, none, n, warm));
  dn_bench::print_json("naive_cpp_std_tanh", dn_bench::measure([&](long i) {
    sink = naive.forward(&xd[(i & 1023) * kIn]); }, none, n, warm));
  dn_mlp_destroy(cm);
  (void)sink;
  return 0;
}
