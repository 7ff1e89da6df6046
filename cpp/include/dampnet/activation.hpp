// Hidden-layer activations for the MLP kernel.
//
// double: std::tanh (correctly rounded to ~1 ulp) so the double kernel meets
// its 1e-12 relative contract against a float64 reference.
// float: a 13/6-degree odd/even rational interpolant of tanh on [-9, 9]
// (the same form Eigen uses), branch-free so the compiler vectorises the
// hidden layer. Its worst absolute error against std::tanh, measured over
// [-10, 10] by tests/cpp/test_activation.cpp, is 3.2e-7 (bound checked: 5e-7;
// about 5 float ulps, near |tanh| = 1); the sigmoid's is 1.7e-7 (bound 3e-7).
// The logistic sigmoid is evaluated through the identity
// sigmoid(x) = 0.5 + 0.5 * tanh(x / 2), so both activations share one
// approximation and one error bound (halved for the sigmoid).
#pragma once

#include <cmath>

#if defined(__AVX2__) && defined(__FMA__)
#include <immintrin.h>
#define DN_TANH8_AVX2 1
#endif

#include "dampnet/dampnet.h"

namespace dampnet {

enum class Activation : int { tanh = DN_ACT_TANH, sigmoid = DN_ACT_SIGMOID };

// The rational interpolant itself, valid for |x| <= 9 (callers clamp first).
// Both polynomials (in y = x^2) are evaluated by Estrin's scheme rather than
// Horner's: the same operations, but a dependency chain about half as long,
// which is what bounds a single-sample call's latency.
inline float tanh_rational(float x) noexcept {
  const float y = x * x, y2 = y * y, y4 = y2 * y2;
  const float e01 = 4.89352455891786e-03f + 6.37261928875436e-04f * y;
  const float e23 = 1.48572235717979e-05f + 5.12229709037114e-08f * y;
  const float e45 = -8.60467152213735e-11f + 2.00018790482477e-13f * y;
  const float e6 = -2.76076847742355e-16f;
  const float p = x * ((e01 + e23 * y2) + (e45 + e6 * y2) * y4);
  const float q = (4.89352518554385e-03f + 2.26843463243900e-03f * y) +
                  (1.18534705686654e-04f + 1.19825839466702e-06f * y) * y2;
  return p / q;
}

// Outside [-9, 9] tanh rounds to +-1 in float; clamping also maps +-Inf.
inline float clamp_tanh_arg(float a) noexcept {
  const float x = a > 9.f ? 9.f : a;
  return x < -9.f ? -9.f : x;
}

inline float fast_tanh(float a) noexcept { return tanh_rational(clamp_tanh_arg(a)); }

#ifdef DN_TANH8_AVX2
// The same rational on 8 floats with FMA (the AVX2 kernel's activation), arranged
// for the shortest dependency chain: y = min(z^2, 81) equals x^2 for the clamped x
// one operation sooner (NaN: z^2 is NaN and minps returns its second operand, 81;
// x = 9), both polynomials by Estrin in y, and x / q computed while the numerator
// polynomial finishes. Worst absolute error against std::tanh over [-10, 10]:
// 2.7e-7 (tests/cpp/test_activation.cpp checks < 5e-7); +-Inf and NaN give +-1
// and +1. (The reciprocal estimate plus a Newton step instead of the division
// measured no faster here, and less accurate, 3.3e-7.)
// tanh(z) = r * p, as two factors, so that a caller that only needs w * tanh(z)
// can form fma(r, p * w, acc): p * w is ready while the division runs (the MLP's
// output layer, one multiplication less on the chain).
inline void fast_tanh8_factors(__m256 z, __m256& r, __m256& p) noexcept {
  const __m256 x = _mm256_max_ps(_mm256_min_ps(z, _mm256_set1_ps(9.f)), _mm256_set1_ps(-9.f));
  const __m256 y = _mm256_min_ps(_mm256_mul_ps(z, z), _mm256_set1_ps(81.f));
  const __m256 y2 = _mm256_mul_ps(y, y), y4 = _mm256_mul_ps(y2, y2);
  const __m256 e01 = _mm256_fmadd_ps(_mm256_set1_ps(6.37261928875436e-04f), y, _mm256_set1_ps(4.89352455891786e-03f));
  const __m256 e23 = _mm256_fmadd_ps(_mm256_set1_ps(5.12229709037114e-08f), y, _mm256_set1_ps(1.48572235717979e-05f));
  const __m256 e45 = _mm256_fmadd_ps(_mm256_set1_ps(2.00018790482477e-13f), y, _mm256_set1_ps(-8.60467152213735e-11f));
  const __m256 lo = _mm256_fmadd_ps(e23, y2, e01);
  const __m256 hi = _mm256_fmadd_ps(_mm256_set1_ps(-2.76076847742355e-16f), y2, e45);
  p = _mm256_fmadd_ps(hi, y4, lo);
  const __m256 q01 = _mm256_fmadd_ps(_mm256_set1_ps(2.26843463243900e-03f), y, _mm256_set1_ps(4.89352518554385e-03f));
  const __m256 q23 = _mm256_fmadd_ps(_mm256_set1_ps(1.19825839466702e-06f), y, _mm256_set1_ps(1.18534705686654e-04f));
  const __m256 q = _mm256_fmadd_ps(q23, y2, q01);
  r = _mm256_div_ps(x, q);
}
inline __m256 fast_tanh8(__m256 z) noexcept {
  __m256 r, p;
  fast_tanh8_factors(z, r, p);
  return _mm256_mul_ps(r, p);
}
#endif

inline double fast_tanh(double a) noexcept { return std::tanh(a); }
inline double clamp_tanh_arg(double a) noexcept { return a; }
inline double tanh_rational(double a) noexcept { return std::tanh(a); }

// Activation applied to one pre-activation value.
template <typename T>
inline T activate(Activation act, T x) noexcept {
  if (act == Activation::sigmoid) return T(0.5) + T(0.5) * fast_tanh(T(0.5) * x);
  return fast_tanh(x);
}

}  // namespace dampnet
