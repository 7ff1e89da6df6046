// The Eigen backend of the MLP kernel (kernel/backend.hpp: DN_KERNEL_BACKEND=eigen, or
// DAMPNET_USE_EIGEN defined; CMake DAMPNET_USE_EIGEN=ON): the dense layers through Eigen
// (compile-time dimensions where known); the clamp and the output's dot product are the SSE
// backend's on x86 and the portable loops elsewhere.
#pragma once

#include <Eigen/Core>

#include "dampnet/kernel/common.hpp"
#if defined(__SSE__)
#include "dampnet/kernel/sse_ops.hpp"
#endif

namespace dampnet {
inline namespace DN_KERNEL_NS {
namespace detail {

constexpr bool kSimdFloat = false;
constexpr bool kFused1 = false;

// y = W^T x for the transposed storage wt[n_in][n_out] (+ bias), n_out outputs.
template <typename T, int kIn, int kOut>
inline void dense_t(const T* wt, const T* b, const T* x, T* y, int n_in, int n_out) noexcept {
  const int ni = kIn > 0 ? kIn : n_in;
  const int no = kOut > 0 ? kOut : n_out;
  constexpr int R = kIn > 0 ? kIn : Eigen::Dynamic, C = kOut > 0 ? kOut : Eigen::Dynamic;
  using Mat = Eigen::Matrix<T, R, C, (C == 1 ? Eigen::ColMajor : Eigen::RowMajor)>;
  using VecIn = Eigen::Matrix<T, R, 1>;
  using VecOut = Eigen::Matrix<T, C, 1>;
  Eigen::Map<const Mat> W(wt, ni, no);
  Eigen::Map<const VecIn> xv(x, ni);
  Eigen::Map<const VecOut> bv(b, no);
  Eigen::Map<VecOut> yv(y, no);
  yv.noalias() = bv;
  yv.noalias() += W.transpose() * xv;
}

#if defined(__SSE__)
using range_all::inputs_in_range;
using sse::clamp_tanh_args;
using sse::dot_padded;
#else
using loops::clamp_tanh_args;
using loops::dot_padded;
using range_branch::inputs_in_range;
#endif

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
