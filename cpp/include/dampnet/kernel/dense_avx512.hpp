// The AVX-512 backend of the MLP kernel (kernel/backend.hpp: DN_KERNEL_BACKEND=avx512; CMake
// DAMPNET_AVX512, off by default: measured no faster than AVX2, bench/RESULTS.md): the AVX2
// backend's float pass (kernel/simd_x86.hpp) per 16 neurons in __m512 registers (layers padded
// to 16, arrays 64-byte aligned); a two-layer model's first layer takes the 13/6 rational tanh
// (fast_tanh16), the last layer the 15/4 one with the output weights folded in.
#pragma once

// GCC 12's AVX-512 intrinsics (_mm512_min_ps, _mm512_rcp14_ps, _mm512_castps512_ps256,
// ...) pass a self-initialised "undefined" vector that -Wuninitialized reports.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wuninitialized"
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

#include "dampnet/kernel/common.hpp"
#include "dampnet/kernel/simd_x86.hpp"

// This translation unit has fast_tanh16 (tests/cpp/unit/test_activation.cpp).
#define DN_TANH16_AVX512 1

namespace dampnet {

// The same rational on 16 floats (the AVX-512 kernel's activation), with a shorter
// chain than fast_tanh8: y = z^2 unclamped (no min on the chain; lanes with |z| > 9
// or NaN, found by a compare beside it, are replaced by +-1 through write masks,
// which cost nothing), and 1/q by vrcp14ps (relative error < 2^-14) and one
// Newton step folded into x / q, shorter than a 512-bit division.
// Worst absolute error against std::tanh over [-10, 10] (tests/cpp/unit/test_activation.cpp):
// 3.0e-7 (checked < 5e-7, the float bound); |z| > 9 and +-Inf give exactly +-1, NaN +1.
// tanh(z) = r * p as two factors (p = 1 where saturated).
inline void fast_tanh16_factors(__m512 z, __m512& r, __m512& p) noexcept {
  const __m512 one = _mm512_set1_ps(1.f);
  const __m512 x = _mm512_max_ps(_mm512_min_ps(z, _mm512_set1_ps(9.f)), _mm512_set1_ps(-9.f));
  // |z| <= 9 (false for NaN): the rational's lanes; the others take x / 9 = +-1 (NaN: x = 9).
  const __mmask16 in = _mm512_cmp_ps_mask(_mm512_abs_ps(z), _mm512_set1_ps(9.f), _CMP_LE_OQ);
  const __m512 sat = _mm512_mul_ps(x, _mm512_set1_ps(1.f / 9.f));  // exactly +-1
  const __m512 y = _mm512_mul_ps(z, z);
  const __m512 y2 = _mm512_mul_ps(y, y), y4 = _mm512_mul_ps(y2, y2);
  const __m512 e01 = _mm512_fmadd_ps(_mm512_set1_ps(6.37261928875436e-04f), y, _mm512_set1_ps(4.89352455891786e-03f));
  const __m512 e23 = _mm512_fmadd_ps(_mm512_set1_ps(5.12229709037114e-08f), y, _mm512_set1_ps(1.48572235717979e-05f));
  const __m512 e45 = _mm512_fmadd_ps(_mm512_set1_ps(2.00018790482477e-13f), y, _mm512_set1_ps(-8.60467152213735e-11f));
  const __m512 lo = _mm512_mask_blend_ps(in, one, _mm512_fmadd_ps(e23, y2, e01));  // 1 where saturated
  const __m512 hi = _mm512_fmadd_ps(_mm512_set1_ps(-2.76076847742355e-16f), y2, e45);
  p = _mm512_mask3_fmadd_ps(hi, y4, lo, in);  // hi y4 + lo; where saturated, lo = 1
  const __m512 q01 = _mm512_fmadd_ps(_mm512_set1_ps(2.26843463243900e-03f), y, _mm512_set1_ps(4.89352518554385e-03f));
  const __m512 q23 = _mm512_fmadd_ps(_mm512_set1_ps(1.19825839466702e-06f), y, _mm512_set1_ps(1.18534705686654e-04f));
  const __m512 q = _mm512_fmadd_ps(q23, y2, q01);
#ifdef DN_TANH16_DIV
  r = _mm512_mask_div_ps(sat, in, x, q);
#else
  // x / q = x r0 (1 + e) + O(e^2), r0 = rcp14(q), e = 1 - q r0.
  const __m512 r0 = _mm512_rcp14_ps(q);
  const __m512 e = _mm512_maskz_fnmadd_ps(in, q, r0, one);  // 0 where saturated
  const __m512 xr0 = _mm512_mask_mul_ps(sat, in, x, r0);     // sat where saturated
  r = _mm512_fmadd_ps(xr0, e, xr0);
#endif
}
inline __m512 fast_tanh16(__m512 z) noexcept {
  __m512 r, p;
  fast_tanh16_factors(z, r, p);
  return _mm512_mul_ps(r, p);
}

inline namespace DN_KERNEL_NS {
namespace detail {

struct Simd16 {
  using V = __m512;
  static constexpr int kW = 16;
  static V load(const float* p) noexcept { return _mm512_load_ps(p); }
  static void store(float* p, V v) noexcept { _mm512_store_ps(p, v); }
  static V set1(float x) noexcept { return _mm512_set1_ps(x); }
  static V zero() noexcept { return _mm512_setzero_ps(); }
  static V lane0(float x) noexcept { return _mm512_maskz_mov_ps(1, _mm512_set1_ps(x)); }
  static V add(V a, V b) noexcept { return _mm512_add_ps(a, b); }
  static V mul(V a, V b) noexcept { return _mm512_mul_ps(a, b); }
  static V fmadd(V a, V b, V c) noexcept { return _mm512_fmadd_ps(a, b, c); }
  static V fnmadd(V a, V b, V c) noexcept { return _mm512_fnmadd_ps(a, b, c); }
  static V min(V a, V b) noexcept { return _mm512_min_ps(a, b); }  // NaN in a: b
  static V max(V a, V b) noexcept { return _mm512_max_ps(a, b); }
  static V div(V a, V b) noexcept { return _mm512_div_ps(a, b); }
  static V tanh(V z) noexcept { return fast_tanh16(z); }
  // Halves added, then the 8 as Simd8::hsum combines them.
  static float hsum(V v) noexcept {
    return Simd8::hsum(_mm256_add_ps(_mm512_castps512_ps256(v), _mm512_extractf32x8_ps(v, 1)));
  }
};
using SimdKernel = Simd16;

}  // namespace detail
}  // namespace DN_KERNEL_NS
}  // namespace dampnet

#include "dampnet/kernel/dense_simd.hpp"  // the interface, over Simd16

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif
