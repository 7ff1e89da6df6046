// The cold inverse's first iterate on a strict latency chain (issue 55 item 4, bench/RESULTS.md):
// each call's demand carries the last result times zero (a true data dependency, which the
// harness's zero_dep does not make), so a call's latency is measured, not its throughput. Damper
// of the default model in float; Damper::inverse_guess, Damper::force and Damper::inverse, ns a
// call, three repetitions. Not built by CMake; a scratch experiment:
//   g++ -std=c++17 -O3 -DNDEBUG -mavx2 -mfma -ffp-contract=off -DDN_MAX_HIDDEN=384 -Icpp/include \
//       -Iexport bench/experiments/inverse_guess_latency.cpp -o inverse_guess_latency && ./inverse_guess_latency
#include <chrono>
#include <cstdio>
#include <random>
#include <vector>
#include "dampnet/damper.hpp"
#include "dn_model_default.h"
using namespace dampnet;
volatile double zero_v = 0;
int main() {
  const dn_mlp_desc desc = DN_MODEL_DEFAULT_DESC_INIT;
  static Damper d;
  if (d.md.load(&desc) || d.mf.load(&desc)) return 1;
  const char* names[] = {"velocity", "acceleration", "voltage"};
  if (d.set_neural_features(names, 3, nullptr, nullptr, 0, DN_PRECISION_FLOAT)) return 2;
  std::mt19937 rng(1);
  std::vector<dn_damper_input> in(1024);
  std::vector<double> dem(1024);
  real lo, hi; d.control_range(&lo, &hi);
  for (int k = 0; k < 1024; ++k) {
    dn_damper_input m{};
    m.v = std::uniform_real_distribution<double>(-0.48, 0.48)(rng);
    m.a = std::uniform_real_distribution<double>(-9, 9)(rng);
    m.temperature = 20;
    real flo, fhi; m.u = lo; d.force(m, &flo); m.u = hi; d.force(m, &fhi);
    dem[k] = flo + (fhi - flo) * std::uniform_real_distribution<double>(0, 1)(rng);
    in[k] = m;
  }
  const double zero = zero_v;
  for (int rep = 0; rep < 3; ++rep) {
    const long n = 1000000;
    double carry = 0;
    auto t0 = std::chrono::steady_clock::now();
    for (long i = 0; i < n; ++i) { carry = (in[i & 1023].v + dem[i & 1023] + carry) * zero; }
    auto t1 = std::chrono::steady_clock::now();
    for (long i = 0; i < n; ++i) { carry = d.inverse_guess(in[i & 1023], dem[i & 1023] + carry) * zero; }
    auto t2 = std::chrono::steady_clock::now();
    for (long i = 0; i < n; ++i) { real f; dn_damper_input m = in[i & 1023]; m.v += carry; d.force(m, &f); carry = f * zero; }
    auto t3 = std::chrono::steady_clock::now();
    for (long i = 0; i < n / 4; ++i) { real u, f; d.inverse(in[i & 1023], dem[i & 1023] + carry, &u, &f); carry = u * zero; }
    auto t4 = std::chrono::steady_clock::now();
    auto ns = [](auto a, auto b, long m) { return std::chrono::duration<double, std::nano>(b - a).count() / m; };
    std::printf("base %.1f guess %.1f force %.1f inverse %.1f ns (%g)\n", ns(t0, t1, n), ns(t1, t2, n), ns(t2, t3, n), ns(t3, t4, n / 4), carry);
  }
}
