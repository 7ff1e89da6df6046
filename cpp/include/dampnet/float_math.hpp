// Float log1p and expm1 for the valve term's float builds (DN_LOOP_FLOAT: a microcontroller's
// loop). newlib's log1pf and expm1f took 127-132 and 126 cycles in the Cortex-M4F quarter-car
// step's worst case with a digressive valve; with these that step is 122 cycles shorter, about
// half of theirs (bench/RESULTS.md). Double builds keep std::log1p and std::expm1.
//
// Both are branch-light, call nothing, and are [RT]. Measured against the double functions by
// tests/cpp/unit/test_float_math.cpp (bound checked: 4 float epsilons relative): log1p_f on
// [0, 1e8], expm1_neg_f on [0, 200].
#pragma once

#include <cstdint>
#include <cstring>

// Out of line where flash is scarce (DN_SMALL_CODE, set by the library's build): the valve
// term's force and its gradient each inline the law, and would each carry a copy of these.
#if defined(DN_SMALL_CODE) && DN_SMALL_CODE && defined(__GNUC__)
#define DN_FMATH_INLINE __attribute__((noinline)) inline
#else
#define DN_FMATH_INLINE inline
#endif

namespace dampnet {
namespace fmath {

inline float from_bits(uint32_t b) noexcept {
  float f;
  std::memcpy(&f, &b, sizeof f);
  return f;
}
inline uint32_t to_bits(float f) noexcept {
  uint32_t b;
  std::memcpy(&b, &f, sizeof b);
  return b;
}

// ln(1 + x) for x >= 0 finite (the valve's opening k_d (|v| - v_k); the caller never passes a
// negative, infinite or NaN x). u = 1 + x = m 2^e with m in [sqrt(1/2), sqrt(2)): ln u = e ln2 +
// 2 atanh(s), s = (m - 1) / (m + 1), |s| <= 0.172, by its series to s^9 (truncation < 1e-9
// relative); plus (x - (u - 1)) / u, what rounding 1 + x lost (so tiny x gives x).
DN_FMATH_INLINE float log1p_f(float x) noexcept {
  const float u = 1.0f + x;
  const uint32_t b = to_bits(u);
  int e = static_cast<int>(b >> 23) - 127;  // u >= 1: the sign bit is 0
  float m = from_bits((b & 0x007fffffu) | 0x3f800000u);  // [1, 2)
  if (m > 1.41421356f) m *= 0.5f, e += 1;
  const float s = (m - 1.0f) / (m + 1.0f), s2 = s * s;
  const float lm = s * (2.0f + s2 * (0.666666667f + s2 * (0.4f + s2 * (0.285714286f + s2 * 0.222222222f))));
  const float fe = static_cast<float>(e);
  // ln2 in two parts (the high one with 9 bits free, so fe * it is exact for |e| < 512)
  return (fe * 0.693145752f + (lm + (x - (u - 1.0f)) / u)) + fe * 1.42860677e-06f;
}

// expm1(-t) = e^-t - 1 for t >= 0 (t NaN gives NaN). Below ln2 / 2 its Taylor polynomial to
// t^8 (no cancellation: e^-t - 1 is not formed); above, e^-t = 2^-k e^r, t = k ln2 - r,
// |r| <= ln2 / 2, e^r by its Taylor polynomial to r^8, and then e^-t - 1, which loses nothing
// there (e^-t <= 0.71). Beyond 87.3 (e^-t under float's smallest normal) it is -1.
DN_FMATH_INLINE float expm1_neg_f(float t) noexcept {
  const float y = -t;
  auto taylor = [](float r) noexcept {  // e^r - 1 for |r| <= ln2 / 2 (truncation < 3e-9)
    return r * (1.0f + r * (0.5f + r * (0.166666667f + r * (0.0416666667f + r * (0.00833333333f +
                r * (0.00138888889f + r * (0.000198412698f + r * 2.48015873e-05f)))))));
  };
  if (!(t > 0.34657359f)) return taylor(y);  // (also t NaN: NaN)
  if (t > 87.3f) return -1.0f;
  const float k = static_cast<float>(static_cast<int>(t * 1.44269504f + 0.5f));  // round(t / ln2), 1..126
  const float r = (k * 0.693145752f - t) + k * 1.42860677e-06f;  // -t + k ln2, |r| <= ln2 / 2 (+ rounding)
  const float two_mk = from_bits(static_cast<uint32_t>(127 - static_cast<int>(k)) << 23);  // 2^-k, exact
  return (taylor(r) * two_mk + two_mk) - 1.0f;
}

}  // namespace fmath
}  // namespace dampnet
