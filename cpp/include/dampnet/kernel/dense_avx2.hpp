// The AVX2+FMA backend of the MLP kernel (kernel/backend.hpp: DN_KERNEL_BACKEND=avx2; CMake
// DAMPNET_AVX2, on by default where the build machine runs it): float models through
// forward_simd per block of 8 neurons in __m256 registers (kernel/simd_x86.hpp), with the
// last hidden layer's 15/4 rational tanh carrying each output weight in its numerator
// (tanh_folded); double models through the portable loops.
#pragma once

#include "dampnet/kernel/common.hpp"
#include "dampnet/kernel/simd_x86.hpp"

namespace dampnet {
inline namespace DN_KERNEL_NS {
namespace detail {

constexpr bool kSimdFloat = true;
constexpr bool kFused1 = false;
using SimdKernel = Simd8;

using loops::clamp_tanh_args;  // (float: unused, forward_simd)
using loops::dense_t;
using loops::dot_padded;
using simd::inputs_in_range;

// float: forward_simd (b_out included); double: mlp.hpp's passes.
template <typename T>
constexpr OwnPass kOwnPass = std::is_same<T, float>::value ? OwnPass::always : OwnPass::never;
template <typename T, int kIn, int kH1, int kH2, bool kGrad, class P>
inline T forward_own(const P& p, const T* xs, const T* col, T* dys) noexcept {
  if constexpr (std::is_same<T, float>::value) {
    return forward_simd<SimdKernel, kIn, kH1, kH2, kGrad>(p, xs, col, dys);
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
