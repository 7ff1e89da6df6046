// The SSE backend of the MLP kernel (kernel/backend.hpp: DN_KERNEL_BACKEND=sse, the default on
// x86): plain loops that the compiler vectorises, the clamp and the output's dot product in SSE.
#pragma once

#include "dampnet/kernel/common.hpp"
#include "dampnet/kernel/sse_ops.hpp"

namespace dampnet {
inline namespace DN_KERNEL_NS {
namespace detail {

constexpr bool kSimdFloat = false;
constexpr bool kFused1 = false;

using loops::dense_t;
using range_all::inputs_in_range;
using sse::clamp_tanh_args;
using sse::dot_padded;

// No pass of its own: mlp.hpp's dense + tanh + dot passes (forward_own is never called).
template <typename T>
constexpr OwnPass kOwnPass = OwnPass::never;
template <typename T, int kIn, int kH1, int kH2, bool kGrad, bool kCurv, class P>
inline T forward_own(const P&, const T*, const T*, T*, T*) noexcept {
  return T(0);
}
// (Declared for mlp.hpp's forward_batch, which calls it only where kSimdFloat.)
template <int kIn, int kH1, bool kGrad, int kB, class P>
void forward_batch_simd(const P& p, const float* const* xs, const float* const* col, float* sums, float* dys) noexcept;

}  // namespace detail
}  // namespace DN_KERNEL_NS
}  // namespace dampnet
