// Mlp::forward_grad4 (four samples in one pass of the kernel, used by the full car's four
// corners) against four forward_grad calls: output, slope, status and clamped mask
// bit-identical (each sample's arithmetic is the single call's, in the same order), for
// float and double models of one and two hidden layers, 1-8 inputs, with samples inside the
// range, outside it, at +-Inf and NaN.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <random>
#include <vector>

#include "check.hpp"
#include "dampnet/mlp.hpp"
#include "random_model.hpp"

namespace {

template <typename T>
int check_model(const dn_mlp_desc& desc, std::mt19937& rng, long* compared) {
  dampnet::Mlp<T> m;
  if (m.load(&desc) != DN_OK) return 1;
  const int n = desc.n_inputs;
  std::uniform_real_distribution<double> pick(0.0, 1.0);
  int bad = 0;
  for (int rep = 0; rep < 200; ++rep) {
    T x[4][DN_MAX_INPUTS];
    for (int b = 0; b < 4; ++b)
      for (int i = 0; i < n; ++i) {
        const double lo = desc.sat_lo[i], hi = desc.sat_hi[i], r = pick(rng);
        double v = lo + (hi - lo) * (2.0 * pick(rng) - 0.5);  // a quarter outside each side
        if (r < 0.03) v = NAN;
        else if (r < 0.05) v = INFINITY;
        else if (r < 0.07) v = -INFINITY;
        x[b][i] = static_cast<T>(v);
      }
    const T* xp[4] = {x[0], x[1], x[2], x[3]};
    for (int gi = -1; gi <= n; ++gi) {  // every input, and indices out of range
      T y4[4], g4[4];
      int st4[4];
      uint32_t m4[4];
      m.forward_grad4(xp, y4, gi, g4, st4, m4);
      for (int b = 0; b < 4; ++b) {
        T y1, g1;
        uint32_t m1 = 0;
        const int st1 = m.forward_grad(x[b], &y1, gi, &g1, &m1);
        ++*compared;
        if (std::memcmp(&y1, &y4[b], sizeof(T)) || std::memcmp(&g1, &g4[b], sizeof(T)) || st1 != st4[b] ||
            m1 != m4[b]) {
          if (bad++ < 5)
            std::printf("  mismatch: n_in %d h1 %d h2 %d grad %d sample %d: y %.17g / %.17g, dy %.17g / %.17g, "
                        "status %d / %d, mask %u / %u\n", n, desc.n_hidden1, desc.n_hidden2, gi, b, double(y1),
                        double(y4[b]), double(g1), double(g4[b]), st1, st4[b], m1, m4[b]);
        }
      }
    }
  }
  return bad;
}

}  // namespace

int main() {
  std::mt19937 rng(7);
  long compared = 0;
  const int shapes[][3] = {{3, 30, 0}, {1, 5, 0}, {2, 16, 0}, {4, 64, 0}, {8, 33, 0}, {3, 12, 7}, {6, 40, 24}};
  for (const auto& s : shapes)
    for (int act : {DN_ACT_TANH, DN_ACT_SIGMOID}) {
      RandomModel rm(s[0], s[1], s[2], act, unsigned(s[0] * 100 + s[1] + act));
      CHECK(check_model<float>(rm.desc, rng, &compared) == 0);
      CHECK(check_model<double>(rm.desc, rng, &compared) == 0);
    }
  std::printf("forward_grad4 against single calls (kernel %s): %ld samples compared\n", dampnet::kernel_isa(),
              compared);
  CHECK(compared > 50000);
  TEST_MAIN_RETURN();
}
