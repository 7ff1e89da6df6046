// The scalar backend of the MLP kernel (kernel/backend.hpp: DN_KERNEL_BACKEND=scalar, the
// default on targets without SSE: Cortex-M and the like): plain loops, and for one hidden
// layer one fused pass (forward_fused1) that keeps every activation in registers.
#pragma once

#include <cmath>
#include <cstddef>
#include <type_traits>

#include "dampnet/kernel/common.hpp"

namespace dampnet {
inline namespace DN_KERNEL_NS {
namespace detail {

constexpr bool kSimdFloat = false;
constexpr bool kFused1 = true;

using loops::clamp_tanh_args;
using loops::dense_t;
using loops::dot_padded;
using range_branch::inputs_in_range;

#define DN_PRAGMA_(x) _Pragma(#x)
#define DN_UNROLL_(n) DN_PRAGMA_(GCC unroll n)
// One hidden layer: forward()'s passes (dense_t, tanh_all, dot_padded's eight partial sums;
// with kGrad the forward-mode column) fused into one pass per partial sum, so that no
// activation is stored and loaded again and the output weights meet each tanh in registers.
// dot_padded's partial sum l is part[l] = sum_k w[8k+l] a[8k+l] in k order: here lane l's
// neurons j = l, l+8, ... in that order, one loop (DN_KERNEL_UNROLL neurons per pass; the lanes
// are not unrolled: one copy of the neuron's code, the flash a microcontroller has little of).
// The operations on each neuron and their order are the passes', so the result is theirs bit
// for bit (and the SSE backend's, whose dot_padded keeps that order). The padding neurons
// (n_h1 .. n_h1p - 1) are skipped: each would add exactly +0 (zero weights; a finite input),
// and a sum that starts at +0 is never -0, so adding +0 changes no bit. The tanh's
// coefficients are held in registers across the loop (on Arm: else reloaded for every
// neuron). Returns b_out + sum_j w_out[j] t_j.
template <typename T, int kIn, int kP1, bool kGrad, bool kCurv, class P>
inline T forward_fused1(const P& p, const T* xs, const T* col, T* dys, T* d2ys) noexcept {
  const int ni = kIn > 0 ? kIn : p.n_in;
  constexpr int stride = P::P1;  // of w1t's rows (layer1_stride)
  const int n = p.n_h1;
  TanhRationalK k = kTanhRational;
#if defined(__arm__) && defined(__ARM_FP)
  __asm__("" : "+t"(k.p0), "+t"(k.p1), "+t"(k.p2), "+t"(k.p3), "+t"(k.p4), "+t"(k.p5));
  __asm__("" : "+t"(k.p6), "+t"(k.q0), "+t"(k.q1), "+t"(k.q2), "+t"(k.q3));
#endif
  constexpr int cap_in = kIn > 0 ? kIn : P::kCapIn;
  T xr[cap_in];  // the inputs in registers (kIn > 0), read once
  for (int i = 0; i < ni; ++i) xr[i] = xs[i];
  T part[8], dpart[8], d2part[8];
  // One pointer walks the neurons of a lane through w1t's row 0; b1, w_out and the other rows
  // are at fixed distances from it (members of p; the rows at the capacity's stride).
  // (Byte offsets within p's object representation.)
  const char* const w0 = reinterpret_cast<const char*>(p.w1t.data());
  constexpr ptrdiff_t ob = static_cast<ptrdiff_t>(offsetof(P, b1)) - static_cast<ptrdiff_t>(offsetof(P, w1t));
  constexpr ptrdiff_t oo = static_cast<ptrdiff_t>(offsetof(P, w_out)) - static_cast<ptrdiff_t>(offsetof(P, w1t));
  const ptrdiff_t oc = col ? reinterpret_cast<const char*>(col) - w0 : 0;  // (no column: row 0's, finite, unused)
  auto at = [](const char* q, ptrdiff_t off) noexcept { return *reinterpret_cast<const T*>(q + off); };
  constexpr int kU = DN_KERNEL_UNROLL;  // lanes per pass
  static_assert(kU == 1 || kU == 2 || kU == 4 || kU == 8, "DN_KERNEL_UNROLL: 1, 2, 4 or 8");
  DN_UNROLL_(1)
  for (int l = 0; l < 8; l += kU) {  // lanes l .. l + kU - 1, row by row
    T acc[kU], dacc[kU], d2acc[kU];
    for (int u = 0; u < kU; ++u) acc[u] = T(0), dacc[u] = T(0), d2acc[u] = T(0);
    for (const char* r = w0 + l * sizeof(T); r < w0 + n * sizeof(T); r += 8 * sizeof(T)) {
      DN_UNROLL_(kU)
      for (int u = 0; u < kU; ++u) {  // neuron j = (q - w0) / sizeof(T); j >= n: padding, adds +0
        const char* const q = r + u * sizeof(T);
        T z = at(q, ob);
        for (int i = 0; i < ni; ++i) z += at(q, static_cast<ptrdiff_t>(i * stride * sizeof(T))) * xr[i];
        // clamp_tanh_arg(z) with one compare on the common path: |z| <= 9 (or NaN) keeps z
        T x = z;
        if (std::fabs(z) > T(9)) x = z > T(0) ? T(9) : T(-9);
#if defined(__arm__) && defined(__ARM_FP)
        if constexpr (std::is_same<T, float>::value) __asm__("" : "+t"(x));  // one path: no code per branch
#endif
        const T t = tanh_rational(x, k);
        acc[u] += at(q, oo) * t;
        if constexpr (kGrad) {
          // (No test of col here: Mlp and StaticMlp send a clamped x_i to the plain forward;
          // otherwise, e.g. forward_grad4, oc reads row 0 and the sums are dropped.)
          const T c = at(q, oc), wg = at(q, oo) * ((T(1) - t * t) * c);  // w_out dt/dx_i
          dacc[u] += wg;
          // w_out d2t/dx_i^2 = w_out dt/dx_i (-2 t c): the factor -2 once, after the sum (three
          // operations a neuron, which the Cortex-M4F's Halley steps pay for)
          if constexpr (kCurv) d2acc[u] += wg * (t * c);
        }
      }
    }
    for (int u = 0; u < kU; ++u) part[l + u] = acc[u], dpart[l + u] = dacc[u], d2part[l + u] = d2acc[u];
  }
  auto combine = [](const T* q) noexcept {
    return ((q[0] + q[4]) + (q[1] + q[5])) + ((q[2] + q[6]) + (q[3] + q[7]));
  };
  if constexpr (kGrad) *dys = col ? combine(dpart) : T(0);
  if constexpr (kCurv) *d2ys = col ? T(-2) * combine(d2part) : T(0);
  (void)d2ys;
  (void)d2part;
  return p.b_out + combine(part);
}

// Models with one hidden layer (at run time when kH2 is not fixed): the fused pass.
template <typename T>
constexpr OwnPass kOwnPass = OwnPass::one_layer;
template <typename T, int kIn, int kH1, int kH2, bool kGrad, bool kCurv, class P>
inline T forward_own(const P& p, const T* xs, const T* col, T* dys, T* d2ys) noexcept {
  constexpr int kP1 = kH1 > 0 ? pad(kH1) : kDynamic;
  return forward_fused1<T, kIn, kP1, kGrad, kCurv>(p, xs, col, dys, d2ys);  // b_out included
}
// (Declared for mlp.hpp's forward_batch, which calls it only where kSimdFloat.)
template <int kIn, int kH1, bool kGrad, int kB, class P>
void forward_batch_simd(const P& p, const float* const* xs, const float* const* col, float* sums, float* dys) noexcept;

}  // namespace detail
}  // namespace DN_KERNEL_NS
}  // namespace dampnet
