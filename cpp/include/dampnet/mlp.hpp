// The MLP inference kernel: one forward pass, two ways to hold a model.
//
//   Mlp<T>                       sizes chosen at run time (from Python or the C ABI),
//                                storage of fixed maximum capacity, no heap.
//   StaticMlp<T, In, H1, H2>     sizes as compile-time constants (from a generated
//                                header), storage of exactly the needed size.
//
// Both are filled from a dn_mlp_desc by load() and evaluated by the same
// detail::forward template, so the same weights give the same result on both
// paths. Internally the weights are stored transposed ([in][out]) so that the
// inner loop runs over neurons, contiguous and vectorisable.
//
// load() folds the affine maps into the weights (in double, then rounded to T):
// the input scaling ((x - offset) * gain + ymin) into layer 1 (the offsets too,
// unless an input's offset exceeds its range), the sigmoid as 0.5 + 0.5 tanh(z / 2)
// into the layers around it, and the output unscaling ((y - ymin) / gain + offset)
// into the output weights, so that forward() is the input saturation, dense + tanh
// per layer, then one dot product plus a constant: the shortest dependency chain,
// which is what bounds a single call's latency. load_folded() takes those folded parameters
// already rounded to float (dn_mlp_folded_f, written by the exporter) and only checks and
// copies them: a float-only target's set-up without double arithmetic.
//
// The backend (dense layers and whatever else is done per instruction set) is one file of
// kernel/, chosen in kernel/backend.hpp from DN_KERNEL_BACKEND (the build's option; kernel_isa()
// says which one a translation unit got): scalar (plain loops; one hidden layer in one fused
// pass), sse (x86's default), avx2 (per 8 neurons in __m256 registers, CMake DAMPNET_AVX2),
// avx512 (per 16 in __m512, DAMPNET_AVX512) or eigen (the dense layers through Eigen,
// DAMPNET_USE_EIGEN). The SIMD backends' last hidden layer uses the 15/4 rational tanh with each
// output weight folded into its numerator (activation.hpp, kernel/simd_x86.hpp tanh_folded),
// the other backends and layers 13/6 rationals (AVX2: 15/4 as well); every backend's tanh is
// within 5e-7 of std::tanh, so the backends' results differ by rounding and by that. Inputs
// inside their saturation range are read in place (no copy, no min/max on the chain) when the
// offsets are folded.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <type_traits>

#include "dampnet/activation.hpp"
#include "dampnet/dampnet.h"
#include "dampnet/kernel/backend.hpp"
#include "dampnet/kernel/common.hpp"
#include DN_KERNEL_HEADER  // the chosen backend (kernel/backend.hpp)

namespace dampnet {
inline namespace DN_KERNEL_NS {

namespace detail {

// tanh of the hidden pre-activations in two passes (clamp, rational): with IEEE
// trapping semantics GCC will not vectorise a loop that both branches and divides.
// h is 32-byte aligned and n a multiple of 8 (padded layers).
template <typename T, int kN>
inline void tanh_all(T* h, int n) noexcept {
  const int nn = kN > 0 ? kN : (n & ~(kPad - 1));  // (the mask: the compiler knows it, no remainder loop)
  clamp_tanh_args(h, nn);
  for (int j = 0; j < nn; ++j) h[j] = tanh_rational(h[j]);
}

// prepare_inputs out of forward_batch's line (DN_KERNEL_OUTLINE): it calls it only when an
// input is out of its range or the offsets could not be folded (load()); one copy per input
// count and variant instead of one per sample. (forward() keeps its own inline: outlined, its
// common path pays for the buffer the call needs, +3 ns of a 30 ns float forward.)
template <typename T, int kIn, bool kSub, class P>
DN_KERNEL_OUTLINE inline int prepare_inputs_outline(const P& p, const T* x, T* xs, uint32_t& mask) noexcept {
  return prepare_inputs<T, kIn, kSub>(p, x, xs, mask);
}

// (GCC's -Wmaybe-uninitialized cannot see that the second layer's t2 is read only where it was
// written, h2 > 0: a false alarm at -O2 in some instantiations, which -Werror builds refuse.)
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
// The forward pass shared by Mlp and StaticMlp. kH2 == 0: one hidden layer.
// Sizes used here are the padded ones (pad()). With kGrad, *dy_dxi also receives
// dy/dx[grad_input] (output units per input unit) by forward-mode differentiation;
// it is 0 when that input was clamped (the saturated model does not depend on it).
// With kCurv (and kGrad) dy_dxi points to two: dy_dxi[1] also receives d2y/dx[grad_input]^2
// for one hidden layer (NaN for two: not computed), 0 when clamped; y and dy/dx are the same
// bits as without it. (One pointer for both: no seventh argument, which x86-64 would pass on
// the stack at every call site of the slope-only forward too.)
template <typename T, int kIn, int kH1, int kH2, class P, bool kGrad = false, bool kCurv = false>
DN_KERNEL_OUTLINE DN_REALTIME inline int forward(const P& p, const T* x, T* y, uint32_t* clamped_mask,
                               int grad_input = 0, T* dy_dxi = nullptr) noexcept {
  static_assert(kGrad || !kCurv, "the curvature comes with the slope");
  constexpr int kP1 = kH1 > 0 ? pad(kH1) : kDynamic;
  constexpr int kP2 = kH2 > 0 ? pad(kH2) : (kH2 == 0 ? 0 : kDynamic);
  // Stack arrays of the model's capacity (P's), or of its compile-time sizes.
  constexpr int cap_in = kIn > 0 ? kIn : P::kCapIn;
  constexpr int cap_h1 = kH1 > 0 ? kP1 : P::P1;
  constexpr int cap_h2 = kH2 > 0 ? kP2 : P::P2;
  const int h1 = kP1 > 0 ? kP1 : p.n_h1p;
  const int h2 = kP2 >= 0 ? kP2 : p.n_h2p;

  uint32_t mask = 0;
  // zeroed: GCC cannot see that prepare_inputs writes all it reads (the scalar backend: no
  // vector alignment, which would cost a realigned stack frame)
  alignas(kFused1 ? alignof(T) : DN_KERNEL_ALIGN) T xs_buf[cap_in] = {};
  // Layer 1's input: the caller's x itself when no input needs saturating and the
  // offsets are folded (the common case; the same values prepare_inputs would copy).
  const T* xs = x;
  int status = DN_OK;
  if constexpr (DN_KERNEL_SMALL != 0) {
    // One copy of the saturation code (flash): the offsets subtracted, or zeros when they are
    // folded (v - 0 is v, -0 included: the same values as prepare_inputs<..., false>).
    if (!p.in_offset_folded || !inputs_in_range<T, kIn>(p, x)) {
      static constexpr T kZeros[cap_in] = {};
      status = prepare_inputs_off<T, kIn>(p, x, p.in_offset_folded ? kZeros : p.in_offset.data(), xs_buf, mask);
      xs = xs_buf;
    }
  } else {
    if (!p.in_offset_folded) {
      status = prepare_inputs<T, kIn, true>(p, x, xs_buf, mask);
      xs = xs_buf;
    } else if (!inputs_in_range<T, kIn>(p, x)) {
      status = prepare_inputs<T, kIn, false>(p, x, xs_buf, mask);
      xs = xs_buf;
    }
  }
  // Layer 1's column for the differentiated input (its gain folded in); none if clamped.
  const T* col = (kGrad && !((mask >> grad_input) & 1u)) ? p.w1t.data() + grad_input * h1 : nullptr;

  // The backend's own pass where it has one for this model (b_out included), else the
  // passes below: dense + tanh per layer, then the output's dot product.
  T sum, dys = T(0), d2ys = T(0);
  if constexpr (kOwnPass<T> == OwnPass::always) {
    sum = forward_own<T, kIn, kH1, kH2, kGrad, kCurv>(p, xs, col, &dys, &d2ys);
  } else if (kOwnPass<T> == OwnPass::one_layer && (kH2 == 0 || h2 == 0)) {
    sum = forward_own<T, kIn, kH1, kH2, kGrad, kCurv>(p, xs, col, &dys, &d2ys);
  } else {
    alignas(DN_KERNEL_ALIGN) T a1[cap_h1];
    dense_t<T, kIn, kP1>(p.w1t.data(), p.b1.data(), xs, a1, p.n_in, h1);
    tanh_all<T, kP1>(a1, h1);

    // Forward mode: t1 = d(a1)/dx_i = (1 - a1^2) * W1[:, i] (gain and sigmoid scale folded in).
    alignas(DN_KERNEL_ALIGN) T t1[kGrad ? cap_h1 : kPad] = {};
    if constexpr (kGrad) {
      if (col) {  // h1 a multiple of kPad: blocks of kPad (no remainder loop), not peeled
#pragma GCC unroll 1
        for (int j0 = 0; j0 < h1; j0 += kPad)
          for (int j = j0; j < j0 + kPad; ++j) t1[j] = (T(1) - a1[j] * a1[j]) * col[j];
      }
    }

    int n_last = h1;
    bool n_last_is_a2 = false;
    alignas(DN_KERNEL_ALIGN) T a2[cap_h2 > 0 ? cap_h2 : kPad];
    alignas(DN_KERNEL_ALIGN) T t2[kGrad && cap_h2 > 0 ? cap_h2 : kPad];
    if constexpr (kH2 != 0) {  // compiled out for one hidden layer
      if (h2 > 0) {
        dense_t<T, kP1, kP2>(p.w2t.data(), p.b2.data(), a1, a2, h1, h2);
        tanh_all<T, kP2>(a2, h2);
        if constexpr (kGrad) {
          alignas(DN_KERNEL_ALIGN) T zero[cap_h2 > 0 ? cap_h2 : kPad] = {};
          alignas(DN_KERNEL_ALIGN) T lin[cap_h2 > 0 ? cap_h2 : kPad];
          dense_t<T, kP1, kP2>(p.w2t.data(), zero, t1, lin, h1, h2);  // W2 t1
          for (int j = 0; j < h2; ++j) t2[j] = (T(1) - a2[j] * a2[j]) * lin[j];
        }
        n_last = h2;
        n_last_is_a2 = true;
      }
    }
    if constexpr (kGrad) {
      dys = n_last_is_a2 ? dot_padded<T, kP2>(p.w_out.data(), t2, n_last)
                         : dot_padded<T, kP1>(p.w_out.data(), t1, n_last);
    }
    if constexpr (kCurv) {  // one layer: sum_j w_j (-2 t_j (1 - t_j^2)) col_j^2
      if (n_last_is_a2) {
        d2ys = std::numeric_limits<T>::quiet_NaN();
      } else if (col) {
        for (int j = 0; j < h1; ++j) d2ys += p.w_out[j] * (T(-2) * a1[j] * (T(1) - a1[j] * a1[j]) * (col[j] * col[j]));
      }
    }
    sum = p.b_out + (n_last_is_a2 ? dot_padded<T, kP2>(p.w_out.data(), a2, n_last)
                                  : dot_padded<T, kP1>(p.w_out.data(), a1, n_last));
  }
  if constexpr (kGrad) *dy_dxi = dys;
  if constexpr (kCurv) dy_dxi[1] = d2ys;

  T out = sum;  // the output unscaling is folded into w_out and b_out
  if (!std::isfinite(out)) {
    out = p.out_offset;
    status = DN_E_NONFINITE_OUTPUT;
  }
  *y = out;
  if (clamped_mask) *clamped_mask = mask;
  return status;
}

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

// forward() of kB samples (x[b], y[b], clamped_mask[b], dy_dxi[b]; masks and dy_dxi
// nullable), each result identical to its own forward() call: float models with one hidden
// layer on the SIMD backends go through forward_batch_simd (forward_simd_batch: the weights
// loaded once per block for all samples); the others are kB forward() calls. Returns the samples' statuses in status[b].
template <typename T, int kIn, int kH1, class P, bool kGrad, int kB>
DN_KERNEL_OUTLINE DN_REALTIME inline void forward_batch(const P& p, const T* const* x, T* y, uint32_t* clamped_mask,
                                      int grad_input, T* dy_dxi, int* status) noexcept {
  if constexpr (kSimdFloat && std::is_same<T, float>::value) {
    if (p.n_h2p == 0) {
      constexpr int cap_in = kIn > 0 ? kIn : P::kCapIn;
      constexpr int kP1 = kH1 > 0 ? pad(kH1) : kDynamic;
      const int h1 = kP1 > 0 ? kP1 : p.n_h1p;
      alignas(DN_KERNEL_ALIGN) T xs_buf[kB][cap_in] = {};
      const T* xs[kB];
      const T* col[kB];
      uint32_t mask[kB];
#pragma GCC unroll 1
      for (int b = 0; b < kB; ++b) {  // forward()'s input handling, per sample (rolled: one copy)
        mask[b] = 0;
        xs[b] = x[b];
        status[b] = DN_OK;
        if (!p.in_offset_folded) {
          status[b] = prepare_inputs_outline<T, kIn, true>(p, x[b], xs_buf[b], mask[b]);
          xs[b] = xs_buf[b];
        } else if (!inputs_in_range<T, kIn>(p, x[b])) {
          status[b] = prepare_inputs_outline<T, kIn, false>(p, x[b], xs_buf[b], mask[b]);
          xs[b] = xs_buf[b];
        }
        col[b] = (kGrad && !((mask[b] >> grad_input) & 1u)) ? p.w1t.data() + grad_input * h1 : nullptr;
      }
      T sums[kB], dys[kB] = {};
      forward_batch_simd<kIn, kH1, kGrad, kB>(p, xs, col, sums, dys);
#pragma GCC unroll 1
      for (int b = 0; b < kB; ++b) {
        T out = sums[b];
        if (!std::isfinite(out)) {
          out = p.out_offset;
          status[b] = DN_E_NONFINITE_OUTPUT;
        }
        y[b] = out;
        if (clamped_mask) clamped_mask[b] = mask[b];
        if constexpr (kGrad) dy_dxi[b] = dys[b];
      }
      return;
    }
  }
  for (int b = 0; b < kB; ++b)
    status[b] = forward<T, kIn, kH1, kDynamic, P, kGrad>(p, x[b], &y[b], clamped_mask ? &clamped_mask[b] : nullptr,
                                                         grad_input, kGrad ? &dy_dxi[b] : nullptr);
}

// A flash-lean build (DN_KERNEL_SMALL) on a scalar core compiles the one-hidden-layer forward
// for exactly its capacity's input count (Mlp::dispatch): set-up refuses another (DN_E_SIZE).
template <class P>
constexpr bool small_refuses(int n_in) noexcept {
  return DN_KERNEL_SMALL != 0 && kFused1 && P::kCapH2 == 0 && n_in != P::kCapIn;
}

// The stride of w1t's rows (and the padded length of b1 and w_out): pad(h1), or on scalar
// targets for one hidden layer the capacity's P::P1, so that forward_fused1 finds every
// input's weight of a neuron at a fixed offset from one pointer.
template <class P>
constexpr int layer1_stride(int h1, int h2) noexcept {
  if (kFused1 && h2 == 0) return P::P1;
  return pad(h1);
}

// The real and padded sizes of a validated description (the loops run over the padded ones).
template <class P>
inline void set_shape(P& p, int ni, int h1, int h2) noexcept {
  p.n_in = ni;
  p.n_h1 = h1;
  p.n_h2 = h2;
  p.n_h1p = layer1_stride<P>(h1, h2);
  p.n_h2p = pad(h2);
}

// A description's sizes (inputs, hidden 1, hidden 2) against the library's limits, fixed sizes
// (kDynamic = any) and this object's capacity: DN_OK, DN_E_SIZE or DN_E_MISMATCH.
template <int kIn, int kH1, int kH2, class P>
inline int check_sizes(int ni, int h1, int h2) noexcept {
  if (ni < 1 || ni > DN_MAX_INPUTS || h1 < 1 || h1 > DN_MAX_HIDDEN || h2 < 0 || h2 > DN_MAX_HIDDEN2)
    return DN_E_SIZE;
  // a network with two hidden layers keeps both within DN_MAX_HIDDEN2 (its [H2][H1] weights stay
  // small in a build that raises DN_MAX_HIDDEN for one wide layer: an averaged network)
  if (h2 > 0 && h1 > DN_MAX_HIDDEN2) return DN_E_SIZE;
  if ((kIn > 0 && ni != kIn) || (kH1 > 0 && h1 != kH1) || (kH2 >= 0 && h2 != kH2)) return DN_E_MISMATCH;
  // beyond this object's capacity (a build with lowered DN_CAP_*: dampnet.h)
  if (ni > P::kCapIn || h1 > P::kCapH1 || h2 > P::kCapH2 || (h2 > 0 && pad(h1) > P::P1T)) return DN_E_SIZE;
  if (small_refuses<P>(ni)) return DN_E_SIZE;
  return DN_OK;
}

// Validate a description against fixed sizes (kDynamic = any) and copy it in,
// folding the scalings into the weights (see the top of this file).
template <typename T, int kIn, int kH1, int kH2, class P>
inline int load(P& p, const dn_mlp_desc* d) noexcept {
  if (!d || !d->w1 || !d->b1 || !d->w_out || !d->b_out || !d->in_offset || !d->in_gain ||
      !d->sat_lo || !d->sat_hi)
    return DN_E_NULL;
  const int size_status = check_sizes<kIn, kH1, kH2, P>(d->n_inputs, d->n_hidden1, d->n_hidden2);
  if (size_status != DN_OK) return size_status;
  if (d->n_hidden2 > 0 && (!d->w2 || !d->b2)) return DN_E_NULL;
  if (d->activation != DN_ACT_TANH && d->activation != DN_ACT_SIGMOID) return DN_E_ACTIVATION;
  const int ni = d->n_inputs, h1 = d->n_hidden1, h2 = d->n_hidden2;
  const int n_last = h2 > 0 ? h2 : h1;
  if (!all_finite(d->w1, h1 * ni) || !all_finite(d->b1, h1) ||
      !all_finite(d->w_out, n_last) || !all_finite(d->b_out, 1) ||
      !all_finite(d->in_offset, ni) || !all_finite(d->in_gain, ni) ||
      !all_finite(d->sat_lo, ni) || !all_finite(d->sat_hi, ni) ||
      !std::isfinite(d->in_ymin) || !std::isfinite(d->out_offset) ||
      !std::isfinite(d->out_gain) || !std::isfinite(d->out_ymin))
    return DN_E_NONFINITE_PARAM;
  if (h2 > 0 && (!all_finite(d->w2, h2 * h1) || !all_finite(d->b2, h2)))
    return DN_E_NONFINITE_PARAM;
  if (d->out_gain == 0.0) return DN_E_PARAM;
  for (int i = 0; i < ni; ++i)
    if (!(d->sat_lo[i] <= d->sat_hi[i])) return DN_E_PARAM;

  set_shape(p, ni, h1, h2);
  const int h1p = p.n_h1p, h2p = p.n_h2p;
  p.act = static_cast<Activation>(d->activation);
  // Zero everything first: the padding must hold zeros even when a model is reloaded.
  p.w1t.fill(T(0));
  p.b1.fill(T(0));
  p.w2t.fill(T(0));
  p.b2.fill(T(0));
  p.w_out.fill(T(0));
  // Every hidden unit is evaluated as t = tanh(z'); its value is a = beta + alpha t:
  // tanh: z' = z, a = t; sigmoid: z' = z / 2, a = 1/2 + t / 2 (sigmoid(z) = 0.5 + 0.5 tanh(z/2)).
  const bool sig = p.act == Activation::sigmoid;
  const double zs = sig ? 0.5 : 1.0, alpha = sig ? 0.5 : 1.0, beta = sig ? 0.5 : 0.0;
  // Layer 1 on x - offset: z'_j = zs (sum_i W1[j,i] gain_i (x_i - off_i) + b1_j + ymin sum_i W1[j,i]).
  // The offsets go into the bias as well (layer 1 on x itself, one subtraction less on
  // the call's dependency chain) when no input's offset exceeds its saturation range:
  // then |x_i| <= 2 x range_i and W1 x loses at most a bit to cancellation; an input
  // far from zero (a temperature in kelvin, say) keeps the exact subtraction.
  bool fold_off = true;
  for (int i = 0; i < ni; ++i)
    if (!(std::fabs(d->in_offset[i]) <= d->sat_hi[i] - d->sat_lo[i])) fold_off = false;
  p.in_offset_folded = fold_off;
  for (int j = 0; j < h1; ++j) {
    double b = d->b1[j];
    for (int i = 0; i < ni; ++i) {
      const double w = d->w1[j * ni + i] * d->in_gain[i];
      p.w1t[i * h1p + j] = static_cast<T>(zs * w);
      b += d->in_ymin * d->w1[j * ni + i];
      if (fold_off) b -= w * d->in_offset[i];
    }
    p.b1[j] = static_cast<T>(zs * b);
  }
  // Layer 2 on layer 1's t: z'_k = zs (sum_j alpha W2[k,j] t_j + b2_k + beta sum_j W2[k,j]).
  for (int k = 0; k < h2; ++k) {
    double b = d->b2[k];
    for (int j = 0; j < h1; ++j) {
      p.w2t[j * h2p + k] = static_cast<T>(zs * alpha * d->w2[k * h1 + j]);
      b += beta * d->w2[k * h1 + j];
    }
    p.b2[k] = static_cast<T>(zs * b);
  }
  // Output: ((sum_j w_j a_j + b_out) - ymin) / gain + offset = sum_j w'_j t_j + b'.
  double c = d->b_out[0];
  for (int j = 0; j < n_last; ++j) {
    p.w_out[j] = static_cast<T>(alpha * d->w_out[j] / d->out_gain);
    c += beta * d->w_out[j];
  }
  p.b_out = static_cast<T>((c - d->out_ymin) / d->out_gain + d->out_offset);
  if constexpr (P::kTw > 0) {
    p.tw.fill(T(0));
    p.inv_w.fill(T(0));
    for (int j = 0; j < n_last; ++j) {
      const double w = alpha * d->w_out[j] / d->out_gain;
      for (int k = 0; k < kTanhPTerms; ++k) p.tw[k * P::kTw + j] = static_cast<T>(kTanhP[k] * w);
      const double iw = 1.0 / w;
      if (std::fabs(iw) < 1e30) p.inv_w[j] = static_cast<T>(iw);
    }
  }
  for (int i = 0; i < ni; ++i) {
    p.in_offset[i] = static_cast<T>(d->in_offset[i]);
    p.sat_lo[i] = static_cast<T>(d->sat_lo[i]);
    p.sat_hi[i] = static_cast<T>(d->sat_hi[i]);
    p.in_mid[i] = static_cast<T>(0.5 * (d->sat_lo[i] + d->sat_hi[i]));
  }
  p.out_offset = static_cast<T>(d->out_offset);
  if constexpr (P::kR8 > 0) {
    for (int i = 0; i < P::kR8; ++i) {
      p.sat_lo8[i] = i < ni ? p.sat_lo[i] : -HUGE_VALF;
      p.sat_hi8[i] = i < ni ? p.sat_hi[i] : HUGE_VALF;
      p.in_mask8[i] = i < ni ? -1 : 0;
    }
  }
  // The folded parameters in T: a scaling that overflows T (float: |x| > 3.4e38, e.g. an
  // out_offset of 1e39 or an out_gain of 1e-40) would make every output non-finite and
  // its replacement, out_offset, too. Refused here instead of failing at every call.
  auto finite_all = [](const auto& a) noexcept {
    for (const auto& x : a)
      if (!std::isfinite(x)) return false;
    return true;
  };
  if (!finite_all(p.w1t) || !finite_all(p.b1) || !finite_all(p.w2t) || !finite_all(p.b2) ||
      !finite_all(p.w_out) || !std::isfinite(p.b_out) || !std::isfinite(p.out_offset) ||
      !finite_all(p.in_offset) || !finite_all(p.sat_lo) || !finite_all(p.sat_hi) ||
      !finite_all(p.in_mid))
    return DN_E_PARAM;
  if constexpr (P::kTw > 0) {
    if (!finite_all(p.tw)) return DN_E_PARAM;
  }
  return DN_OK;
}

inline bool all_finite_f(const float* a, int n) noexcept {
  for (int i = 0; i < n; ++i)
    if (!std::isfinite(a[i])) return false;
  return true;
}

template <class A>
inline void zero_all(A& a) noexcept {
  for (auto& v : a) v = {};
}

// (Set-up code of a flash-lean build is optimised for size: DN_SETUP_SIZE, kernel/backend.hpp.)
// Validate a folded float description (dn_mlp_folded_f: what load() above makes of a
// dn_mlp_desc, already rounded to float) and copy it in: float comparisons and copies only
// (for T = float no double arithmetic at all), so that a float-only target's set-up links no
// software double routine. For T = float the parameters are load()'s bit for bit when the
// description holds load()'s values (the exporter writes them; tests compare), except the SIMD
// kernels' tw / inv_w, made here from the float w_out (load(): from the double one).
template <typename T, int kIn, int kH1, int kH2, class P>
DN_SETUP_SIZE inline int load_folded(P& p, const dn_mlp_folded_f* f) noexcept {
  if (!f || !f->w1 || !f->b1 || !f->w_out || !f->in_offset || !f->sat_lo || !f->sat_hi || !f->sat_mid)
    return DN_E_NULL;
  const int size_status = check_sizes<kIn, kH1, kH2, P>(f->n_inputs, f->n_hidden1, f->n_hidden2);
  if (size_status != DN_OK) return size_status;
  if (f->n_hidden2 > 0 && (!f->w2 || !f->b2)) return DN_E_NULL;
  const int ni = f->n_inputs, h1 = f->n_hidden1, h2 = f->n_hidden2;
  const int n_last = h2 > 0 ? h2 : h1;
  if (!all_finite_f(f->w1, h1 * ni) || !all_finite_f(f->b1, h1) || !all_finite_f(f->w_out, n_last) ||
      !std::isfinite(f->b_out) || !std::isfinite(f->out_offset) || !all_finite_f(f->in_offset, ni) ||
      !all_finite_f(f->sat_lo, ni) || !all_finite_f(f->sat_hi, ni) || !all_finite_f(f->sat_mid, ni))
    return DN_E_NONFINITE_PARAM;
  if (h2 > 0 && (!all_finite_f(f->w2, h2 * h1) || !all_finite_f(f->b2, h2))) return DN_E_NONFINITE_PARAM;
  if (f->offsets_folded != 0 && f->offsets_folded != 1) return DN_E_PARAM;
  for (int i = 0; i < ni; ++i)
    if (!(f->sat_lo[i] <= f->sat_mid[i] && f->sat_mid[i] <= f->sat_hi[i])) return DN_E_PARAM;

  set_shape(p, ni, h1, h2);
  const int h1p = p.n_h1p, h2p = p.n_h2p;
  p.act = Activation::tanh;  // a sigmoid's halvings are in the weights
  p.in_offset_folded = f->offsets_folded == 1;
  // Zero everything first: the padding must hold zeros even when a model is reloaded.
  zero_all(p.w1t);  // (not std::array::fill: a size-optimised build outlines that as a std:: symbol)
  zero_all(p.b1);
  zero_all(p.w2t);
  zero_all(p.b2);
  zero_all(p.w_out);
  for (int j = 0; j < h1; ++j) {
    for (int i = 0; i < ni; ++i) p.w1t[i * h1p + j] = static_cast<T>(f->w1[j * ni + i]);
    p.b1[j] = static_cast<T>(f->b1[j]);
  }
  for (int k = 0; k < h2; ++k) {
    for (int j = 0; j < h1; ++j) p.w2t[j * h2p + k] = static_cast<T>(f->w2[k * h1 + j]);
    p.b2[k] = static_cast<T>(f->b2[k]);
  }
  for (int j = 0; j < n_last; ++j) p.w_out[j] = static_cast<T>(f->w_out[j]);
  p.b_out = static_cast<T>(f->b_out);
  p.out_offset = static_cast<T>(f->out_offset);
  for (int i = 0; i < ni; ++i) {
    p.in_offset[i] = static_cast<T>(f->in_offset[i]);
    p.sat_lo[i] = static_cast<T>(f->sat_lo[i]);
    p.sat_hi[i] = static_cast<T>(f->sat_hi[i]);
    p.in_mid[i] = static_cast<T>(f->sat_mid[i]);
  }
  if constexpr (P::kTw > 0) {  // the AVX2 / AVX-512 kernels (host builds) only
    zero_all(p.tw);
    zero_all(p.inv_w);
    for (int j = 0; j < n_last; ++j) {
      const double w = static_cast<double>(f->w_out[j]);
      for (int k = 0; k < kTanhPTerms; ++k) p.tw[k * P::kTw + j] = static_cast<T>(kTanhP[k] * w);
      const double iw = 1.0 / w;
      if (std::fabs(iw) < 1e30) p.inv_w[j] = static_cast<T>(iw);
    }
    for (const auto& x : p.tw)
      if (!std::isfinite(x)) return DN_E_PARAM;
  }
  if constexpr (P::kR8 > 0) {
    for (int i = 0; i < P::kR8; ++i) {
      p.sat_lo8[i] = i < ni ? p.sat_lo[i] : -HUGE_VALF;
      p.sat_hi8[i] = i < ni ? p.sat_hi[i] : HUGE_VALF;
      p.in_mask8[i] = i < ni ? -1 : 0;
    }
  }
  return DN_OK;
}

// A float widened to double exactly. On a core whose FPU has no double precision (Cortex-M4F)
// in integer arithmetic: a cast would link libgcc's software __aeabi_f2d.
inline double widen_exact(float f) noexcept {
#if defined(__arm__) && !(defined(__ARM_FP) && (__ARM_FP & 8))
  uint32_t u;
  std::memcpy(&u, &f, sizeof u);
  const int e = static_cast<int>((u >> 23) & 0xffu);  // float's biased exponent
  uint32_t m = u & 0x7fffffu;
  int ed;  // double's: 1023 - 127 = 896 more
  if (e == 0xff) {
    ed = 0x7ff;  // infinities and NaNs
  } else if (e != 0) {
    ed = e + 896;
  } else if (m == 0u) {
    ed = 0;  // +-0
  } else {  // subnormal, m 2^-149: normalised by s places
    const int s = __builtin_clz(m) - 8;
    m = (m << s) & 0x7fffffu;
    ed = 897 - s;
  }
  const uint64_t d = (static_cast<uint64_t>(u >> 31) << 63) | (static_cast<uint64_t>(ed) << 52) |
                     (static_cast<uint64_t>(m) << 29);
  double r;
  std::memcpy(&r, &d, sizeof r);
  return r;
#else
  return static_cast<double>(f);
#endif
}

}  // namespace detail

// Parameters of an MLP with capacities In x H1 x H2 (storage only; see load(),
// which folds the input/output scalings and the sigmoid into the weights).
template <typename T, int In, int H1, int H2>
struct MlpParams {
  static_assert(In >= 1 && In <= DN_MAX_INPUTS, "1..8 inputs");
  static_assert(H1 >= 1 && H1 <= DN_MAX_HIDDEN, "1..DN_MAX_HIDDEN neurons in hidden layer 1");
  static_assert(H2 >= 0 && H2 <= DN_MAX_HIDDEN2, "0..DN_MAX_HIDDEN2 neurons in hidden layer 2");
  static constexpr int P1 = pad(H1), P2 = pad(H2);
  // The last hidden layer's capacity: layer 2's, or layer 1's for a one-layer model, which a
  // build with both layers also loads (layer 1 may be the wider: DN_MAX_HIDDEN > DN_MAX_HIDDEN2).
  static constexpr int PL = P1 > P2 ? P1 : P2;
  // Layer 1's capacity when there is a layer 2 (both within DN_MAX_HIDDEN2: check_sizes).
  static constexpr int P1T = H2 > 0 ? (H1 < DN_MAX_HIDDEN2 ? P1 : pad(DN_MAX_HIDDEN2)) : 0;
  static constexpr int kCapIn = In, kCapH1 = H1, kCapH2 = H2;
  int n_in = 0, n_h1 = 0, n_h2 = 0;  // real sizes
  int n_h1p = 0, n_h2p = 0;          // padded sizes the loops run over
  Activation act = Activation::tanh;
  alignas(DN_KERNEL_ALIGN) std::array<T, In * P1> w1t{};  // [in][h1 padded], input gain folded in
  alignas(DN_KERNEL_ALIGN) std::array<T, P1> b1{};
  alignas(DN_KERNEL_ALIGN) std::array<T, P1T * P2> w2t{};  // [h1 padded][h2 padded]
  alignas(DN_KERNEL_ALIGN) std::array<T, P2> b2{};
  alignas(DN_KERNEL_ALIGN) std::array<T, PL> w_out{};  // output unscaling folded in
  // float only: the last hidden layer's tanh numerator with the output weight folded in,
  // tw[k * kTw + j] = kTanhP[k] w_out[j] (activation.hpp), and 1 / w_out[j] (0 where
  // w_out[j] is 0 or its reciprocal would not be finite), for the SIMD backends.
  // (Not stored for the other kernels, which never read them.)
  static constexpr int kTw = detail::kSimdFloat && std::is_same<T, float>::value ? PL : 0;
  alignas(DN_KERNEL_ALIGN) std::array<T, kTanhPTerms * kTw> tw{};
  alignas(DN_KERNEL_ALIGN) std::array<T, kTw> inv_w{};
  T b_out{};  // the output for all-zero hidden units, in output units
  std::array<T, In> in_offset{}, in_mid{}, sat_lo{}, sat_hi{};
  // float only: sat_lo / sat_hi padded to 8 with -inf / +inf, and -1 for each input (0
  // beyond), for the SIMD kernels' range check (inputs_in_range).
  static constexpr int kR8 = detail::kSimdFloat && std::is_same<T, float>::value ? 8 : 0;
  alignas(32) std::array<T, kR8> sat_lo8{}, sat_hi8{};
  alignas(32) std::array<int32_t, kR8> in_mask8{};
  bool in_offset_folded = false;  // layer 1's bias holds -W1 offset (forward skips x - offset)
  T out_offset{};  // what a non-finite output is replaced by
};

namespace detail {
// The scalar backend's fused pass does not test at each neuron whether x[i] is clamped (30
// branches a call on a Cortex-M4F; forward's col): Mlp and StaticMlp send a clamped or NaN x[i],
// whose slope is 0, to the plain forward, before any frame of the kernel (prepare_inputs' test:
// the same y, status and mask). False on the other backends.
template <typename T, class P>
inline bool clamped_on_scalar(const P& p, const T* x, int i) noexcept {
  return kFused1 && !(x[i] >= p.sat_lo[i] && x[i] <= p.sat_hi[i]);
}
}  // namespace detail

// A model whose sizes are chosen at run time (up to the DN_MAX_* capacities).
template <typename T>
class Mlp {
 public:
  // Validate and copy a description; returns DN_OK or a DN_E_* error.
  int load(const dn_mlp_desc* d) noexcept {
    return detail::load<T, kDynamic, kDynamic, kDynamic>(p_, d);
  }
  // Validate and copy a folded float description (dn_mlp_folded_f; no double arithmetic for T = float).
  int load_folded(const dn_mlp_folded_f* f) noexcept {
    return detail::load_folded<T, kDynamic, kDynamic, kDynamic>(p_, f);
  }
  // [RT] One sample; see dn_mlp_forward for the input policy.
  DN_REALTIME int forward(const T* x, T* y, uint32_t* clamped_mask = nullptr) const noexcept {
    return dispatch<false>(x, y, clamped_mask, 0, nullptr);
  }
  // [RT] As forward, plus dy/dx[i] (see detail::forward) in *dy_dxi.
  // An input index out of range gives dy/dx = 0.
  DN_REALTIME int forward_grad(const T* x, T* y, int i, T* dy_dxi,
                               uint32_t* clamped_mask = nullptr) const noexcept {
    if (i < 0 || i >= p_.n_in || detail::clamped_on_scalar(p_, x, i)) {
      *dy_dxi = T(0);
      return forward(x, y, clamped_mask);
    }
    return dispatch<true>(x, y, clamped_mask, i, dy_dxi);
  }
  // [RT] As forward_grad, plus d2y/dx[i]^2 in *d2y_dxi2 (one hidden layer; NaN for two, 0
  // when x[i] is clamped). y and dy/dx[i] are forward_grad's bits.
  DN_REALTIME int forward_grad_curv(const T* x, T* y, int i, T* dy_dxi, T* d2y_dxi2,
                                    uint32_t* clamped_mask = nullptr) const noexcept {
    if (i < 0 || i >= p_.n_in || detail::clamped_on_scalar(p_, x, i)) {
      *dy_dxi = T(0);
      // (clamped: 0 as the kernel gives it, NaN for two hidden layers, which it does not compute)
      *d2y_dxi2 = i >= 0 && i < p_.n_in && p_.n_h2 > 0 ? std::numeric_limits<T>::quiet_NaN() : T(0);
      return forward(x, y, clamped_mask);
    }
    T g[2] = {T(0), T(0)};
    const int st = dispatch<true, true>(x, y, clamped_mask, i, g);
    *dy_dxi = g[0];
    *d2y_dxi2 = g[1];
    return st;
  }
  // [RT] forward_grad of 4 samples in one pass of the kernel (detail::forward_batch: each
  // result identical to its own call); statuses in status[4]. Nullable: clamped_mask.
  DN_REALTIME void forward_grad4(const T* const x[4], T y[4], int i, T dy_dxi[4], int status[4],
                                 uint32_t* clamped_mask = nullptr) const noexcept {
    using P = decltype(p_);
    if (i < 0 || i >= p_.n_in) {  // (no such input: never from a damper; rolled)
#pragma GCC unroll 1
      for (int b = 0; b < 4; ++b) {
        dy_dxi[b] = T(0);
        status[b] = forward(x[b], &y[b], clamped_mask ? &clamped_mask[b] : nullptr);
      }
      return;
    }
    if constexpr (DN_KERNEL_SMALL != 0 && detail::kFused1 && P::kCapH2 == 0)  // the one forward this build has (dispatch)
      return detail::forward_batch<T, P::kCapIn, kDynamic, P, true, 4>(p_, x, y, clamped_mask, i, dy_dxi, status);
    if constexpr (P::kCapIn >= 3) {
      if (p_.n_h2 == 0 && p_.n_in == 3)  // the thesis's shape, compiled for its input count
        return detail::forward_batch<T, 3, kDynamic, P, true, 4>(p_, x, y, clamped_mask, i, dy_dxi, status);
    }
    detail::forward_batch<T, kDynamic, kDynamic, P, true, 4>(p_, x, y, clamped_mask, i, dy_dxi, status);
  }
  int n_inputs() const noexcept { return p_.n_in; }
  const T* sat_lo() const noexcept { return p_.sat_lo.data(); }
  const T* sat_hi() const noexcept { return p_.sat_hi.data(); }
  // The largest |output| the model can give, |b_out| + sum_j |w_out[j]| [output units]: the
  // scale of the rounding of the kernel's output sum (an ulp of it). Bounded loop, no branch.
  // (Summed here, not kept by the loads: the kernel part's flash on the Cortex-M7 is held below
  // emlearn's; the damper keeps its own copy, Damper::out_bound_f.)
  T out_bound() const noexcept {
    const int n = p_.n_h2 > 0 ? p_.n_h2 : p_.n_h1;
    T s = std::fabs(p_.b_out);
    for (int j = 0; j < n; ++j) s += std::fabs(p_.w_out[j]);
    return s;
  }
  // The folded parameters as the kernel reads them (tests compare the two loads).
  const MlpParams<T, DN_CAP_INPUTS, DN_CAP_HIDDEN, DN_CAP_HIDDEN2>& params() const noexcept { return p_; }

 private:
  // The common shapes (one hidden layer, 1-4 inputs) go to the kernel compiled for their
  // input count and layer count (the dense layer unrolled, no loop over inputs, no second
  // layer's code); the others to the fully run-time one. Same arithmetic, same results.
  template <bool kGrad, bool kCurv = false>
  int dispatch(const T* x, T* y, uint32_t* m, int i, T* g) const noexcept {
    using P = decltype(p_);
    // The scalar backend (a microcontroller's flash): one specialised kernel, for the capacity's
    // input count (DN_CAP_INPUTS: the model the build is made for), and the run-time one.
    if constexpr (detail::kFused1 && P::kCapH2 == 0) {
      if constexpr (DN_KERNEL_SMALL != 0) {
        // only that one (set-up refuses another input count: small_refuses)
        return detail::forward<T, P::kCapIn, kDynamic, 0, P, kGrad, kCurv>(p_, x, y, m, i, g);
      } else {
        if (p_.n_in == P::kCapIn) return detail::forward<T, P::kCapIn, kDynamic, 0, P, kGrad, kCurv>(p_, x, y, m, i, g);
        return detail::forward<T, kDynamic, kDynamic, 0, P, kGrad, kCurv>(p_, x, y, m, i, g);
      }
    }
    // (Shapes beyond this build's capacity are never compiled: DN_CAP_* in dampnet.h.)
    if (p_.n_h2 == 0) {
      switch (p_.n_in) {
        case 1: return detail::forward<T, 1, kDynamic, 0, P, kGrad, kCurv>(p_, x, y, m, i, g);
        case 2:
          if constexpr (P::kCapIn >= 2) return detail::forward<T, 2, kDynamic, 0, P, kGrad, kCurv>(p_, x, y, m, i, g);
          break;
        case 3:
          if constexpr (P::kCapIn >= 3) return detail::forward<T, 3, kDynamic, 0, P, kGrad, kCurv>(p_, x, y, m, i, g);
          break;
        case 4:
          if constexpr (P::kCapIn >= 4) return detail::forward<T, 4, kDynamic, 0, P, kGrad, kCurv>(p_, x, y, m, i, g);
          break;
        default: break;
      }
    }
    if constexpr (P::kCapH2 == 0) return detail::forward<T, kDynamic, kDynamic, 0, P, kGrad, kCurv>(p_, x, y, m, i, g);
    else return detail::forward<T, kDynamic, kDynamic, kDynamic, P, kGrad, kCurv>(p_, x, y, m, i, g);
  }
  MlpParams<T, DN_CAP_INPUTS, DN_CAP_HIDDEN, DN_CAP_HIDDEN2> p_;
};

// What a build without the double kernel (DN_DOUBLE_KERNEL 0: float-only targets) holds in
// place of Mlp<double> (MlpDouble below): the input count and saturation ranges that set-up
// reads, no weights and no kernel; every evaluation gives DN_E_PARAM and 0. (The float copy,
// loaded from the same description, validates it.)
template <typename T>
class NoKernelMlp {
 public:
  int load(const dn_mlp_desc* d) noexcept {
    if (!d || !d->sat_lo || !d->sat_hi) return DN_E_NULL;
    if (d->n_inputs < 1 || d->n_inputs > DN_CAP_INPUTS) return DN_E_SIZE;
    n_in_ = d->n_inputs;
    for (int i = 0; i < n_in_; ++i) lo_[i] = static_cast<T>(d->sat_lo[i]), hi_[i] = static_cast<T>(d->sat_hi[i]);
    return DN_OK;
  }
  // The same from a folded float description (the float copy validates it), widened exactly
  // without double arithmetic (detail::widen_exact).
  DN_SETUP_SIZE int load_folded(const dn_mlp_folded_f* f) noexcept {
    if (!f || !f->sat_lo || !f->sat_hi) return DN_E_NULL;
    if (f->n_inputs < 1 || f->n_inputs > DN_CAP_INPUTS) return DN_E_SIZE;
    n_in_ = f->n_inputs;
    for (int i = 0; i < n_in_; ++i) lo_[i] = detail::widen_exact(f->sat_lo[i]), hi_[i] = detail::widen_exact(f->sat_hi[i]);
    return DN_OK;
  }
  int forward(const T*, T* y, uint32_t* clamped_mask = nullptr) const noexcept {
    *y = T(0);
    if (clamped_mask) *clamped_mask = 0;
    return DN_E_PARAM;
  }
  int forward_grad(const T* x, T* y, int, T* dy_dxi, uint32_t* clamped_mask = nullptr) const noexcept {
    *dy_dxi = T(0);
    return forward(x, y, clamped_mask);
  }
  int forward_grad_curv(const T* x, T* y, int, T* dy_dxi, T* d2y_dxi2, uint32_t* clamped_mask = nullptr) const noexcept {
    *d2y_dxi2 = T(0);
    *dy_dxi = T(0);
    return forward(x, y, clamped_mask);
  }
  int n_inputs() const noexcept { return n_in_; }
  const T* sat_lo() const noexcept { return lo_; }
  const T* sat_hi() const noexcept { return hi_; }

 private:
  int n_in_ = 0;
  T lo_[DN_CAP_INPUTS] = {}, hi_[DN_CAP_INPUTS] = {};
};

// The double-precision model of dn_mlp and of neural dampers in this build.
#if DN_DOUBLE_KERNEL
using MlpDouble = Mlp<double>;
#else
using MlpDouble = NoKernelMlp<double>;
#endif

// A model whose sizes are compile-time constants (H2 = 0: one hidden layer).
template <typename T, int In, int H1, int H2 = 0>
class StaticMlp {
  // a two-layer network keeps layer 1 within DN_MAX_HIDDEN2 too (MlpParams::P1T sizes its weights)
  static_assert(H2 == 0 || H1 <= DN_MAX_HIDDEN2, "a two-layer network: 1..DN_MAX_HIDDEN2 neurons in layer 1");

 public:
  static constexpr int kInputs = In;
  // Validate and copy a description of exactly these sizes (else DN_E_MISMATCH).
  int load(const dn_mlp_desc* d) noexcept { return detail::load<T, In, H1, H2>(p_, d); }
  // Validate and copy a folded float description of exactly these sizes.
  int load_folded(const dn_mlp_folded_f* f) noexcept { return detail::load_folded<T, In, H1, H2>(p_, f); }
  // [RT] One sample; see dn_mlp_forward for the input policy.
  DN_REALTIME int forward(const T* x, T* y, uint32_t* clamped_mask = nullptr) const noexcept {
    return detail::forward<T, In, H1, H2>(p_, x, y, clamped_mask);
  }
  // [RT] As forward, plus dy/dx[i]; an input index out of range gives 0.
  DN_REALTIME int forward_grad(const T* x, T* y, int i, T* dy_dxi,
                               uint32_t* clamped_mask = nullptr) const noexcept {
    if (i < 0 || i >= In || detail::clamped_on_scalar(p_, x, i)) {
      *dy_dxi = T(0);
      return forward(x, y, clamped_mask);
    }
    return detail::forward<T, In, H1, H2, decltype(p_), true>(p_, x, y, clamped_mask, i, dy_dxi);
  }

 private:
  MlpParams<T, In, H1, H2> p_;
};

}  // namespace DN_KERNEL_NS
}  // namespace dampnet
