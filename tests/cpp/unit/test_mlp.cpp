// The MLP kernel: run-time vs compile-time paths, float vs double, validation,
// and the documented policy for non-finite and out-of-range inputs.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "check.hpp"
#include "dampnet/mlp.hpp"
#include "random_model.hpp"

using dampnet::Mlp;
using dampnet::StaticMlp;

template <int In, int H1, int H2>
void static_equals_dynamic(int act, unsigned seed) {
  RandomModel rm(In, H1, H2, act, seed);
  Mlp<double> md;
  Mlp<float> mf;
  StaticMlp<double, In, H1, H2> sd;
  StaticMlp<float, In, H1, H2> sf;
  CHECK(md.load(&rm.desc) == DN_OK);
  CHECK(mf.load(&rm.desc) == DN_OK);
  CHECK(sd.load(&rm.desc) == DN_OK);
  CHECK(sf.load(&rm.desc) == DN_OK);
  // out_bound (the damper's inverse's rounding scale): |b_out| + sum |w_out| of the folded
  // output layer, summed here in double from the parameters
  auto bound = [](const auto& p) {
    double s = std::fabs(static_cast<double>(p.b_out));
    for (int j = 0; j < (p.n_h2 > 0 ? p.n_h2 : p.n_h1); ++j) s += std::fabs(static_cast<double>(p.w_out[j]));
    return s;
  };
  CHECK(bound(md.params()) > 0.0);
  CHECK_NEAR(md.out_bound(), bound(md.params()), 1e-12 * bound(md.params()));
  CHECK_NEAR(mf.out_bound(), bound(mf.params()), 1e-6 * bound(mf.params()));
  std::mt19937 rng(seed + 1);
  for (int k = 0; k < 200; ++k) {
    std::vector<double> x = rm.sample(rng);
    std::vector<float> xf(x.begin(), x.end());
    double yd = 0, ysd = 0;
    float yf = 0, ysf = 0;
    CHECK(md.forward(x.data(), &yd) == DN_OK);
    CHECK(sd.forward(x.data(), &ysd) == DN_OK);
    CHECK(mf.forward(xf.data(), &yf) == DN_OK);
    CHECK(sf.forward(xf.data(), &ysf) == DN_OK);
    CHECK(yd == ysd);   // same kernel, same arithmetic: bit-identical
    CHECK(yf == ysf);
    CHECK_NEAR(yf, yd, 1e-5 * 4000.0);  // float within 1e-5 of the force range
    // forward_grad, every fourth sample with the differentiated input beyond its range (clamped:
    // slope 0; the scalar backend sends it to the plain forward, Mlp and StaticMlp alike)
    const int gi = In - 1;
    if (k % 4 == 0) x[gi] = xf[gi] = 1e6f;
    double gd = -1, gsd = -1, yg = 0, ysg = 0;
    float gf = -1, gsf = -1, yfg = 0, ysfg = 0;
    const int s1 = md.forward_grad(x.data(), &yg, gi, &gd), s2 = sd.forward_grad(x.data(), &ysg, gi, &gsd);
    const int s3 = mf.forward_grad(xf.data(), &yfg, gi, &gf), s4 = sf.forward_grad(xf.data(), &ysfg, gi, &gsf);
    CHECK(s1 == s2 && s3 == s4 && yg == ysg && yfg == ysfg && gd == gsd && gf == gsf);
    if (k % 4 == 0) CHECK(gd == 0.0 && gf == 0.0f && (s1 & DN_W_SATURATED) && (s3 & DN_W_SATURATED));
    double yplain = 0;
    CHECK(md.forward(x.data(), &yplain) == s1 && yplain == yg);  // the slope's pass: the forward's value
  }
}

void validation_errors() {
  RandomModel rm(3, 30, 0, DN_ACT_TANH, 7);
  Mlp<double> m;
  CHECK(m.load(nullptr) == DN_E_NULL);
  dn_mlp_desc d = rm.desc;
  d.n_inputs = 9;
  CHECK(m.load(&d) == DN_E_SIZE);
  d = rm.desc;
  d.n_hidden1 = 65;
  CHECK(m.load(&d) == DN_E_SIZE);
  d = rm.desc;
  d.activation = 7;
  CHECK(m.load(&d) == DN_E_ACTIVATION);
  d = rm.desc;
  d.out_gain = 0.0;
  CHECK(m.load(&d) == DN_E_PARAM);
  std::vector<double> bad = rm.w1;
  bad[5] = std::numeric_limits<double>::quiet_NaN();
  d = rm.desc;
  d.w1 = bad.data();
  CHECK(m.load(&d) == DN_E_NONFINITE_PARAM);
  std::vector<double> lo = rm.sat_lo;
  lo[1] = rm.sat_hi[1] + 1.0;
  d = rm.desc;
  d.sat_lo = lo.data();
  CHECK(m.load(&d) == DN_E_PARAM);
  d = rm.desc;
  d.n_hidden2 = 4;  // second layer declared but no weights
  CHECK(m.load(&d) == DN_E_NULL);
  StaticMlp<double, 3, 20, 0> wrong;
  CHECK(wrong.load(&rm.desc) == DN_E_MISMATCH);
}

template <typename T>
void input_policy() {
  RandomModel rm(3, 30, 0, DN_ACT_SIGMOID, 11);
  Mlp<T> m;
  CHECK(m.load(&rm.desc) == DN_OK);
  const T nan = std::numeric_limits<T>::quiet_NaN(), inf = std::numeric_limits<T>::infinity();
  T mid[3], lo[3], hi[3];
  for (int i = 0; i < 3; ++i) {
    lo[i] = T(rm.sat_lo[i]);
    hi[i] = T(rm.sat_hi[i]);
    mid[i] = T(0.5) * (lo[i] + hi[i]);
  }
  T y_ref, y;
  uint32_t mask = 99;
  CHECK(m.forward(mid, &y_ref, &mask) == DN_OK);
  CHECK(mask == 0u);

  // NaN -> the centre of the range, flagged.
  T x[3] = {mid[0], nan, mid[2]};
  CHECK(m.forward(x, &y, &mask) == DN_W_NONFINITE_INPUT);
  CHECK(mask == 2u);
  CHECK(y == y_ref);

  // +Inf and far out of range -> the upper limit, flagged as saturated.
  T x_hi[3] = {inf, hi[1] * T(1e6) + T(1e6), mid[2]};
  T at_hi[3] = {hi[0], hi[1], mid[2]};
  T y_at_hi;
  CHECK(m.forward(at_hi, &y_at_hi) == DN_OK);
  CHECK(m.forward(x_hi, &y, &mask) == DN_W_SATURATED);
  CHECK(mask == 3u);
  CHECK(y == y_at_hi);

  // -Inf -> the lower limit; NaN and saturation together report both bits.
  T x_mix[3] = {-inf, nan, lo[2]};
  const int st = m.forward(x_mix, &y, &mask);
  CHECK(st == (DN_W_SATURATED | DN_W_NONFINITE_INPUT));
  CHECK(mask == 3u);  // input 2 is exactly at its limit: not clamped
  CHECK(std::isfinite(y));

  // Anything at all gives a finite output.
  std::mt19937 rng(5);
  std::uniform_int_distribution<uint64_t> bits;
  for (int k = 0; k < 100000; ++k) {
    T xr[3];
    for (auto& v : xr) {
      uint64_t b = bits(rng);
      if (sizeof(T) == 4) {
        uint32_t b32 = uint32_t(b);
        std::memcpy(&v, &b32, 4);
      } else {
        std::memcpy(&v, &b, 8);
      }
    }
    CHECK(m.forward(xr, &y) >= 0);
    CHECK(std::isfinite(y));
  }
}

// Finite parameters whose sum overflows: every hidden unit saturates at tanh(5) ~ +1
// and h output weights of w each add up past the type's range (float: w below
// 3.4e38 / 56, the largest tanh numerator coefficient folded into w_out). The status must be
// DN_E_NONFINITE_OUTPUT and the output exactly the (finite) out_offset.
template <typename T>
void output_overflow_is_caught(int h, double w) {
  RandomModel rm(2, h, 0, DN_ACT_TANH, 3);
  for (auto& x : rm.w1) x = 0.0;
  for (auto& x : rm.b1) x = 5.0;
  for (auto& x : rm.w_out) x = w;
  rm.b_out[0] = 0.0;
  rm.desc.out_gain = 1.0;
  rm.desc.out_ymin = 0.0;
  rm.desc.out_offset = -123.0;
  Mlp<T> m;
  CHECK(m.load(&rm.desc) == DN_OK);
  T x[2] = {T(rm.sat_lo[0]), T(rm.sat_hi[1])}, y = 0;
  CHECK(m.forward(x, &y) == DN_E_NONFINITE_OUTPUT);
  CHECK(y == T(-123.0));
}

// A scaling that overflows the kernel's type once folded (float: out_offset 1e39, an
// out_gain of 1e-40, a saturation limit of 1e39) is refused at creation: before, the
// float forward returned +-inf with DN_E_NONFINITE_OUTPUT, its fallback being inf too.
void float_overflowing_scaling_is_refused() {
  for (int c = 0; c < 4; ++c) {
    RandomModel rm(2, 4, 0, DN_ACT_TANH, 5);
    if (c == 0) rm.desc.out_offset = 1e39;
    if (c == 1) rm.desc.out_offset = -1e39;
    if (c == 2) rm.desc.out_gain = 1e-40;
    if (c == 3) rm.sat_hi[1] = 1e39;
    Mlp<float> mf;
    Mlp<double> md;
    CHECK(mf.load(&rm.desc) == DN_E_PARAM);
    CHECK(md.load(&rm.desc) == DN_OK);  // double holds it, but a dn_mlp holds both copies
    dn_mlp* h = reinterpret_cast<dn_mlp*>(&md);  // poison: must be overwritten with NULL
    CHECK(dn_mlp_create(&rm.desc, &h) == DN_E_PARAM);
    CHECK(h == nullptr);
  }
  RandomModel ok(2, 4, 0, DN_ACT_TANH, 5);
  ok.desc.out_offset = 1e30;  // large, but float holds it
  dn_mlp* h = nullptr;
  CHECK(dn_mlp_create(&ok.desc, &h) == DN_OK);
  float xf[2] = {0.f, 0.f}, yf = 0.f;
  CHECK(dn_mlp_forward_f(h, xf, &yf, nullptr) >= 0 && std::isfinite(yf));
  dn_mlp_destroy(h);
}

// forward_grad's dy/dx_i against a central difference of the double kernel, for every
// input of one- and two-layer models, inside the range; 0 for a clamped input.
template <int In, int H1, int H2>
void gradient_matches_difference(int act, unsigned seed) {
  RandomModel rm(In, H1, H2, act, seed);
  Mlp<double> md;
  StaticMlp<double, In, H1, H2> sd;
  Mlp<float> mf;
  CHECK(md.load(&rm.desc) == DN_OK && sd.load(&rm.desc) == DN_OK && mf.load(&rm.desc) == DN_OK);
  std::mt19937 rng(seed);
  for (int k = 0; k < 50; ++k) {
    std::vector<double> x = rm.sample(rng);
    for (int i = 0; i < In; ++i) {
      const double h = 1e-6 * (rm.sat_hi[i] - rm.sat_lo[i]);
      std::vector<double> xp = x, xm = x;
      xp[i] += h;
      xm[i] -= h;
      double yp, ym, y, g, ys, gs;
      md.forward(xp.data(), &yp);
      md.forward(xm.data(), &ym);
      const double fd = (yp - ym) / (2 * h);
      CHECK(md.forward_grad(x.data(), &y, i, &g) == DN_OK);
      CHECK(sd.forward_grad(x.data(), &ys, i, &gs) == DN_OK);
      double y0;
      md.forward(x.data(), &y0);
      CHECK(y == y0 && ys == y && gs == g);  // the value is the plain forward's
      CHECK_NEAR(g, fd, 1e-5 * (std::fabs(fd) + 4000.0 / (rm.sat_hi[i] - rm.sat_lo[i])));
      std::vector<float> xf(x.begin(), x.end());
      float yf, gf;
      mf.forward_grad(xf.data(), &yf, i, &gf);
      CHECK_NEAR(gf, g, 1e-4 * (std::fabs(g) + 4000.0 / (rm.sat_hi[i] - rm.sat_lo[i])));
    }
  }
  std::vector<double> x(In);
  for (int i = 0; i < In; ++i) x[i] = rm.sat_hi[i] + 1.0;  // all clamped
  double y, g = 1.0;
  md.forward_grad(x.data(), &y, 0, &g);
  CHECK(g == 0.0);
  CHECK(md.forward_grad(x.data(), &y, In, &g) >= 0 && g == 0.0);  // index out of range
}

// The float kernel's own tanh (on the AVX2 / AVX-512 paths the 15/4 rational with the
// output weight folded into its numerator, see mlp.hpp tanh_folded) through a 1-1-1 model
// whose scalings are the identity: y = w tanh(x), dy/dx = w (1 - tanh^2 x), every 1024th
// float of [-10, 10], both sizes; the float tanh bound (5e-7, activation.hpp) scaled by |w|.
template <class M>
void kernel_tanh_accuracy(double w) {
  const double w1 = 1.0, b1 = 0.0, b_out = 0.0, off = 0.0, gain = 1.0, lo = -20.0, hi = 20.0;
  const dn_mlp_desc d{1, 1, 0, DN_ACT_TANH, &w1, &b1, nullptr, nullptr, &w, &b_out, &off, &gain,
                      0.0, 0.0, 1.0, 0.0, &lo, &hi};
  M m;
  CHECK(m.load(&d) == DN_OK);
  double worst = 0.0, worst_g = 0.0, at = 0.0;
  for (float x = -10.0f; x <= 10.0f;) {
    float y, g;
    CHECK(m.forward_grad(&x, &y, 0, &g) == DN_OK);
    const double t = std::tanh(double(x)), e = std::fabs(y - w * t);
    if (e > worst) {
      worst = e;
      at = x;
    }
    worst_g = std::fmax(worst_g, std::fabs(g - w * (1.0 - t * t)));
    float y0;
    m.forward(&x, &y0);
    CHECK(y0 == y);  // the value is the plain forward's
    uint32_t b;
    std::memcpy(&b, &x, 4);
    b = (b & 0x80000000u) ? (b > 0x80000400u ? b - 1024u : 0u) : b + 1024u;
    std::memcpy(&x, &b, 4);
  }
  std::printf("float kernel (%s) w tanh(x), w = %g: worst |error| %.3g (x = %.9g), of dy/dx %.3g\n",
              dampnet::kernel_isa(), w, worst, at, worst_g);
  CHECK(worst < 5e-7 * std::fabs(w) + 1e-12);
  CHECK(worst_g < 2e-6 * std::fabs(w));
}

int main() {
  kernel_tanh_accuracy<Mlp<float>>(1.0);
  kernel_tanh_accuracy<StaticMlp<float, 1, 1, 0>>(1.0);
  kernel_tanh_accuracy<Mlp<float>>(-0.37);
  kernel_tanh_accuracy<StaticMlp<float, 1, 1, 0>>(2345.6);
  gradient_matches_difference<3, 30, 0>(DN_ACT_TANH, 21);
  gradient_matches_difference<3, 30, 0>(DN_ACT_SIGMOID, 22);
  gradient_matches_difference<4, 17, 9>(DN_ACT_TANH, 23);
  gradient_matches_difference<2, 5, 40>(DN_ACT_SIGMOID, 24);
  static_equals_dynamic<1, 1, 0>(DN_ACT_TANH, 1);
  static_equals_dynamic<3, 30, 0>(DN_ACT_SIGMOID, 2);
  static_equals_dynamic<3, 30, 0>(DN_ACT_TANH, 3);
  static_equals_dynamic<8, 64, 0>(DN_ACT_TANH, 4);
  static_equals_dynamic<5, 16, 8>(DN_ACT_SIGMOID, 5);
  static_equals_dynamic<8, 64, 64>(DN_ACT_TANH, 6);
  static_equals_dynamic<2, 7, 1>(DN_ACT_SIGMOID, 7);
  validation_errors();
  input_policy<double>();
  input_policy<float>();
  output_overflow_is_caught<double>(4, 1e308);
  output_overflow_is_caught<float>(64, 5.9e36);
  float_overflowing_scaling_is_refused();
  TEST_MAIN_RETURN();
}
