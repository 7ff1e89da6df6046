// What every backend of the MLP kernel shares (kernel/backend.hpp lists them): the padding,
// the input saturation, and the portable forms of the dense layer, the clamp, the padded dot
// product and the range check, which a backend uses as they are or replaces.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <type_traits>

#include "dampnet/activation.hpp"
#include "dampnet/dampnet.h"
#include "dampnet/kernel/backend.hpp"

namespace dampnet {
// Everything here carries the kernel's backend in its mangled names, so that
// translation units compiled for different backends never share a function by accident.
inline namespace DN_KERNEL_NS {

constexpr int kDynamic = -1;

// Hidden layers are stored padded to a multiple of 8 neurons (16 on the AVX-512
// backend) with zero weights, so every loop runs over whole SIMD vectors (no scalar
// tails). A padded neuron has pre-activation 0 and a zero output weight: it adds
// exactly +0 to the sum.
constexpr int kPad = DN_KERNEL_PAD;
constexpr int pad(int n) { return n <= 0 ? 0 : (n + kPad - 1) / kPad * kPad; }

// The backend of the kernel compiled into this translation unit (kernel/backend.hpp):
// "avx512", "avx2+fma", "sse", "scalar" or "eigen".
constexpr const char* kernel_isa() noexcept { return DN_KERNEL_ISA; }

namespace detail {

// Where a backend's own forward pass (forward_own, after the inputs) replaces mlp.hpp's passes.
enum class OwnPass { never, one_layer, always };

inline bool all_finite(const double* p, int n) noexcept {
  for (int i = 0; i < n; ++i)
    if (!std::isfinite(p[i])) return false;
  return true;
}

// The portable forms, under the names mlp.hpp calls: a backend takes them with using-
// declarations (no call of their own in between).
namespace loops {

// y = W^T x for the transposed storage wt[n_in][n_out] (+ bias), n_out outputs (a padded
// layer: a multiple of kPad, which the mask tells the compiler: no remainder loops).
template <typename T, int kIn, int kOut>
inline void dense_t(const T* wt, const T* b, const T* x, T* y, int n_in, int n_out) noexcept {
  const int ni = kIn > 0 ? kIn : n_in;
  const int no = kOut > 0 ? kOut : (n_out & ~(kPad - 1));
  for (int j = 0; j < no; ++j) y[j] = b[j];
  for (int i = 0; i < ni; ++i) {
    const T xi = x[i];
    const T* row = wt + i * no;
    for (int j = 0; j < no; ++j) y[j] += row[j] * xi;
  }
}

// Clamp n floats to the tanh's range (activation.hpp clamp_tanh_arg), one by one.
inline void clamp_tanh_args(float* h, int n) noexcept {
  for (int j = 0; j < n; ++j) h[j] = clamp_tanh_arg(h[j]);
}

// sum_j w[j] a[j] over n (a multiple of 8) in eight interleaved partial sums,
// part[l] = sum_k w[8k+l] a[8k+l], combined as ((p0+p4)+(p1+p5))+((p2+p6)+(p3+p7)):
// the adds pipeline instead of forming one long chain. The SSE version (dense_sse.hpp) keeps
// exactly this order (and its horizontal sum in registers), so both give the same bits.
template <typename T, int kN>
inline T dot_padded(const T* __restrict w, const T* __restrict a, int n) noexcept {
  const int nn = kN > 0 ? kN : n;
  alignas(DN_KERNEL_ALIGN) T part[8] = {};
  for (int j = 0; j < nn; j += 8)
    for (int l = 0; l < 8; ++l) part[l] += w[j + l] * a[j + l];
  return ((part[0] + part[4]) + (part[1] + part[5])) + ((part[2] + part[6]) + (part[3] + part[7]));
}

}  // namespace loops

// double: every backend's clamp.
inline void clamp_tanh_args(double* h, int n) noexcept {
  for (int j = 0; j < n; ++j) h[j] = clamp_tanh_arg(h[j]);
}

// Saturate the inputs and, with kSub, subtract their offsets (the rest of the
// input scaling is folded into layer 1, and the offsets too when load() found that
// safe: see in_offset_folded); returns the warning bits, sets the mask.
// (GCC, inlining a run-time-sized model's forward into a caller whose input array
// is exactly n_in long, cannot see that i < n_in and warns of a read beyond it.)
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
// (Likewise, in Mlp's fully run-time branch, taken for n_in > 4, it reports reads beyond
// a shorter input array of the caller's that that branch never receives.)
#pragma GCC diagnostic ignored "-Warray-bounds"
#endif
template <typename T, int kIn, bool kSub, class P>
inline int prepare_inputs(const P& p, const T* x, T* xs, uint32_t& mask) noexcept {
  const int ni = kIn > 0 ? kIn : p.n_in;
  int status = DN_OK;
  for (int i = 0; i < ni; ++i) {
    T v = x[i];
    const T lo = p.sat_lo[i], hi = p.sat_hi[i];
    if (v != v) {  // NaN: the centre of the training range is the least surprising value
      v = p.in_mid[i];
      status |= DN_W_NONFINITE_INPUT;
      mask |= (1u << i);
    } else if (v < lo) {  // also -Inf
      v = lo;
      status |= DN_W_SATURATED;
      mask |= (1u << i);
    } else if (v > hi) {  // also +Inf
      v = hi;
      status |= DN_W_SATURATED;
      mask |= (1u << i);
    }
    xs[i] = kSub ? v - p.in_offset[i] : v;
  }
  return status;
}

// prepare_inputs with the offsets to subtract given (zeros: none), for DN_KERNEL_SMALL.
template <typename T, int kIn, class P>
inline int prepare_inputs_off(const P& p, const T* x, const T* off, T* xs, uint32_t& mask) noexcept {
  const int ni = kIn > 0 ? kIn : p.n_in;
  int status = DN_OK;
  for (int i = 0; i < ni; ++i) {
    T v = x[i];
    const T lo = p.sat_lo[i], hi = p.sat_hi[i];
    if (v != v) {
      v = p.in_mid[i];
      status |= DN_W_NONFINITE_INPUT;
      mask |= (1u << i);
    } else if (v < lo) {
      v = lo;
      status |= DN_W_SATURATED;
      mask |= (1u << i);
    } else if (v > hi) {
      v = hi;
      status |= DN_W_SATURATED;
      mask |= (1u << i);
    }
    xs[i] = v - off[i];
  }
  return status;
}

// True when every input lies within its saturation range (false for NaN): then,
// with the offsets folded, the kernel reads the caller's inputs directly and the
// values reach layer 1 without passing through the saturation's min/max (compares
// and one predicted branch beside the data chain, not on it). Two portable forms:
// scalar cores: a compare and a branch each (fewer instructions than combining the flags);
namespace range_branch {
template <typename T, int kIn, class P>
inline bool inputs_in_range(const P& p, const T* x) noexcept {
  const int ni = kIn > 0 ? kIn : p.n_in;
  for (int i = 0; i < ni; ++i)
    if (!(x[i] >= p.sat_lo[i] && x[i] <= p.sat_hi[i])) return false;
  return true;
}
}  // namespace range_branch
// cores with SIMD registers: the flags combined, one branch.
namespace range_all {
template <typename T, int kIn, class P>
inline bool inputs_in_range(const P& p, const T* x) noexcept {
  const int ni = kIn > 0 ? kIn : p.n_in;
  bool ok = true;
  for (int i = 0; i < ni; ++i) ok &= (x[i] >= p.sat_lo[i]) & (x[i] <= p.sat_hi[i]);
  return ok;
}
}  // namespace range_all
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

}  // namespace detail
}  // namespace DN_KERNEL_NS
}  // namespace dampnet
