// The backend interface (kernel/backend.hpp) of the x86 SIMD backends, written once over the
// vector width: the including backend defines detail::SimdKernel first (dense_avx2.hpp: Simd8,
// __m256; dense_avx512.hpp: Simd16, __m512). Float models run forward_simd / forward_simd_batch
// (kernel/simd_x86.hpp) over it, b_out included; double models mlp.hpp's portable passes.
#pragma once

#include <type_traits>

#include "dampnet/kernel/common.hpp"
#include "dampnet/kernel/simd_x86.hpp"

namespace dampnet {
inline namespace DN_KERNEL_NS {
namespace detail {

constexpr bool kSimdFloat = true;
constexpr bool kFused1 = false;

using loops::clamp_tanh_args;  // (float: unused, forward_simd)
using loops::dense_t;
using loops::dot_padded;
using simd::inputs_in_range;

// float: forward_simd over SimdKernel (b_out included); double: mlp.hpp's passes.
template <typename T>
constexpr OwnPass kOwnPass = std::is_same<T, float>::value ? OwnPass::always : OwnPass::never;
template <typename T, int kIn, int kH1, int kH2, bool kGrad, bool kCurv, class P>
inline T forward_own(const P& p, const T* xs, const T* col, T* dys, T* d2ys) noexcept {
  if constexpr (std::is_same<T, float>::value) {
    return forward_simd<SimdKernel, kIn, kH1, kH2, kGrad, kCurv>(p, xs, col, dys, d2ys);
  } else {
    return T(0);  // (never called)
  }
}
// forward_batch's float pass (one hidden layer): forward_simd_batch.
template <int kIn, int kH1, bool kGrad, int kB, class P>
inline void forward_batch_simd(const P& p, const float* const* xs, const float* const* col, float* sums,
                               float* dys) noexcept {
  forward_simd_batch<SimdKernel, kIn, kH1, kGrad, kB>(p, xs, col, sums, dys);
}

}  // namespace detail
}  // namespace DN_KERNEL_NS
}  // namespace dampnet
