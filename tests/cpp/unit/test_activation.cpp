// The float tanh approximation against std::tanh over [-10, 10], every 128th
// float bit pattern (about 1.7e7 values, dense near 0 where floats are), and
// the sigmoid identity. Prints the worst errors that the docs state.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <initializer_list>

#include "check.hpp"
#include "dampnet/activation.hpp"
#include "dampnet/mlp.hpp"  // the backend: fast_tanh8 / fast_tanh16 where it has them

namespace {

// The walk of these tests over the float bit patterns: 128 ulps towards +10.
float next_128_ulps(float x) {
  uint32_t b;
  std::memcpy(&b, &x, 4);
  b = (b & 0x80000000u) ? (b > 0x80000080u ? b - 128u : 0u) : b + 128u;
  std::memcpy(&x, &b, 4);
  return x;
}

// Raise *worst to the largest |approx - std::tanh| over the floats from lo to hi (stepping
// by next), the approximation evaluated W at a time by eval(in, out); *at: where.
template <int W, class Eval, class Next>
void walk_tanh_error(Eval eval, float lo, float hi, Next next, double* worst, double* at) {
  alignas(64) float in[W] = {}, out[W] = {};
  int k = 0;
  auto flush = [&] {
    eval(in, out);
    for (int l = 0; l < k; ++l) {
      const double err = std::fabs(double(out[l]) - std::tanh(double(in[l])));
      if (err > *worst) {
        *worst = err;
        *at = in[l];
      }
    }
    k = 0;
  };
  for (float z = lo; z <= hi; z = next(z)) {
    in[k++] = z;
    if (k == W) flush();
  }
  if (k) flush();
}

}  // namespace

int main() {
  double worst_tanh = 0.0, worst_at = 0.0;
  walk_tanh_error<1>([](const float* in, float* out) { out[0] = dampnet::fast_tanh(in[0]); }, -10.0f,
                     10.0f, next_128_ulps, &worst_tanh, &worst_at);
  std::printf("float fast_tanh: worst |error| vs std::tanh on [-10, 10] (every 128th float) = %.3g at x = %.9g\n",
              worst_tanh, worst_at);
  CHECK(worst_tanh < 5e-7);  // the bound stated in activation.hpp and the docs

  double worst_sig = 0.0;
  for (int i = -200000; i <= 200000; ++i) {
    const float xf = float(i) * 1e-4f;
    const double ref = 1.0 / (1.0 + std::exp(-double(xf)));
    const double got = dampnet::activate(dampnet::Activation::sigmoid, xf);
    worst_sig = std::fmax(worst_sig, std::fabs(got - ref));
  }
  std::printf("float sigmoid via tanh: worst |error| on [-20, 20] = %.3g\n", worst_sig);
  CHECK(worst_sig < 3e-7);

  // Non-finite arguments stay bounded.
  CHECK(dampnet::fast_tanh(INFINITY) == 1.0f || std::fabs(dampnet::fast_tanh(INFINITY) - 1.0f) < 1e-6f);
  CHECK(std::fabs(dampnet::fast_tanh(-INFINITY) + 1.0f) < 1e-6f);

#ifdef DN_TANH8_AVX2
  // The AVX2 kernel's 8-wide tanh (FMA, another evaluation order) over the same floats.
  {
    double worst8 = 0.0, worst8_at = 0.0;
    walk_tanh_error<8>(
        [](const float* in, float* out) { _mm256_store_ps(out, dampnet::fast_tanh8(_mm256_load_ps(in))); },
        -10.0f, 10.0f, next_128_ulps, &worst8, &worst8_at);
    alignas(32) float in[8], out[8];
    std::printf("AVX2 fast_tanh8: worst |error| vs std::tanh on [-10, 10] (every 128th float) = %.3g at x = %.9g\n",
                worst8, worst8_at);
    CHECK(worst8 < 5e-7);
    // Non-finite and huge arguments: +-1 (NaN: +1), never NaN.
    const float special[8] = {INFINITY, -INFINITY, NAN, 1e30f, -1e30f, 9.0f, -9.0f, 0.0f};
    for (int l = 0; l < 8; ++l) in[l] = special[l];
    _mm256_store_ps(out, dampnet::fast_tanh8(_mm256_load_ps(in)));
    CHECK(std::fabs(out[0] - 1.0f) < 1e-6f && std::fabs(out[1] + 1.0f) < 1e-6f);
    CHECK(std::fabs(out[2] - 1.0f) < 1e-6f);
    CHECK(std::fabs(out[3] - 1.0f) < 1e-6f && std::fabs(out[4] + 1.0f) < 1e-6f);
    CHECK(out[7] == 0.0f);
  }
#else
  std::printf("AVX2 fast_tanh8: not in this build (kernel backend %s)\n", dampnet::kernel_isa());
#endif

#ifdef DN_TANH16_AVX512
  // The AVX-512 kernel's 16-wide tanh (unclamped square, write masks, vrcp14ps with a
  // Newton step) over the same floats, and its special values.
  {
    double worst16 = 0.0, worst16_at = 0.0;
    auto tanh16 = [](const float* in, float* out) {
      _mm512_store_ps(out, dampnet::fast_tanh16(_mm512_load_ps(in)));
    };
    walk_tanh_error<16>(tanh16, -10.0f, 10.0f, next_128_ulps, &worst16, &worst16_at);
    // Every float in [8.9, 9.1] and [-9.1, -8.9], where the masks switch.
    for (float a : {8.9f, -9.1f})
      walk_tanh_error<16>(tanh16, a, a + 0.2f, [](float v) { return std::nextafter(v, 100.f); },
                          &worst16, &worst16_at);
    alignas(64) float in[16], out[16];
    std::printf("AVX-512 fast_tanh16: worst |error| vs std::tanh on [-10, 10] (every 128th float, every float near +-9) = %.3g at x = %.9g\n",
                worst16, worst16_at);
    CHECK(worst16 < 5e-7);
    const float special[16] = {INFINITY, -INFINITY, NAN, 1e30f, -1e30f, 9.0f, -9.0f, 0.0f,
                               -0.0f, 1e-30f, 3e38f, -3e38f, 9.000001f, -9.000001f, 1e-45f, 20.f};
    for (int l = 0; l < 16; ++l) in[l] = special[l];
    _mm512_store_ps(out, dampnet::fast_tanh16(_mm512_load_ps(in)));
    for (int l = 0; l < 16; ++l) CHECK(std::isfinite(out[l]) && std::fabs(out[l]) <= 1.0f);
    CHECK(out[0] == 1.0f && out[1] == -1.0f && out[2] == 1.0f);
    CHECK(out[3] == 1.0f && out[4] == -1.0f && out[10] == 1.0f && out[11] == -1.0f);
    CHECK(std::fabs(out[5] - std::tanh(9.0)) < 5e-7 && std::fabs(out[6] + std::tanh(9.0)) < 5e-7);
    CHECK(out[7] == 0.0f && out[8] == 0.0f && std::fabs(out[9]) <= 1e-30f);
    CHECK(out[12] == 1.0f && out[13] == -1.0f && out[15] == 1.0f);
  }
#else
  std::printf("AVX-512 fast_tanh16: not in this build (kernel backend %s)\n", dampnet::kernel_isa());
#endif

  // double: tanh_d against std::tanh, relative error (a few ulps), over [-25, 25] in
  // steps of 1e-4, plus tiny, huge and non-finite arguments.
  double worst_rel = 0.0, worst_rel_at = 0.0;
  for (long i = -250000; i <= 250000; ++i) {
    const double xd = double(i) * 1e-4 + 1e-9 * double(i % 7);
    const double ref = std::tanh(xd), got = dampnet::activate(dampnet::Activation::tanh, xd);
    const double rel = ref == 0.0 ? std::fabs(got) : std::fabs(got - ref) / std::fabs(ref);
    if (rel > worst_rel) {
      worst_rel = rel;
      worst_rel_at = xd;
    }
  }
  for (double xd : {1e-300, -1e-300, 1e-20, 1e-9, -3e-5, 0.17, 0.35, 0.3466, 0.3467, 0.6931, 19.99, -19.99}) {
    const double ref = std::tanh(xd), got = dampnet::tanh_d(xd);
    worst_rel = std::fmax(worst_rel, std::fabs(got - ref) / std::fabs(ref));
  }
  std::printf("double tanh_d: worst relative error vs std::tanh = %.3g (%.1f ulps) at x = %.17g\n",
              worst_rel, worst_rel / 2.220446049250313e-16, worst_rel_at);
  CHECK(worst_rel < 8.9e-16);  // 4 ulps, the bound stated in activation.hpp
  CHECK(dampnet::tanh_d(0.0) == 0.0);
  CHECK(dampnet::tanh_d(1e3) == 1.0 && dampnet::tanh_d(-1e300) == -1.0);
  CHECK(dampnet::tanh_d(INFINITY) == 1.0 && dampnet::tanh_d(-INFINITY) == -1.0);
  CHECK(std::fabs(dampnet::tanh_d(NAN)) == 1.0);  // never NaN
  TEST_MAIN_RETURN();
}
