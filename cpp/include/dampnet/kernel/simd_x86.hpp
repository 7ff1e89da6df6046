// What the AVX2 and AVX-512 backends of the MLP kernel share (kernel/dense_avx2.hpp,
// kernel/dense_avx512.hpp): the 8-wide 15/4 rational tanh, the 8-wide vector operations, and
// the float forward pass written once over a vector width (Simd8 here, Simd16 in
// dense_avx512.hpp): per block of neurons, dense (FMA), tanh and the output FMA in registers.
#pragma once

#include <immintrin.h>

#include <cstdint>
#include <limits>
#include <type_traits>

#include "dampnet/activation.hpp"
#include "dampnet/kernel/common.hpp"

// This translation unit has fast_tanh8 (tests/cpp/unit/test_activation.cpp).
#define DN_TANH8_AVX2 1

namespace dampnet {

// The 15/4 rational on 8 floats with FMA, in the MLP kernel's order of operations:
// y = min(z^2, kTanhClampSq) equals x^2 for the clamped x one operation sooner (NaN: z^2
// is NaN and minps returns its second operand; x = kTanhClamp), P by Estrin in y, and
// t = (x / q) P. Worst absolute error against std::tanh over [-10, 10]: 3.1e-7
// (tests/cpp/unit/test_activation.cpp checks < 5e-7); +-Inf and NaN give +-(1 - 1.2e-7) and
// +(1 - 1.2e-7), the rational's value at the clamp.
inline __m256 fast_tanh8(__m256 z) noexcept {
  const __m256 x = _mm256_max_ps(_mm256_min_ps(z, _mm256_set1_ps(kTanhClamp)), _mm256_set1_ps(-kTanhClamp));
  const __m256 y = _mm256_min_ps(_mm256_mul_ps(z, z), _mm256_set1_ps(kTanhClampSq));
  const __m256 y2 = _mm256_mul_ps(y, y), y4 = _mm256_mul_ps(y2, y2);
  auto c = [](int k) { return _mm256_set1_ps(static_cast<float>(kTanhP[k])); };
  const __m256 c01 = _mm256_fmadd_ps(c(1), y, c(0)), c23 = _mm256_fmadd_ps(c(3), y, c(2));
  const __m256 c45 = _mm256_fmadd_ps(c(5), y, c(4)), c67 = _mm256_fmadd_ps(c(7), y, c(6));
  const __m256 p = _mm256_fmadd_ps(_mm256_fmadd_ps(c67, y2, c45), y4, _mm256_fmadd_ps(c23, y2, c01));
  const __m256 q = _mm256_fmadd_ps(y, _mm256_add_ps(y, _mm256_set1_ps(static_cast<float>(kTanhQ1))),
                                   _mm256_set1_ps(static_cast<float>(kTanhQ0)));
  return _mm256_mul_ps(_mm256_div_ps(x, q), p);
}

inline namespace DN_KERNEL_NS {
namespace detail {

// inputs_in_range for the float SIMD kernels: one vector compare against the stored ranges
// (lanes beyond the inputs compare against -inf / +inf), fewer operations beside the chain than
// 2 n_in scalar compares. Up to 4 compile-time inputs are gathered by scalar loads; otherwise a
// masked load reads x[0..n_in-1] (AVX vmaskmovps: masked lanes are not read and cannot
// fault, though one lying on an unmapped page costs a microcode assist). double: range_all's.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Warray-bounds"
#endif
namespace simd {
template <typename T, int kIn, class P>
inline bool inputs_in_range(const P& p, const T* x) noexcept {
  if constexpr (std::is_same<T, float>::value) {
    if constexpr (kIn > 0 && kIn <= 4) {
      // (Read through a pointer the compiler cannot see equals x: else GCC reuses these
      // scalar loads for layer 1 and broadcasts from registers, a longer chain than
      // vbroadcastss from memory.)
      const float* xc = x;
#if defined(__GNUC__)
      __asm__("" : "+r"(xc));
#endif
      const __m128 v = _mm_setr_ps(xc[0], kIn > 1 ? xc[1] : 0.f, kIn > 2 ? xc[2] : 0.f, kIn > 3 ? xc[3] : 0.f);
      const __m128 ok = _mm_and_ps(_mm_cmp_ps(v, _mm_load_ps(p.sat_lo8.data()), _CMP_GE_OQ),
                                   _mm_cmp_ps(v, _mm_load_ps(p.sat_hi8.data()), _CMP_LE_OQ));
      return _mm_movemask_ps(ok) == 0xf;
    } else {
      const __m256 v = _mm256_maskload_ps(x, _mm256_load_si256(reinterpret_cast<const __m256i*>(p.in_mask8.data())));
      const __m256 ok = _mm256_and_ps(_mm256_cmp_ps(v, _mm256_load_ps(p.sat_lo8.data()), _CMP_GE_OQ),
                                      _mm256_cmp_ps(v, _mm256_load_ps(p.sat_hi8.data()), _CMP_LE_OQ));
      return _mm256_movemask_ps(ok) == 0xff;
    }
  }
  const int ni = kIn > 0 ? kIn : p.n_in;
  bool ok = true;
  for (int i = 0; i < ni; ++i) ok &= (x[i] >= p.sat_lo[i]) & (x[i] <= p.sat_hi[i]);
  return ok;
}
}  // namespace simd
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

// The vector operations of one SIMD width, for the pipeline below written once:
// Simd8 (AVX2+FMA, __m256) here and Simd16 (__m512) in dense_avx512.hpp.
struct Simd8 {
  using V = __m256;
  static constexpr int kW = 8;
  static V load(const float* p) noexcept { return _mm256_load_ps(p); }
  static void store(float* p, V v) noexcept { _mm256_store_ps(p, v); }
  static V set1(float x) noexcept { return _mm256_set1_ps(x); }
  static V zero() noexcept { return _mm256_setzero_ps(); }
  static V lane0(float x) noexcept { return _mm256_setr_ps(x, 0.f, 0.f, 0.f, 0.f, 0.f, 0.f, 0.f); }
  static V add(V a, V b) noexcept { return _mm256_add_ps(a, b); }
  static V mul(V a, V b) noexcept { return _mm256_mul_ps(a, b); }
  static V fmadd(V a, V b, V c) noexcept { return _mm256_fmadd_ps(a, b, c); }
  static V fnmadd(V a, V b, V c) noexcept { return _mm256_fnmadd_ps(a, b, c); }
  static V min(V a, V b) noexcept { return _mm256_min_ps(a, b); }  // NaN in a: b
  static V max(V a, V b) noexcept { return _mm256_max_ps(a, b); }
  static V div(V a, V b) noexcept { return _mm256_div_ps(a, b); }
  static V tanh(V z) noexcept { return fast_tanh8(z); }
  // The 8 partial sums combined in dot_padded's order.
  static float hsum(V v) noexcept {
    const __m128 q = _mm_add_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
    const __m128 t = _mm_add_ps(q, _mm_shuffle_ps(q, q, _MM_SHUFFLE(2, 3, 0, 1)));
    return _mm_cvtss_f32(_mm_add_ss(t, _mm_movehl_ps(t, t)));
  }
};


// One block of S::kW outputs of a dense layer: init + sum_i x[i] * wt[i * stride + 0..kW-1].
// Up to 4 inputs in one FMA chain; more in four interleaved chains (latency n/4 FMAs).
template <class S, int kN>
inline typename S::V dense_block(typename S::V init, const float* wt, const float* x, int n_dyn,
                                 int stride) noexcept {
  const int n = kN > 0 ? kN : n_dyn;
  if (n <= 4) {
    for (int i = 0; i < n; ++i) init = S::fmadd(S::load(wt + i * stride), S::set1(x[i]), init);
    return init;
  }
  typename S::V c1 = S::zero(), c2 = c1, c3 = c1;
  const int n4 = n - n % 4;
  for (int i = 0; i < n4; i += 4) {
    init = S::fmadd(S::load(wt + i * stride), S::set1(x[i]), init);
    c1 = S::fmadd(S::load(wt + (i + 1) * stride), S::set1(x[i + 1]), c1);
    c2 = S::fmadd(S::load(wt + (i + 2) * stride), S::set1(x[i + 2]), c2);
    c3 = S::fmadd(S::load(wt + (i + 3) * stride), S::set1(x[i + 3]), c3);
  }
  for (int i = n4; i < n; ++i) init = S::fmadd(S::load(wt + i * stride), S::set1(x[i]), init);
  return S::add(S::add(init, c1), S::add(c2, c3));
}

// w_j tanh(z_j) for one block of the last hidden layer as r * pw: the 15/4 rational of
// activation.hpp (fast_tanh8's operations) with the neuron's output weight folded into
// the numerator's coefficients (tw[k * stride + j] = P_k w_j, made by load()), so that
// the output is one FMA per block, acc + r pw, and the numerator with its weight is off
// the chain (ready before the division is). r = x / q.
template <class S>
inline void tanh_folded(typename S::V z, const float* tw, int stride, typename S::V& r,
                        typename S::V& pw) noexcept {
  using V = typename S::V;
  const V x = S::max(S::min(z, S::set1(kTanhClamp)), S::set1(-kTanhClamp));  // NaN: +clamp
  const V y = S::min(S::mul(z, z), S::set1(kTanhClampSq));
  const V y2 = S::mul(y, y), y4 = S::mul(y2, y2);
  const V c01 = S::fmadd(S::load(tw + stride), y, S::load(tw));
  const V c23 = S::fmadd(S::load(tw + 3 * stride), y, S::load(tw + 2 * stride));
  const V c45 = S::fmadd(S::load(tw + 5 * stride), y, S::load(tw + 4 * stride));
  const V c67 = S::fmadd(S::load(tw + 7 * stride), y, S::load(tw + 6 * stride));
  pw = S::fmadd(S::fmadd(c67, y2, c45), y4, S::fmadd(c23, y2, c01));
  const V q = S::fmadd(y, S::add(y, S::set1(static_cast<float>(kTanhQ1))), S::set1(static_cast<float>(kTanhQ0)));
  r = S::div(x, q);
}

// The float forward pass after the inputs: per block of S::kW neurons, dense (FMA),
// tanh and the output FMA in registers, the blocks' outputs accumulated in one FMA chain
// in block order (the blocks finish one after another, limited by the FMA ports, so a
// serial chain waits least for the last one), b_out in lane 0 of the accumulator. Returns
// b_out + sum_j w_out[j] t_j; with kGrad also (in *dys) the forward-mode derivative for
// the input whose layer-1 column is `col` (nullptr: that input was clamped, derivative 0):
// sum_j (w_j - (w_j t_j) t_j) col_j, with t_j = (w_j t_j) / w_j by the stored 1/w_j, so
// that the value is computed exactly as without kGrad.
template <class S, int kIn, int kH1, int kH2, bool kGrad, bool kCurv, class P>
inline float forward_simd(const P& p, const float* xs, const float* col, float* dys, float* d2ys) noexcept {
  using V = typename S::V;
  constexpr int kW = S::kW;
  constexpr int kP1 = kH1 > 0 ? pad(kH1) : kDynamic;
  constexpr int kP2 = kH2 > 0 ? pad(kH2) : (kH2 == 0 ? 0 : kDynamic);
  constexpr int cap_h1 = kH1 > 0 ? kP1 : P::P1;
  constexpr int stride = P::kTw;
  const int ni = kIn > 0 ? kIn : p.n_in;
  const int h1 = kP1 > 0 ? kP1 : p.n_h1p;
  const int h2 = kP2 >= 0 ? kP2 : p.n_h2p;
  V acc = S::lane0(p.b_out), dacc = S::zero(), d2acc = S::zero();
  // The last layer's contribution of one block: acc += w t; with kGrad, dacc += w (1 - t^2) d;
  // with kCurv (one layer), d2acc += -2 w t (1 - t^2) d^2.
  auto last = [&](V z, int j, const float* dz) {
    (void)dz;
    V r, pw;
    tanh_folded<S>(z, p.tw.data() + j, stride, r, pw);
    acc = S::fmadd(r, pw, acc);
    if constexpr (kGrad) {
      if (dz) {
        const V wt = S::mul(r, pw), t = S::mul(wt, S::load(p.inv_w.data() + j));
        const V d = S::load(dz);
        dacc = S::fmadd(S::fnmadd(wt, t, S::load(p.w_out.data() + j)), d, dacc);
        if constexpr (kCurv) {
          if (kH2 == 0 || h2 == 0) {  // (two layers: not computed)
            const V s = S::fnmadd(t, t, S::set1(1.f));  // 1 - t^2
            d2acc = S::fmadd(S::mul(S::mul(wt, s), S::mul(d, d)), S::set1(-2.f), d2acc);
          }
        }
      }
    }
  };
  if (kH2 == 0 || h2 == 0) {
    for (int j = 0; j < h1; j += kW)
      last(dense_block<S, kIn>(S::load(p.b1.data() + j), p.w1t.data() + j, xs, ni, h1), j,
           col ? col + j : nullptr);
  } else {
    const V one = S::set1(1.f);
    alignas(4 * kW) float a1[cap_h1];
    alignas(4 * kW) float t1[kGrad ? cap_h1 : kPad];
    for (int j = 0; j < h1; j += kW) {
      const V t = S::tanh(dense_block<S, kIn>(S::load(p.b1.data() + j), p.w1t.data() + j, xs, ni, h1));
      S::store(a1 + j, t);
      if constexpr (kGrad)
        S::store(t1 + j, col ? S::mul(S::fnmadd(t, t, one), S::load(col + j)) : S::zero());
    }
    alignas(4 * kW) float lin[kGrad ? kW : 1];
    for (int j = 0; j < h2; j += kW) {
      if constexpr (kGrad) S::store(lin, dense_block<S, kP1>(S::zero(), p.w2t.data() + j, t1, h1, h2));
      last(dense_block<S, kP1>(S::load(p.b2.data() + j), p.w2t.data() + j, a1, h1, h2), j,
           kGrad ? lin : nullptr);
    }
  }
  if constexpr (kGrad) *dys = S::hsum(dacc);
  if constexpr (kCurv) *d2ys = (kH2 == 0 || h2 == 0) ? S::hsum(d2acc) : std::numeric_limits<float>::quiet_NaN();
  (void)d2ys;
  return S::hsum(acc);
}

// forward_simd of kB samples at once, one hidden layer: per block of neurons the weights
// are loaded once for all samples, and the samples' kB independent chains interleave (more
// work in flight per weight load). Each sample's operations and their order are
// forward_simd's, so its result is bit-identical to a single call's.
template <class S, int kIn, int kH1, bool kGrad, int kB, class P>
inline void forward_simd_batch(const P& p, const float* const* xs, const float* const* col,
                               float* sums, float* dys) noexcept {
  using V = typename S::V;
  constexpr int kW = S::kW;
  constexpr int kP1 = kH1 > 0 ? pad(kH1) : kDynamic;
  constexpr int stride = P::kTw;
  const int ni = kIn > 0 ? kIn : p.n_in;
  const int h1 = kP1 > 0 ? kP1 : p.n_h1p;
  V acc[kB], dacc[kB];
  for (int b = 0; b < kB; ++b) acc[b] = S::lane0(p.b_out), dacc[b] = S::zero();
  for (int j = 0; j < h1; j += kW) {
#pragma GCC unroll 1
    for (int b = 0; b < kB; ++b) {
      const V z = dense_block<S, kIn>(S::load(p.b1.data() + j), p.w1t.data() + j, xs[b], ni, h1);
      V r, pw;
      tanh_folded<S>(z, p.tw.data() + j, stride, r, pw);
      acc[b] = S::fmadd(r, pw, acc[b]);
      if constexpr (kGrad) {
        if (col[b]) {
          const V wt = S::mul(r, pw), t = S::mul(wt, S::load(p.inv_w.data() + j));
          dacc[b] = S::fmadd(S::fnmadd(wt, t, S::load(p.w_out.data() + j)), S::load(col[b] + j), dacc[b]);
        }
      }
    }
  }
  for (int b = 0; b < kB; ++b) {
    sums[b] = S::hsum(acc[b]);
    if constexpr (kGrad) dys[b] = S::hsum(dacc[b]);
  }
}

}  // namespace detail
}  // namespace DN_KERNEL_NS
}  // namespace dampnet
