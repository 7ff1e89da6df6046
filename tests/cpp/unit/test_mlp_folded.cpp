// The folded float description (dn_mlp_folded_f, Mlp::load_folded, dn_mlp_init_folded): what
// load() makes of a dn_mlp_desc, given back as floats, loads into the same parameters bit for
// bit and gives the same forward; the exported header's P_FOLDED_INIT (python/dampnet/export/header.py
// folds in Python) equals the library's own folding of its P_DESC_INIT; validation in float.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "check.hpp"
#include "dampnet/mlp.hpp"
#include "dn_model_default.h"
#include "random_model.hpp"

using dampnet::Mlp;
using dampnet::StaticMlp;
using Params = dampnet::MlpParams<float, DN_CAP_INPUTS, DN_CAP_HIDDEN, DN_CAP_HIDDEN2>;

// The SIMD kernels fold w_out into their tanh from the float w_out (load_folded) or the double
// one (load): there the forwards agree to float rounding, elsewhere bit for bit.
static bool bitwise_kernel() { return Params::kTw == 0; }

template <class A>
static bool same_bits(const A& a, const A& b) {
  return a.size() == 0 || std::memcmp(a.data(), b.data(), sizeof(a[0]) * a.size()) == 0;  // (empty: data() may be null)
}
static bool same_bits(float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// Every parameter the kernel reads, compared bit for bit (tw / inv_w: see bitwise_kernel).
static bool same_params(const Params& a, const Params& b) {
  bool ok = a.n_in == b.n_in && a.n_h1 == b.n_h1 && a.n_h2 == b.n_h2 && a.n_h1p == b.n_h1p &&
            a.n_h2p == b.n_h2p && a.in_offset_folded == b.in_offset_folded;
  ok = ok && same_bits(a.w1t, b.w1t) && same_bits(a.b1, b.b1) && same_bits(a.w2t, b.w2t) &&
       same_bits(a.b2, b.b2) && same_bits(a.w_out, b.w_out) && same_bits(a.b_out, b.b_out) &&
       same_bits(a.in_offset, b.in_offset) && same_bits(a.in_mid, b.in_mid) &&
       same_bits(a.sat_lo, b.sat_lo) && same_bits(a.sat_hi, b.sat_hi) && same_bits(a.out_offset, b.out_offset);
  if (bitwise_kernel()) ok = ok && same_bits(a.tw, b.tw) && same_bits(a.inv_w, b.inv_w);
  return ok;
}

// A folded description read back out of loaded parameters (the layout of dn_mlp_folded_f).
struct Folded {
  std::vector<float> w1, b1, w2, b2, w_out, in_offset, sat_lo, sat_hi, sat_mid;
  dn_mlp_folded_f f{};
  explicit Folded(const Params& p) {
    const int ni = p.n_in, h1 = p.n_h1, h2 = p.n_h2, n_last = h2 > 0 ? h2 : h1;
    for (int j = 0; j < h1; ++j) {
      for (int i = 0; i < ni; ++i) w1.push_back(p.w1t[i * p.n_h1p + j]);
      b1.push_back(p.b1[j]);
    }
    for (int k = 0; k < h2; ++k) {
      for (int j = 0; j < h1; ++j) w2.push_back(p.w2t[j * p.n_h2p + k]);
      b2.push_back(p.b2[k]);
    }
    for (int j = 0; j < n_last; ++j) w_out.push_back(p.w_out[j]);
    for (int i = 0; i < ni; ++i) {
      in_offset.push_back(p.in_offset[i]);
      sat_lo.push_back(p.sat_lo[i]);
      sat_hi.push_back(p.sat_hi[i]);
      sat_mid.push_back(p.in_mid[i]);
    }
    f.n_inputs = ni;
    f.n_hidden1 = h1;
    f.n_hidden2 = h2;
    f.offsets_folded = p.in_offset_folded ? 1 : 0;
    f.w1 = w1.data();
    f.b1 = b1.data();
    f.w2 = h2 > 0 ? w2.data() : nullptr;
    f.b2 = h2 > 0 ? b2.data() : nullptr;
    f.w_out = w_out.data();
    f.b_out = p.b_out;
    f.out_offset = p.out_offset;
    f.in_offset = in_offset.data();
    f.sat_lo = sat_lo.data();
    f.sat_hi = sat_hi.data();
    f.sat_mid = sat_mid.data();
  }
};

// Inputs in range, beyond it and non-finite.
static std::vector<std::vector<float>> inputs(const RandomModel& rm, unsigned seed) {
  std::mt19937 rng(seed);
  std::vector<std::vector<float>> xs;
  for (int k = 0; k < 300; ++k) {
    std::vector<double> x = rm.sample(rng);
    std::vector<float> xf(x.begin(), x.end());
    if (k % 3 == 1) xf[k % xf.size()] += 10.f * (k % 2 ? 1.f : -1.f);
    if (k % 50 == 2) xf[0] = std::numeric_limits<float>::quiet_NaN();
    if (k % 50 == 3) xf[0] = -std::numeric_limits<float>::infinity();
    xs.push_back(xf);
  }
  return xs;
}

static void same_forward(const Mlp<float>& a, const Mlp<float>& b, const std::vector<std::vector<float>>& xs) {
  for (const auto& x : xs) {
    float ya = 0, yb = 0, ga = 0, gb = 0;
    uint32_t ma = 0, mb = 0;
    const int sa = a.forward(x.data(), &ya, &ma), sb = b.forward(x.data(), &yb, &mb);
    CHECK(sa == sb && ma == mb);
    a.forward_grad(x.data(), &ya, 0, &ga);
    b.forward_grad(x.data(), &yb, 0, &gb);
    if (bitwise_kernel()) {
      CHECK(same_bits(ya, yb));
      CHECK(same_bits(ga, gb));
    } else {
      CHECK_NEAR(ya, yb, 1e-6 * 4000.0);
      CHECK_NEAR(ga, gb, 1e-4 * (std::fabs(ga) + 1.0));
    }
  }
}

static void folded_equals_desc(int n_in, int h1, int h2, int act, unsigned seed, bool far_offsets) {
  RandomModel rm(n_in, h1, h2, act, seed);
  if (far_offsets) rm.in_offset[0] = rm.sat_lo[0] = 1e3, rm.sat_hi[0] = 1e3 + 2.0;  // kept unfolded
  Mlp<float> a, b;
  CHECK(a.load(&rm.desc) == DN_OK);
  if (far_offsets) CHECK(!a.params().in_offset_folded);
  Folded fd(a.params());
  CHECK(b.load_folded(&fd.f) == DN_OK);
  CHECK(same_params(a.params(), b.params()));
  same_forward(a, b, inputs(rm, seed + 1));
  // reloading over another model leaves no trace of it (padding zeroed)
  RandomModel other(n_in, 64 < DN_CAP_HIDDEN ? 64 : DN_CAP_HIDDEN, 0, DN_ACT_TANH, seed + 7);
  Mlp<float> c;
  CHECK(c.load(&other.desc) == DN_OK);
  CHECK(c.load_folded(&fd.f) == DN_OK);
  CHECK(same_params(a.params(), c.params()));
  // the double kernel evaluates the same float weights
  Mlp<double> d;
  CHECK(d.load_folded(&fd.f) == DN_OK);
  std::mt19937 rng(seed);
  for (int k = 0; k < 50; ++k) {
    std::vector<double> x = rm.sample(rng);
    std::vector<float> xf(x.begin(), x.end());
    std::vector<double> xd(xf.begin(), xf.end());
    double yd = 0;
    float yf = 0;
    CHECK(d.forward(xd.data(), &yd) == DN_OK);
    CHECK(a.forward(xf.data(), &yf) == DN_OK);
    CHECK_NEAR(yf, yd, 1e-5 * 4000.0);
  }
}

// The generated header: the exporter's folding (Python) is the library's (C++), bit for bit.
static void header_folding_is_the_librarys() {
  const dn_mlp_desc desc = DN_MODEL_DEFAULT_DESC_INIT;
  const dn_mlp_folded_f folded = DN_MODEL_DEFAULT_FOLDED_INIT;
  Mlp<float> a, b;
  CHECK(a.load(&desc) == DN_OK);
  CHECK(b.load_folded(&folded) == DN_OK);
  CHECK(same_params(a.params(), b.params()));
  StaticMlp<float, DN_MODEL_DEFAULT_N_INPUTS, DN_MODEL_DEFAULT_N_HIDDEN1> s;
  CHECK(s.load_folded(&folded) == DN_OK);
  // the C ABI: dn_mlp_init_folded against dn_mlp_init
  alignas(DN_STORAGE_ALIGN) static unsigned char mem_a[1 << 17], mem_b[1 << 17];
  dn_mlp *ma = nullptr, *mb = nullptr;
  CHECK(dn_mlp_size() <= sizeof mem_a);
  CHECK(dn_mlp_init(&desc, mem_a, sizeof mem_a, &ma) == DN_OK);
  CHECK(dn_mlp_init_folded(&folded, mem_b, sizeof mem_b, &mb) == DN_OK);
  CHECK(ma && mb && dn_mlp_n_inputs(mb) == DN_MODEL_DEFAULT_N_INPUTS);
  if (!ma || !mb) return;
  std::mt19937 rng(5);
  for (int k = 0; k < 500; ++k) {
    float x[DN_MODEL_DEFAULT_N_INPUTS];
    for (int i = 0; i < DN_MODEL_DEFAULT_N_INPUTS; ++i) {
      const double lo = dn_model_default_sat_lo[i], hi = dn_model_default_sat_hi[i], w = hi - lo;
      x[i] = static_cast<float>(std::uniform_real_distribution<double>(lo - 0.5 * w, hi + 0.5 * w)(rng));
    }
    // this translation unit's kernel: bit for bit (or to rounding, see bitwise_kernel)
    float ya = 0, yb = 0, ys = 0;
    CHECK(a.forward(x, &ya) == b.forward(x, &yb));
    CHECK(s.forward(x, &ys) >= 0);
    CHECK(same_bits(yb, ys));
    if (bitwise_kernel()) CHECK(same_bits(ya, yb));
    else CHECK_NEAR(ya, yb, 1e-6 * 2.0 / DN_MODEL_DEFAULT_OUT_GAIN);
    // the library's (which may be built for another SIMD path than this file: to rounding)
    uint32_t mka = 0, mkb = 0;
    CHECK(dn_mlp_forward_f(ma, x, &ya, &mka) == dn_mlp_forward_f(mb, x, &yb, &mkb));
    CHECK(mka == mkb);
    CHECK_NEAR(ya, yb, 1e-6 * 2.0 / DN_MODEL_DEFAULT_OUT_GAIN);
    double xd[DN_MODEL_DEFAULT_N_INPUTS], yd = 0;
    for (int i = 0; i < DN_MODEL_DEFAULT_N_INPUTS; ++i) xd[i] = x[i];
    CHECK(dn_mlp_forward(mb, xd, &yd, nullptr) >= 0);
    CHECK_NEAR(yd, yb, 1e-5 * 2.0 / DN_MODEL_DEFAULT_OUT_GAIN);
  }
}

static void validation() {
  RandomModel rm(3, 30, 0, DN_ACT_TANH, 3);
  Mlp<float> a, m;
  CHECK(a.load(&rm.desc) == DN_OK);
  const Folded good(a.params());
  CHECK(m.load_folded(nullptr) == DN_E_NULL);
  auto expect = [&](int status, auto&& edit) {
    Folded fd(a.params());
    edit(fd);
    CHECK(m.load_folded(&fd.f) == status);
  };
  expect(DN_E_NULL, [](Folded& fd) { fd.f.sat_mid = nullptr; });
  expect(DN_E_NULL, [](Folded& fd) { fd.f.w1 = nullptr; });
  expect(DN_E_SIZE, [](Folded& fd) { fd.f.n_inputs = 0; });
  expect(DN_E_SIZE, [](Folded& fd) { fd.f.n_hidden1 = DN_MAX_HIDDEN + 1; });
  expect(DN_E_NULL, [](Folded& fd) { fd.f.n_hidden2 = 4; });  // no layer-2 arrays
  expect(DN_E_NONFINITE_PARAM, [](Folded& fd) { fd.w1[7] = std::numeric_limits<float>::quiet_NaN(); });
  expect(DN_E_NONFINITE_PARAM, [](Folded& fd) { fd.f.b_out = std::numeric_limits<float>::infinity(); });
  expect(DN_E_NONFINITE_PARAM, [](Folded& fd) { fd.sat_hi[2] = std::numeric_limits<float>::infinity(); });
  expect(DN_E_PARAM, [](Folded& fd) { fd.f.offsets_folded = 2; });
  expect(DN_E_PARAM, [](Folded& fd) { fd.sat_lo[1] = fd.sat_hi[1] + 1.f; });
  expect(DN_E_PARAM, [](Folded& fd) { fd.sat_mid[0] = fd.sat_hi[0] + 1.f; });
  StaticMlp<float, 3, 20> wrong;
  CHECK(wrong.load_folded(&good.f) == DN_E_MISMATCH);
  // the C ABI: memory checks as dn_mlp_init, *out NULL on every error
  alignas(DN_STORAGE_ALIGN) static unsigned char mem[1 << 17];
  CHECK(dn_mlp_size() < sizeof mem);
  dn_mlp* out = reinterpret_cast<dn_mlp*>(mem);
  CHECK(dn_mlp_init_folded(&good.f, mem, dn_mlp_size() - 1, &out) == DN_E_SIZE && out == nullptr);
  CHECK(dn_mlp_init_folded(&good.f, mem + 1, dn_mlp_size() + 1, &out) == DN_E_PARAM && out == nullptr);
  CHECK(dn_mlp_init_folded(nullptr, mem, sizeof mem, &out) == DN_E_NULL && out == nullptr);
  CHECK(dn_mlp_init_folded(&good.f, mem, sizeof mem, nullptr) == DN_E_NULL);
  Folded bad(a.params());
  bad.b1[0] = std::numeric_limits<float>::quiet_NaN();
  CHECK(dn_mlp_init_folded(&bad.f, mem, sizeof mem, &out) == DN_E_NONFINITE_PARAM && out == nullptr);
  CHECK(dn_mlp_init_folded(&good.f, mem, sizeof mem, &out) == DN_OK && out != nullptr);
}

// widen_exact: every kind of float (on the host a cast; on a Cortex-M4F integer arithmetic).
static void widening() {
  const float vals[] = {0.f, -0.f, 1.f, -3.5f, 1e-40f, -1e-45f, 3.4e38f, 1.17549435e-38f, 123.456f};
  for (float v : vals) CHECK(dampnet::detail::widen_exact(v) == static_cast<double>(v));
  CHECK(std::signbit(dampnet::detail::widen_exact(-0.f)));
}

int main() {
  std::printf("folded loads on the %s kernel (%s)\n", dampnet::kernel_isa(),
              bitwise_kernel() ? "bit for bit" : "tw from the float w_out: to rounding");
  folded_equals_desc(3, 30, 0, DN_ACT_TANH, 1, false);
  folded_equals_desc(3, 30, 0, DN_ACT_SIGMOID, 2, false);
  folded_equals_desc(2, 7, 0, DN_ACT_TANH, 3, true);
  folded_equals_desc(5, 17, 9, DN_ACT_SIGMOID, 4, false);
  folded_equals_desc(8, 64, 64, DN_ACT_TANH, 5, true);
  folded_equals_desc(1, 1, 0, DN_ACT_TANH, 6, false);
  header_folding_is_the_librarys();
  validation();
  widening();
  TEST_MAIN_RETURN();
}
