// The SSE forms of the float clamp and padded dot product, for the SSE backend (and the Eigen
// backend on x86): the same results as common.hpp's loops, bit for bit (namespace detail::sse).
#pragma once

#include <immintrin.h>

#include "dampnet/kernel/common.hpp"

namespace dampnet {
inline namespace DN_KERNEL_NS {
namespace detail {
namespace sse {

// Clamp n (a multiple of 8) floats to [-9, 9]. GCC will not turn the portable
// compare-and-select into minps/maxps (it must keep NaN and -0 semantics), so
// the instructions are used directly (a NaN becomes +9: minps returns its second
// operand when either is NaN).
inline void clamp_tanh_args(float* h, int n) noexcept {
#if defined(__AVX__)
  const __m256 lo = _mm256_set1_ps(-9.f), hi = _mm256_set1_ps(9.f);
  for (int j = 0; j < n; j += 8)
    _mm256_store_ps(h + j, _mm256_max_ps(_mm256_min_ps(_mm256_load_ps(h + j), hi), lo));
#else
  const __m128 lo = _mm_set1_ps(-9.f), hi = _mm_set1_ps(9.f);
  for (int j = 0; j < n; j += 4)
    _mm_store_ps(h + j, _mm_max_ps(_mm_min_ps(_mm_load_ps(h + j), hi), lo));
#endif
}

// loops::dot_padded's partial sums, in its order, with the horizontal sum in registers.
template <typename T, int kN>
inline T dot_padded(const T* __restrict w, const T* __restrict a, int n) noexcept {
  const int nn = kN > 0 ? kN : n;
  if constexpr (std::is_same<T, float>::value) {
    __m128 lo = _mm_setzero_ps(), hi = _mm_setzero_ps();  // part[0..3], part[4..7]
    for (int j = 0; j < nn; j += 8) {
      lo = _mm_add_ps(lo, _mm_mul_ps(_mm_load_ps(w + j), _mm_load_ps(a + j)));
      hi = _mm_add_ps(hi, _mm_mul_ps(_mm_load_ps(w + j + 4), _mm_load_ps(a + j + 4)));
    }
    const __m128 q = _mm_add_ps(lo, hi);  // q_l = p_l + p_{l+4}
    const __m128 t = _mm_add_ps(q, _mm_shuffle_ps(q, q, _MM_SHUFFLE(2, 3, 0, 1)));  // q0+q1, ., q2+q3, .
    return _mm_cvtss_f32(_mm_add_ss(t, _mm_movehl_ps(t, t)));
  }
  alignas(DN_KERNEL_ALIGN) T part[8] = {};
  for (int j = 0; j < nn; j += 8)
    for (int l = 0; l < 8; ++l) part[l] += w[j + l] * a[j + l];
  return ((part[0] + part[4]) + (part[1] + part[5])) + ((part[2] + part[6]) + (part[3] + part[7]));
}

}  // namespace sse
}  // namespace detail
}  // namespace DN_KERNEL_NS
}  // namespace dampnet
