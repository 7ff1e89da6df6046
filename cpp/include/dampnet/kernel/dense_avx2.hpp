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

using SimdKernel = Simd8;

}  // namespace detail
}  // namespace DN_KERNEL_NS
}  // namespace dampnet

#include "dampnet/kernel/dense_simd.hpp"  // the interface, over Simd8
