// Hidden-layer activations for the MLP kernel.
//
// double: tanh_d below (exp-based, within a few ulps of std::tanh, vectorisable),
// so the double kernel meets its 1e-12 relative contract against a float64 reference.
// float (scalar and SSE paths): a 13/6-degree odd/even rational interpolant of tanh
// on [-9, 9] (the same form Eigen uses), branch-free so the compiler vectorises the
// hidden layer; the AVX2 and AVX-512 kernels use a 15/4 rational (below) in the last
// hidden layer (an AVX-512 two-layer model's first layer keeps the 13/6 form). Their vector
// forms live with those backends (kernel/simd_x86.hpp fast_tanh8, kernel/dense_avx512.hpp
// fast_tanh16): this file keys on no compiler flag. The 13/6 form's worst absolute error
// against std::tanh, measured over [-10, 10] by tests/cpp/unit/test_activation.cpp, is
// 3.2e-7 (bound checked: 5e-7; about 5 float ulps, near |tanh| = 1); the sigmoid's is
// 1.7e-7 (bound 3e-7).
// The logistic sigmoid is evaluated through the identity
// sigmoid(x) = 0.5 + 0.5 * tanh(x / 2), so both activations share one
// approximation and one error bound (halved for the sigmoid).
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>

#include "dampnet/dampnet.h"

namespace dampnet {

enum class Activation : int { tanh = DN_ACT_TANH, sigmoid = DN_ACT_SIGMOID };

// The rational interpolant itself, valid for |x| <= 9 (callers clamp first).
// Both polynomials (in y = x^2) are evaluated by Estrin's scheme rather than
// Horner's: the same operations, but a dependency chain about half as long,
// which is what bounds a single-sample call's latency.
// Its coefficients (numerator p0..p6, denominator q0..q3) as one object, so that a scalar
// kernel can hold them in registers across its loop (mlp.hpp, forward_fused1).
struct TanhRationalK {
  float p0, p1, p2, p3, p4, p5, p6, q0, q1, q2, q3;
};
constexpr TanhRationalK kTanhRational = {
    4.89352455891786e-03f,  6.37261928875436e-04f, 1.48572235717979e-05f, 5.12229709037114e-08f,
    -8.60467152213735e-11f, 2.00018790482477e-13f, -2.76076847742355e-16f, 4.89352518554385e-03f,
    2.26843463243900e-03f,  1.18534705686654e-04f, 1.19825839466702e-06f};
inline float tanh_rational(float x, const TanhRationalK& k) noexcept {
  const float y = x * x, y2 = y * y, y4 = y2 * y2;
  const float e01 = k.p0 + k.p1 * y;
  const float e23 = k.p2 + k.p3 * y;
  const float e45 = k.p4 + k.p5 * y;
  const float e6 = k.p6;
  const float p = x * ((e01 + e23 * y2) + (e45 + e6 * y2) * y4);
  const float q = (k.q0 + k.q1 * y) + (k.q2 + k.q3 * y) * y2;
  return p / q;
}
inline float tanh_rational(float x) noexcept { return tanh_rational(x, kTanhRational); }

// Outside [-9, 9] tanh rounds to +-1 in float; clamping also maps +-Inf.
inline float clamp_tanh_arg(float a) noexcept {
  const float x = a > 9.f ? 9.f : a;
  return x < -9.f ? -9.f : x;
}

inline float fast_tanh(float a) noexcept { return tanh_rational(clamp_tanh_arg(a)); }

// The AVX2 (and AVX-512) kernels' float tanh: a 15/4-degree odd/even rational,
// tanh(x) ~ x P(y) / Q(y), y = x^2, x clamped to +-kTanhClamp (tanh(8.125) = 1 - 1.8e-7),
// P of degree 7 and Q(y) = y^2 + q1 y + q0 = y (y + q1) + q0, evaluated as one add and
// one FMA: a shorter chain to the division than the 13/6 form's three FMAs. Fitted by
// bench/experiments/fit_tanh_rational.py (linearised minimax over [0, kTanhClamp] with an allowance
// for float rounding; 2.1e-7 from tanh in exact arithmetic, clamp included). Used with
// each neuron's output weight folded into P's coefficients by the MLP kernel (kernel/simd_x86.hpp,
// tanh_folded). Measured worst error of the float evaluation: 3.1e-7 over every float in
// [-10, 10] (fast_tanh8; 2.9e-7 every 128th float, the test's walk).
constexpr int kTanhPTerms = 8;
constexpr double kTanhP[kTanhPTerms] = {
    56.013727922621555,      6.4971212826648399,      0.078959531331288441,
    -0.00045613713383282266, 4.2261502248783843e-06,  -3.4723963391927464e-08,
    1.9402772002528185e-10,  -5.1804715822882512e-13};
constexpr double kTanhQ0 = 56.013765804633906, kTanhQ1 = 25.168260707120925;
constexpr float kTanhClamp = 8.125f, kTanhClampSq = 66.015625f;  // both exact

// double: tanh(z) = sign(z) e / (e + 2) with e = expm1(2 |z|), for |z| <= 20 (the
// caller clamps: clamp_tanh_arg; tanh(20) rounds to 1). expm1(t) = 2^k (p(r) + 1) - 1
// with t = k ln2 + r, |r| <= ln2/2, p(r) = expm1(r) by its Taylor polynomial to r^13
// (truncation < 2e-17 relative); the scaling by 2^k and 2^k - 1 are exact, so e is
// accurate to a few ulps relative for every z (no cancellation near 0). Branch-free and
// call-free, so the hidden layer's loop vectorises (SSE2: 2 lanes, AVX2: 4; the clamp
// is a separate pass, as GCC will not if-convert a select in a loop that divides).
// Worst relative error against std::tanh over [-25, 25], measured by
// tests/cpp/unit/test_activation.cpp: 5.9e-16, 2.6 ulps (bound checked: 4 ulps); NaN gives +1.
inline double tanh_d_core(double z) noexcept {
  const double a = std::fabs(z);
  const double t = 2.0 * a;
  const double shifter = 6755399441055744.0;  // 1.5 * 2^52: adding it rounds to an integer
  const double kd = t * 1.4426950408889634 + shifter;
  const double k = kd - shifter;  // round(t / ln2), 0..58
  const double r = (t - k * 6.93147180369123816490e-01) - k * 1.90821492927058770002e-10;
  // expm1(r) = r (1 + r/2 + r^2/6 + ... + r^12/13!), the bracket by Estrin.
  const double r2 = r * r, r4 = r2 * r2, r8 = r4 * r4;
  const double c01 = 1.0 + r * (1.0 / 2);
  const double c23 = 1.0 / 6 + r * (1.0 / 24);
  const double c45 = 1.0 / 120 + r * (1.0 / 720);
  const double c67 = 1.0 / 5040 + r * (1.0 / 40320);
  const double c89 = 1.0 / 362880 + r * (1.0 / 3628800);
  const double cab = 1.0 / 39916800 + r * (1.0 / 479001600);
  const double cc = 1.0 / 6227020800.0;
  const double lo = (c01 + c23 * r2) + (c45 + c67 * r2) * r4;
  const double hi = (c89 + cab * r2) + cc * r4;
  const double pm1 = r * (lo + hi * r8);
  // 2^k from its bits: the low bits of kd hold k (kd = 1.5 * 2^52 + k exactly).
  int64_t kbits;
  std::memcpy(&kbits, &kd, sizeof kbits);
  const int64_t sbits = (kbits - int64_t(0x4338000000000000) + 1023) * (int64_t(1) << 52);
  double s2k;
  std::memcpy(&s2k, &sbits, sizeof s2k);
  const double e = pm1 * s2k + (s2k - 1.0);  // expm1(2 |z|)
  return std::copysign(e / (e + 2.0), z);
}

// Outside [-20, 20] tanh rounds to +-1 in double; NaN -> 20 (+1), as the float clamp.
inline double clamp_tanh_arg(double a) noexcept { return !(a <= 20.0) ? 20.0 : (a < -20.0 ? -20.0 : a); }
inline double tanh_d(double z) noexcept { return tanh_d_core(clamp_tanh_arg(z)); }

inline double fast_tanh(double a) noexcept { return tanh_d(a); }
inline double tanh_rational(double a) noexcept { return tanh_d_core(a); }  // after clamp_tanh_arg
inline double tanh_rational(double a, const TanhRationalK&) noexcept { return tanh_d_core(a); }

// Activation applied to one pre-activation value.
template <typename T>
inline T activate(Activation act, T x) noexcept {
  if (act == Activation::sigmoid) return T(0.5) + T(0.5) * fast_tanh(T(0.5) * x);
  return fast_tanh(x);
}

}  // namespace dampnet
