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
// SIMD path, chosen at compile time (kernel_isa() says which one a translation
// unit got): AVX-512 (F, VL, DQ) when compiled with -mavx512f -mavx512vl -mavx512dq
// on top of -mavx2 -mfma (CMake: DAMPNET_AVX512, off by default), the same pipeline
// per 16 neurons in __m512 registers (layers padded to 16, 64-byte aligned); AVX2+FMA
// when compiled with -mavx2 -mfma (CMake: DAMPNET_AVX2), a fused per-8-neuron pipeline
// in __m256 registers (both: forward_simd over Simd16 / Simd8); otherwise SSE (x86-64
// baseline) or plain C++ loops. The SIMD paths' last hidden layer uses the 15/4 rational
// tanh with each output weight folded into its numerator (activation.hpp, tanh_folded
// below), the other paths and layers 13/6 rationals (AVX2: 15/4 as well); every path's
// tanh is within 5e-7 of std::tanh, so the paths' results differ by rounding and by
// that. Inputs inside their saturation range are read in place (no copy, no min/max on
// the chain) when the offsets are folded.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <type_traits>

#if defined(__SSE__)
#include <immintrin.h>
#endif

#include "dampnet/activation.hpp"
#include "dampnet/dampnet.h"

#ifdef DAMPNET_USE_EIGEN
#include <Eigen/Core>
#endif

#if defined(__clang__) && defined(DN_REALTIME_SANITIZE)
#define DN_REALTIME [[clang::nonblocking]]
#else
#define DN_REALTIME
#endif

// Flash against speed on scalar cores (dampnet.h, "Capacities"): DN_KERNEL_SMALL 1 compiles
// one float forward, for DN_CAP_INPUTS inputs; DN_KERNEL_UNROLL neurons per pass of it.
#ifndef DN_KERNEL_SMALL
#define DN_KERNEL_SMALL 0
#endif
#ifndef DN_KERNEL_UNROLL
#if DN_KERNEL_SMALL
#define DN_KERNEL_UNROLL 2
#else
#define DN_KERNEL_UNROLL 8
#endif
#endif

// The kernel's SIMD path in this translation unit.
#if defined(DN_TANH16_AVX512) && !defined(DAMPNET_USE_EIGEN)
#define DN_KERNEL_AVX512 1
#define DN_KERNEL_ISA "avx512"
#define DN_KERNEL_NS isa_avx512
#define DN_KERNEL_ALIGN 64
#elif defined(DN_TANH8_AVX2) && !defined(DAMPNET_USE_EIGEN)
#define DN_KERNEL_AVX2 1
#define DN_KERNEL_ISA "avx2+fma"
#define DN_KERNEL_NS isa_avx2_fma
#elif defined(__AVX__)
#define DN_KERNEL_ISA "avx"
#define DN_KERNEL_NS isa_avx
#elif defined(__SSE__)
#define DN_KERNEL_ISA "sse"
#define DN_KERNEL_NS isa_sse
#else
#define DN_KERNEL_ISA "scalar"
#define DN_KERNEL_NS isa_scalar
#endif
#ifndef DN_KERNEL_ALIGN
#define DN_KERNEL_ALIGN 32
#endif

namespace dampnet {
// Everything here carries the kernel's SIMD path in its mangled names, so that
// translation units compiled with different flags never share a function by accident.
inline namespace DN_KERNEL_NS {

constexpr int kDynamic = -1;

// Hidden layers are stored padded to a multiple of 8 neurons (16 on the AVX-512
// path) with zero weights, so every loop runs over whole SIMD vectors (no scalar
// tails). A padded neuron has pre-activation 0 and a zero output weight: it adds
// exactly +0 to the sum.
#if DN_KERNEL_AVX512
constexpr int kPad = 16;
#else
constexpr int kPad = 8;
#endif
constexpr int pad(int n) { return n <= 0 ? 0 : (n + kPad - 1) / kPad * kPad; }

// The SIMD path of the kernel compiled into this translation unit:
// "avx512", "avx2+fma", "avx", "sse" or "scalar" (Eigen, when enabled, does the dense layers).
constexpr const char* kernel_isa() noexcept { return DN_KERNEL_ISA; }

namespace detail {

inline bool all_finite(const double* p, int n) noexcept {
  for (int i = 0; i < n; ++i)
    if (!std::isfinite(p[i])) return false;
  return true;
}

// y = W^T x for the transposed storage wt[n_in][n_out] (+ bias), n_out outputs.
template <typename T, int kIn, int kOut>
inline void dense_t(const T* wt, const T* b, const T* x, T* y, int n_in, int n_out) noexcept {
  const int ni = kIn > 0 ? kIn : n_in;
  const int no = kOut > 0 ? kOut : n_out;
#ifdef DAMPNET_USE_EIGEN
  // Compile-time dimensions where known, so Eigen picks exact-size code paths.
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
#else
  for (int j = 0; j < no; ++j) y[j] = b[j];
  for (int i = 0; i < ni; ++i) {
    const T xi = x[i];
    const T* row = wt + i * no;
    for (int j = 0; j < no; ++j) y[j] += row[j] * xi;
  }
#endif
}

// Clamp n (a multiple of 8) floats to [-9, 9]. GCC will not turn the portable
// compare-and-select into minps/maxps (it must keep NaN and -0 semantics), so
// SSE/AVX use the instructions directly (a NaN becomes +9: minps returns its
// second operand when either is NaN).
inline void clamp_tanh_args(float* h, int n) noexcept {
#if defined(__AVX__)
  const __m256 lo = _mm256_set1_ps(-9.f), hi = _mm256_set1_ps(9.f);
  for (int j = 0; j < n; j += 8)
    _mm256_store_ps(h + j, _mm256_max_ps(_mm256_min_ps(_mm256_load_ps(h + j), hi), lo));
#elif defined(__SSE__)
  const __m128 lo = _mm_set1_ps(-9.f), hi = _mm_set1_ps(9.f);
  for (int j = 0; j < n; j += 4)
    _mm_store_ps(h + j, _mm_max_ps(_mm_min_ps(_mm_load_ps(h + j), hi), lo));
#else
  for (int j = 0; j < n; ++j) h[j] = clamp_tanh_arg(h[j]);
#endif
}
inline void clamp_tanh_args(double* h, int n) noexcept {
  for (int j = 0; j < n; ++j) h[j] = clamp_tanh_arg(h[j]);
}

// tanh of the hidden pre-activations in two passes (clamp, rational): with IEEE
// trapping semantics GCC will not vectorise a loop that both branches and divides.
// h is 32-byte aligned and n a multiple of 8 (padded layers).
template <typename T, int kN>
inline void tanh_all(T* h, int n) noexcept {
  const int nn = kN > 0 ? kN : n;
  clamp_tanh_args(h, nn);
  for (int j = 0; j < nn; ++j) h[j] = tanh_rational(h[j]);
}

// sum_j w[j] a[j] over n (a multiple of 8) in eight interleaved partial sums,
// part[l] = sum_k w[8k+l] a[8k+l], combined as ((p0+p4)+(p1+p5))+((p2+p6)+(p3+p7)):
// the adds pipeline instead of forming one long chain. The SSE version keeps
// exactly this order (and its horizontal sum in registers), so both give the same bits.
template <typename T, int kN>
inline T dot_padded(const T* __restrict w, const T* __restrict a, int n) noexcept {
  const int nn = kN > 0 ? kN : n;
#if defined(__SSE__)
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
#endif
  alignas(DN_KERNEL_ALIGN) T part[8] = {};
  for (int j = 0; j < nn; j += 8)
    for (int l = 0; l < 8; ++l) part[l] += w[j + l] * a[j + l];
  return ((part[0] + part[4]) + (part[1] + part[5])) + ((part[2] + part[6]) + (part[3] + part[7]));
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
// and one predicted branch beside the data chain, not on it).
// float SIMD kernels: one vector compare against the stored ranges (lanes beyond the
// inputs compare against -inf / +inf), fewer operations beside the chain than 2 n_in
// scalar compares. Up to 4 compile-time inputs are gathered by scalar loads; otherwise a
// masked load reads x[0..n_in-1] (AVX vmaskmovps: masked lanes are not read and cannot
// fault, though one lying on an unmapped page costs a microcode assist).
template <typename T, int kIn, class P>
inline bool inputs_in_range(const P& p, const T* x) noexcept {
#if DN_KERNEL_AVX2 || DN_KERNEL_AVX512
  if constexpr (std::is_same<T, float>::value) {
    if constexpr (kIn > 0 && kIn <= 4) {
      // (Read through a pointer the compiler cannot see equals x: else GCC reuses these
      // scalar loads for layer 1 and broadcasts from registers, a longer chain than
      // vbroadcastss from memory.)
      const float* xc = x;
#if defined(__GNUC__)
      __asm__("" : "+r"(xc));
#endif
      const __m128 v = _mm_setr_ps(xc[0], kIn > 1 ? xc[1] : 0.f, kIn > 2 ? xc[2] : 0.f, kIn > 3 ? xc[3] : 0.f);
      const __m128 ok = _mm_and_ps(_mm_cmp_ps(v, _mm_load_ps(p.sat_lo8.data()), _CMP_GE_OQ),
                                   _mm_cmp_ps(v, _mm_load_ps(p.sat_hi8.data()), _CMP_LE_OQ));
      return _mm_movemask_ps(ok) == 0xf;
    } else {
      const __m256 v = _mm256_maskload_ps(x, _mm256_load_si256(reinterpret_cast<const __m256i*>(p.in_mask8.data())));
      const __m256 ok = _mm256_and_ps(_mm256_cmp_ps(v, _mm256_load_ps(p.sat_lo8.data()), _CMP_GE_OQ),
                                      _mm256_cmp_ps(v, _mm256_load_ps(p.sat_hi8.data()), _CMP_LE_OQ));
      return _mm256_movemask_ps(ok) == 0xff;
    }
  }
#endif
  const int ni = kIn > 0 ? kIn : p.n_in;
#if !defined(__SSE__)
  // scalar cores: a compare and a branch each (fewer instructions than combining the flags)
  for (int i = 0; i < ni; ++i)
    if (!(x[i] >= p.sat_lo[i] && x[i] <= p.sat_hi[i])) return false;
  return true;
#else
  bool ok = true;
  for (int i = 0; i < ni; ++i) ok &= (x[i] >= p.sat_lo[i]) & (x[i] <= p.sat_hi[i]);
  return ok;
#endif
}
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

#if DN_KERNEL_AVX2 || DN_KERNEL_AVX512
#if DN_KERNEL_AVX512 && defined(__GNUC__) && !defined(__clang__)
// GCC 12's AVX-512 intrinsics (_mm512_min_ps, _mm512_rcp14_ps, _mm512_castps512_ps256,
// ...) pass a self-initialised "undefined" vector that -Wuninitialized reports.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wuninitialized"
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
// The vector operations of one SIMD width, for the pipeline below written once:
// Simd8 (AVX2+FMA, __m256) and, in AVX-512 builds, Simd16 (__m512).
struct Simd8 {
  using V = __m256;
  static constexpr int kW = 8;
  static V load(const float* p) noexcept { return _mm256_load_ps(p); }
  static void store(float* p, V v) noexcept { _mm256_store_ps(p, v); }
  static V set1(float x) noexcept { return _mm256_set1_ps(x); }
  static V zero() noexcept { return _mm256_setzero_ps(); }
  static V lane0(float x) noexcept { return _mm256_setr_ps(x, 0.f, 0.f, 0.f, 0.f, 0.f, 0.f, 0.f); }
  static V add(V a, V b) noexcept { return _mm256_add_ps(a, b); }
  static V mul(V a, V b) noexcept { return _mm256_mul_ps(a, b); }
  static V fmadd(V a, V b, V c) noexcept { return _mm256_fmadd_ps(a, b, c); }
  static V fnmadd(V a, V b, V c) noexcept { return _mm256_fnmadd_ps(a, b, c); }
  static V min(V a, V b) noexcept { return _mm256_min_ps(a, b); }  // NaN in a: b
  static V max(V a, V b) noexcept { return _mm256_max_ps(a, b); }
  static V div(V a, V b) noexcept { return _mm256_div_ps(a, b); }
  static V tanh(V z) noexcept { return fast_tanh8(z); }
  // The 8 partial sums combined in dot_padded's order.
  static float hsum(V v) noexcept {
    const __m128 q = _mm_add_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
    const __m128 t = _mm_add_ps(q, _mm_shuffle_ps(q, q, _MM_SHUFFLE(2, 3, 0, 1)));
    return _mm_cvtss_f32(_mm_add_ss(t, _mm_movehl_ps(t, t)));
  }
};

#if DN_KERNEL_AVX512
struct Simd16 {
  using V = __m512;
  static constexpr int kW = 16;
  static V load(const float* p) noexcept { return _mm512_load_ps(p); }
  static void store(float* p, V v) noexcept { _mm512_store_ps(p, v); }
  static V set1(float x) noexcept { return _mm512_set1_ps(x); }
  static V zero() noexcept { return _mm512_setzero_ps(); }
  static V lane0(float x) noexcept { return _mm512_maskz_mov_ps(1, _mm512_set1_ps(x)); }
  static V add(V a, V b) noexcept { return _mm512_add_ps(a, b); }
  static V mul(V a, V b) noexcept { return _mm512_mul_ps(a, b); }
  static V fmadd(V a, V b, V c) noexcept { return _mm512_fmadd_ps(a, b, c); }
  static V fnmadd(V a, V b, V c) noexcept { return _mm512_fnmadd_ps(a, b, c); }
  static V min(V a, V b) noexcept { return _mm512_min_ps(a, b); }  // NaN in a: b
  static V max(V a, V b) noexcept { return _mm512_max_ps(a, b); }
  static V div(V a, V b) noexcept { return _mm512_div_ps(a, b); }
  static V tanh(V z) noexcept { return fast_tanh16(z); }
  // Halves added, then the 8 as Simd8::hsum combines them.
  static float hsum(V v) noexcept {
    return Simd8::hsum(_mm256_add_ps(_mm512_castps512_ps256(v), _mm512_extractf32x8_ps(v, 1)));
  }
};
using SimdKernel = Simd16;
#else
using SimdKernel = Simd8;
#endif

// One block of S::kW outputs of a dense layer: init + sum_i x[i] * wt[i * stride + 0..kW-1].
// Up to 4 inputs in one FMA chain; more in four interleaved chains (latency n/4 FMAs).
template <class S, int kN>
inline typename S::V dense_block(typename S::V init, const float* wt, const float* x, int n_dyn,
                                 int stride) noexcept {
  const int n = kN > 0 ? kN : n_dyn;
  if (n <= 4) {
    for (int i = 0; i < n; ++i) init = S::fmadd(S::load(wt + i * stride), S::set1(x[i]), init);
    return init;
  }
  typename S::V c1 = S::zero(), c2 = c1, c3 = c1;
  const int n4 = n - n % 4;
  for (int i = 0; i < n4; i += 4) {
    init = S::fmadd(S::load(wt + i * stride), S::set1(x[i]), init);
    c1 = S::fmadd(S::load(wt + (i + 1) * stride), S::set1(x[i + 1]), c1);
    c2 = S::fmadd(S::load(wt + (i + 2) * stride), S::set1(x[i + 2]), c2);
    c3 = S::fmadd(S::load(wt + (i + 3) * stride), S::set1(x[i + 3]), c3);
  }
  for (int i = n4; i < n; ++i) init = S::fmadd(S::load(wt + i * stride), S::set1(x[i]), init);
  return S::add(S::add(init, c1), S::add(c2, c3));
}

// w_j tanh(z_j) for one block of the last hidden layer as r * pw: the 15/4 rational of
// activation.hpp (fast_tanh8's operations) with the neuron's output weight folded into
// the numerator's coefficients (tw[k * stride + j] = P_k w_j, made by load()), so that
// the output is one FMA per block, acc + r pw, and the numerator with its weight is off
// the chain (ready before the division is). r = x / q.
template <class S>
inline void tanh_folded(typename S::V z, const float* tw, int stride, typename S::V& r,
                        typename S::V& pw) noexcept {
  using V = typename S::V;
  const V x = S::max(S::min(z, S::set1(kTanhClamp)), S::set1(-kTanhClamp));  // NaN: +clamp
  const V y = S::min(S::mul(z, z), S::set1(kTanhClampSq));
  const V y2 = S::mul(y, y), y4 = S::mul(y2, y2);
  const V c01 = S::fmadd(S::load(tw + stride), y, S::load(tw));
  const V c23 = S::fmadd(S::load(tw + 3 * stride), y, S::load(tw + 2 * stride));
  const V c45 = S::fmadd(S::load(tw + 5 * stride), y, S::load(tw + 4 * stride));
  const V c67 = S::fmadd(S::load(tw + 7 * stride), y, S::load(tw + 6 * stride));
  pw = S::fmadd(S::fmadd(c67, y2, c45), y4, S::fmadd(c23, y2, c01));
  const V q = S::fmadd(y, S::add(y, S::set1(static_cast<float>(kTanhQ1))), S::set1(static_cast<float>(kTanhQ0)));
  r = S::div(x, q);
}

// The float forward pass after the inputs: per block of S::kW neurons, dense (FMA),
// tanh and the output FMA in registers, the blocks' outputs accumulated in one FMA chain
// in block order (the blocks finish one after another, limited by the FMA ports, so a
// serial chain waits least for the last one), b_out in lane 0 of the accumulator. Returns
// b_out + sum_j w_out[j] t_j; with kGrad also (in *dys) the forward-mode derivative for
// the input whose layer-1 column is `col` (nullptr: that input was clamped, derivative 0):
// sum_j (w_j - (w_j t_j) t_j) col_j, with t_j = (w_j t_j) / w_j by the stored 1/w_j, so
// that the value is computed exactly as without kGrad.
template <class S, int kIn, int kH1, int kH2, bool kGrad, class P>
inline float forward_simd(const P& p, const float* xs, const float* col, float* dys) noexcept {
  using V = typename S::V;
  constexpr int kW = S::kW;
  constexpr int kP1 = kH1 > 0 ? pad(kH1) : kDynamic;
  constexpr int kP2 = kH2 > 0 ? pad(kH2) : (kH2 == 0 ? 0 : kDynamic);
  constexpr int cap_h1 = kH1 > 0 ? kP1 : P::P1;
  constexpr int stride = P::kTw;
  const int ni = kIn > 0 ? kIn : p.n_in;
  const int h1 = kP1 > 0 ? kP1 : p.n_h1p;
  const int h2 = kP2 >= 0 ? kP2 : p.n_h2p;
  V acc = S::lane0(p.b_out), dacc = S::zero();
  // The last layer's contribution of one block: acc += w t; with kGrad, dacc += w (1 - t^2) d.
  auto last = [&](V z, int j, const float* dz) {
    (void)dz;
    V r, pw;
    tanh_folded<S>(z, p.tw.data() + j, stride, r, pw);
    acc = S::fmadd(r, pw, acc);
    if constexpr (kGrad) {
      if (dz) {
        const V wt = S::mul(r, pw), t = S::mul(wt, S::load(p.inv_w.data() + j));
        dacc = S::fmadd(S::fnmadd(wt, t, S::load(p.w_out.data() + j)), S::load(dz), dacc);
      }
    }
  };
  if (kH2 == 0 || h2 == 0) {
    for (int j = 0; j < h1; j += kW)
      last(dense_block<S, kIn>(S::load(p.b1.data() + j), p.w1t.data() + j, xs, ni, h1), j,
           col ? col + j : nullptr);
  } else {
    const V one = S::set1(1.f);
    alignas(4 * kW) float a1[cap_h1];
    alignas(4 * kW) float t1[kGrad ? cap_h1 : kPad];
    for (int j = 0; j < h1; j += kW) {
      const V t = S::tanh(dense_block<S, kIn>(S::load(p.b1.data() + j), p.w1t.data() + j, xs, ni, h1));
      S::store(a1 + j, t);
      if constexpr (kGrad)
        S::store(t1 + j, col ? S::mul(S::fnmadd(t, t, one), S::load(col + j)) : S::zero());
    }
    alignas(4 * kW) float lin[kGrad ? kW : 1];
    for (int j = 0; j < h2; j += kW) {
      if constexpr (kGrad) S::store(lin, dense_block<S, kP1>(S::zero(), p.w2t.data() + j, t1, h1, h2));
      last(dense_block<S, kP1>(S::load(p.b2.data() + j), p.w2t.data() + j, a1, h1, h2), j,
           kGrad ? lin : nullptr);
    }
  }
  if constexpr (kGrad) *dys = S::hsum(dacc);
  return S::hsum(acc);
}

// forward_simd of kB samples at once, one hidden layer: per block of neurons the weights
// are loaded once for all samples, and the samples' kB independent chains interleave (more
// work in flight per weight load). Each sample's operations and their order are
// forward_simd's, so its result is bit-identical to a single call's.
template <class S, int kIn, int kH1, bool kGrad, int kB, class P>
inline void forward_simd_batch(const P& p, const float* const* xs, const float* const* col,
                               float* sums, float* dys) noexcept {
  using V = typename S::V;
  constexpr int kW = S::kW;
  constexpr int kP1 = kH1 > 0 ? pad(kH1) : kDynamic;
  constexpr int stride = P::kTw;
  const int ni = kIn > 0 ? kIn : p.n_in;
  const int h1 = kP1 > 0 ? kP1 : p.n_h1p;
  V acc[kB], dacc[kB];
  for (int b = 0; b < kB; ++b) acc[b] = S::lane0(p.b_out), dacc[b] = S::zero();
  for (int j = 0; j < h1; j += kW) {
    for (int b = 0; b < kB; ++b) {
      const V z = dense_block<S, kIn>(S::load(p.b1.data() + j), p.w1t.data() + j, xs[b], ni, h1);
      V r, pw;
      tanh_folded<S>(z, p.tw.data() + j, stride, r, pw);
      acc[b] = S::fmadd(r, pw, acc[b]);
      if constexpr (kGrad) {
        if (col[b]) {
          const V wt = S::mul(r, pw), t = S::mul(wt, S::load(p.inv_w.data() + j));
          dacc[b] = S::fmadd(S::fnmadd(wt, t, S::load(p.w_out.data() + j)), S::load(col[b] + j), dacc[b]);
        }
      }
    }
  }
  for (int b = 0; b < kB; ++b) {
    sums[b] = S::hsum(acc[b]);
    if constexpr (kGrad) dys[b] = S::hsum(dacc[b]);
  }
}
#if DN_KERNEL_AVX512 && defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif
#endif

#if !defined(__SSE__) && !defined(DAMPNET_USE_EIGEN)
#define DN_PRAGMA_(x) _Pragma(#x)
#define DN_UNROLL_(n) DN_PRAGMA_(GCC unroll n)
// Scalar targets (no SIMD: Cortex-M and the like), one hidden layer: forward()'s passes
// below (dense_t, tanh_all, dot_padded's eight partial sums; with kGrad the forward-mode
// column) fused into one pass per partial sum, so that no activation is stored and loaded
// again and the output weights meet each tanh in registers. dot_padded's partial sum l is
// part[l] = sum_k w[8k+l] a[8k+l] in k order: here lane l's neurons j = l, l+8, ... in that
// order, one loop (DN_KERNEL_UNROLL neurons per pass; the lanes are not unrolled: one copy
// of the neuron's code, the flash a microcontroller has little of). The operations on each
// neuron and their order are the passes', so the result is theirs bit for bit (and the SSE
// kernel's, whose dot_padded keeps that order). The padding neurons (n_h1 .. n_h1p - 1) are
// skipped: each would add exactly +0 (zero weights; a finite input), and a sum that starts at
// +0 is never -0, so adding +0 changes no bit. The tanh's coefficients are held in registers
// across the loop (on Arm: else reloaded for every neuron). Returns b_out + sum_j w_out[j] t_j.
template <typename T, int kIn, int kP1, bool kGrad, class P>
inline T forward_fused1(const P& p, const T* xs, const T* col, T* dys) noexcept {
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
  T part[8], dpart[8];
  // One pointer walks the neurons of a lane through w1t's row 0; b1, w_out and the other rows
  // are at fixed distances from it (members of p; the rows at the capacity's stride).
  // (Byte offsets within p's object representation.)
  const char* const w0 = reinterpret_cast<const char*>(p.w1t.data());
  constexpr ptrdiff_t ob = static_cast<ptrdiff_t>(offsetof(P, b1)) - static_cast<ptrdiff_t>(offsetof(P, w1t));
  constexpr ptrdiff_t oo = static_cast<ptrdiff_t>(offsetof(P, w_out)) - static_cast<ptrdiff_t>(offsetof(P, w1t));
  const ptrdiff_t oc = col ? reinterpret_cast<const char*>(col) - w0 : 0;
  auto at = [](const char* q, ptrdiff_t off) noexcept { return *reinterpret_cast<const T*>(q + off); };
  constexpr int kU = DN_KERNEL_UNROLL;  // lanes per pass
  static_assert(kU == 1 || kU == 2 || kU == 4 || kU == 8, "DN_KERNEL_UNROLL: 1, 2, 4 or 8");
  DN_UNROLL_(1)
  for (int l = 0; l < 8; l += kU) {  // lanes l .. l + kU - 1, row by row
    T acc[kU], dacc[kU];
    for (int u = 0; u < kU; ++u) acc[u] = T(0), dacc[u] = T(0);
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
          if (col) dacc[u] += at(q, oo) * ((T(1) - t * t) * at(q, oc));
        }
      }
    }
    for (int u = 0; u < kU; ++u) part[l + u] = acc[u], dpart[l + u] = dacc[u];
  }
  auto combine = [](const T* q) noexcept {
    return ((q[0] + q[4]) + (q[1] + q[5])) + ((q[2] + q[6]) + (q[3] + q[7]));
  };
  if constexpr (kGrad) *dys = col ? combine(dpart) : T(0);
  return p.b_out + combine(part);
}
#define DN_KERNEL_FUSED1 1
#endif

// Each forward is one function (not inlined into every caller: the damper's and the loop's
// several call sites would each get a copy, and its stack; a flash-lean build's flash, the
// host's L1i: issue 30).
#if defined(__GNUC__)
#define DN_KERNEL_OUTLINE __attribute__((noinline, noclone))
#else
#define DN_KERNEL_OUTLINE
#endif

// The forward pass shared by Mlp and StaticMlp. kH2 == 0: one hidden layer.
// Sizes used here are the padded ones (pad()). With kGrad, *dy_dxi also receives
// dy/dx[grad_input] (output units per input unit) by forward-mode differentiation;
// it is 0 when that input was clamped (the saturated model does not depend on it).
template <typename T, int kIn, int kH1, int kH2, class P, bool kGrad = false>
DN_KERNEL_OUTLINE DN_REALTIME inline int forward(const P& p, const T* x, T* y, uint32_t* clamped_mask,
                               int grad_input = 0, T* dy_dxi = nullptr) noexcept {
  constexpr int kP1 = kH1 > 0 ? pad(kH1) : kDynamic;
  constexpr int kP2 = kH2 > 0 ? pad(kH2) : (kH2 == 0 ? 0 : kDynamic);
  // Stack arrays of the model's capacity (P's), or of its compile-time sizes.
  constexpr int cap_in = kIn > 0 ? kIn : P::kCapIn;
  constexpr int cap_h1 = kH1 > 0 ? kP1 : P::P1;
  constexpr int cap_h2 = kH2 > 0 ? kP2 : P::P2;
  const int h1 = kP1 > 0 ? kP1 : p.n_h1p;
  const int h2 = kP2 >= 0 ? kP2 : p.n_h2p;

  uint32_t mask = 0;
  // zeroed: GCC cannot see that prepare_inputs writes all it reads (scalar cores: no vector
  // alignment, which would cost a realigned stack frame)
#ifdef DN_KERNEL_FUSED1
  T xs_buf[cap_in] = {};
#else
  alignas(DN_KERNEL_ALIGN) T xs_buf[cap_in] = {};
#endif
  // Layer 1's input: the caller's x itself when no input needs saturating and the
  // offsets are folded (the common case; the same values prepare_inputs would copy).
  const T* xs = x;
  int status = DN_OK;
#if DN_KERNEL_SMALL
  // One copy of the saturation code (flash): the offsets subtracted, or zeros when they are
  // folded (v - 0 is v, -0 included: the same values as prepare_inputs<..., false>).
  if (!p.in_offset_folded || !inputs_in_range<T, kIn>(p, x)) {
    static constexpr T kZeros[cap_in] = {};
    status = prepare_inputs_off<T, kIn>(p, x, p.in_offset_folded ? kZeros : p.in_offset.data(), xs_buf, mask);
    xs = xs_buf;
  }
#else
  if (!p.in_offset_folded) {
    status = prepare_inputs<T, kIn, true>(p, x, xs_buf, mask);
    xs = xs_buf;
  } else if (!inputs_in_range<T, kIn>(p, x)) {
    status = prepare_inputs<T, kIn, false>(p, x, xs_buf, mask);
    xs = xs_buf;
  }
#endif
  // Layer 1's column for the differentiated input (its gain folded in); none if clamped.
  const T* col = (kGrad && !((mask >> grad_input) & 1u)) ? p.w1t.data() + grad_input * h1 : nullptr;

  T sum, dys = T(0);
#if DN_KERNEL_AVX2 || DN_KERNEL_AVX512
  if constexpr (std::is_same<T, float>::value) {
    sum = forward_simd<SimdKernel, kIn, kH1, kH2, kGrad>(p, xs, col, &dys);  // b_out included
  } else
#endif
#if DN_KERNEL_FUSED1
  if (kH2 == 0 || h2 == 0) {
    sum = forward_fused1<T, kIn, kP1, kGrad>(p, xs, col, &dys);  // b_out included
  } else
#endif
  {
    alignas(DN_KERNEL_ALIGN) T a1[cap_h1];
    dense_t<T, kIn, kP1>(p.w1t.data(), p.b1.data(), xs, a1, p.n_in, h1);
    tanh_all<T, kP1>(a1, h1);

    // Forward mode: t1 = d(a1)/dx_i = (1 - a1^2) * W1[:, i] (gain and sigmoid scale folded in).
    alignas(DN_KERNEL_ALIGN) T t1[kGrad ? cap_h1 : kPad] = {};
    if constexpr (kGrad) {
      if (col)
        for (int j = 0; j < h1; ++j) t1[j] = (T(1) - a1[j] * a1[j]) * col[j];
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
    sum = p.b_out + (n_last_is_a2 ? dot_padded<T, kP2>(p.w_out.data(), a2, n_last)
                                  : dot_padded<T, kP1>(p.w_out.data(), a1, n_last));
  }
  if constexpr (kGrad) *dy_dxi = dys;

  T out = sum;  // the output unscaling is folded into w_out and b_out
  if (!std::isfinite(out)) {
    out = p.out_offset;
    status = DN_E_NONFINITE_OUTPUT;
  }
  *y = out;
  if (clamped_mask) *clamped_mask = mask;
  return status;
}

// forward() of kB samples (x[b], y[b], clamped_mask[b], dy_dxi[b]; masks and dy_dxi
// nullable), each result identical to its own forward() call: float models with one hidden
// layer go through forward_simd_batch (the weights loaded once per block for all samples);
// the others are kB forward() calls. Returns the samples' statuses in status[b].
template <typename T, int kIn, int kH1, class P, bool kGrad, int kB>
DN_KERNEL_OUTLINE DN_REALTIME inline void forward_batch(const P& p, const T* const* x, T* y, uint32_t* clamped_mask,
                                      int grad_input, T* dy_dxi, int* status) noexcept {
#if DN_KERNEL_AVX2 || DN_KERNEL_AVX512
  if constexpr (std::is_same<T, float>::value) {
    if (p.n_h2p == 0) {
      constexpr int cap_in = kIn > 0 ? kIn : P::kCapIn;
      constexpr int kP1 = kH1 > 0 ? pad(kH1) : kDynamic;
      const int h1 = kP1 > 0 ? kP1 : p.n_h1p;
      alignas(DN_KERNEL_ALIGN) T xs_buf[kB][cap_in] = {};
      const T* xs[kB];
      const T* col[kB];
      uint32_t mask[kB];
      for (int b = 0; b < kB; ++b) {  // forward()'s input handling, per sample
        mask[b] = 0;
        xs[b] = x[b];
        status[b] = DN_OK;
        if (!p.in_offset_folded) {
          status[b] = prepare_inputs<T, kIn, true>(p, x[b], xs_buf[b], mask[b]);
          xs[b] = xs_buf[b];
        } else if (!inputs_in_range<T, kIn>(p, x[b])) {
          status[b] = prepare_inputs<T, kIn, false>(p, x[b], xs_buf[b], mask[b]);
          xs[b] = xs_buf[b];
        }
        col[b] = (kGrad && !((mask[b] >> grad_input) & 1u)) ? p.w1t.data() + grad_input * h1 : nullptr;
      }
      T sums[kB], dys[kB] = {};
      forward_simd_batch<SimdKernel, kIn, kH1, kGrad, kB>(p, xs, col, sums, dys);
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
#endif
  for (int b = 0; b < kB; ++b)
    status[b] = forward<T, kIn, kH1, kDynamic, P, kGrad>(p, x[b], &y[b], clamped_mask ? &clamped_mask[b] : nullptr,
                                                         grad_input, kGrad ? &dy_dxi[b] : nullptr);
}

// A flash-lean build (DN_KERNEL_SMALL) on a scalar core compiles the one-hidden-layer forward
// for exactly its capacity's input count (Mlp::dispatch): set-up refuses another (DN_E_SIZE).
template <class P>
constexpr bool small_refuses(int n_in) noexcept {
#if DN_KERNEL_SMALL && defined(DN_KERNEL_FUSED1)
  return P::kCapH2 == 0 && n_in != P::kCapIn;
#else
  return (void)n_in, false;
#endif
}

// The stride of w1t's rows (and the padded length of b1 and w_out): pad(h1), or on scalar
// targets for one hidden layer the capacity's P::P1, so that forward_fused1 finds every
// input's weight of a neuron at a fixed offset from one pointer.
template <class P>
constexpr int layer1_stride(int h1, int h2) noexcept {
#ifdef DN_KERNEL_FUSED1
  if (h2 == 0) return P::P1;
#endif
  return (void)h2, pad(h1);
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
  if (ni < 1 || ni > DN_MAX_INPUTS || h1 < 1 || h1 > DN_MAX_HIDDEN || h2 < 0 || h2 > DN_MAX_HIDDEN)
    return DN_E_SIZE;
  if ((kIn > 0 && ni != kIn) || (kH1 > 0 && h1 != kH1) || (kH2 >= 0 && h2 != kH2)) return DN_E_MISMATCH;
  // beyond this object's capacity (a build with lowered DN_CAP_*: dampnet.h)
  if (ni > P::kCapIn || h1 > P::kCapH1 || h2 > P::kCapH2) return DN_E_SIZE;
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

// Set-up code of a flash-lean build (DN_KERNEL_SMALL) is optimised for size (GCC): it runs
// once, and -O3 would unroll its copies and checks into kilobytes.
#if DN_KERNEL_SMALL && defined(__GNUC__) && !defined(__clang__)
#define DN_SETUP_SIZE __attribute__((optimize("Os")))
#else
#define DN_SETUP_SIZE
#endif

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
  static_assert(H1 >= 1 && H1 <= DN_MAX_HIDDEN, "1..64 neurons in hidden layer 1");
  static_assert(H2 >= 0 && H2 <= DN_MAX_HIDDEN, "0..64 neurons in hidden layer 2");
  static constexpr int P1 = pad(H1), P2 = pad(H2);
  static constexpr int kCapIn = In, kCapH1 = H1, kCapH2 = H2;
  int n_in = 0, n_h1 = 0, n_h2 = 0;  // real sizes
  int n_h1p = 0, n_h2p = 0;          // padded sizes the loops run over
  Activation act = Activation::tanh;
  alignas(DN_KERNEL_ALIGN) std::array<T, In * P1> w1t{};  // [in][h1 padded], input gain folded in
  alignas(DN_KERNEL_ALIGN) std::array<T, P1> b1{};
  alignas(DN_KERNEL_ALIGN) std::array<T, (H2 > 0 ? P1 * P2 : 0)> w2t{};  // [h1 padded][h2 padded]
  alignas(DN_KERNEL_ALIGN) std::array<T, P2> b2{};
  alignas(DN_KERNEL_ALIGN) std::array<T, (H2 > 0 ? P2 : P1)> w_out{};  // output unscaling folded in
  // float only: the last hidden layer's tanh numerator with the output weight folded in,
  // tw[k * kTw + j] = kTanhP[k] w_out[j] (activation.hpp), and 1 / w_out[j] (0 where
  // w_out[j] is 0 or its reciprocal would not be finite), for the SIMD kernels.
  // (Not stored for the other kernels, which never read them.)
#if DN_KERNEL_AVX2 || DN_KERNEL_AVX512
  static constexpr int kTw = std::is_same<T, float>::value ? (H2 > 0 ? P2 : P1) : 0;
#else
  static constexpr int kTw = 0;
#endif
  alignas(DN_KERNEL_ALIGN) std::array<T, kTanhPTerms * kTw> tw{};
  alignas(DN_KERNEL_ALIGN) std::array<T, kTw> inv_w{};
  T b_out{};  // the output for all-zero hidden units, in output units
  std::array<T, In> in_offset{}, in_mid{}, sat_lo{}, sat_hi{};
  // float only: sat_lo / sat_hi padded to 8 with -inf / +inf, and -1 for each input (0
  // beyond), for the SIMD kernels' range check (inputs_in_range).
#if DN_KERNEL_AVX2 || DN_KERNEL_AVX512
  static constexpr int kR8 = std::is_same<T, float>::value ? 8 : 0;
#else
  static constexpr int kR8 = 0;
#endif
  alignas(32) std::array<T, kR8> sat_lo8{}, sat_hi8{};
  alignas(32) std::array<int32_t, kR8> in_mask8{};
  bool in_offset_folded = false;  // layer 1's bias holds -W1 offset (forward skips x - offset)
  T out_offset{};  // what a non-finite output is replaced by
};

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
    if (i < 0 || i >= p_.n_in) {
      *dy_dxi = T(0);
      return forward(x, y, clamped_mask);
    }
    return dispatch<true>(x, y, clamped_mask, i, dy_dxi);
  }
  // [RT] forward_grad of 4 samples in one pass of the kernel (detail::forward_batch: each
  // result identical to its own call); statuses in status[4]. Nullable: clamped_mask.
  DN_REALTIME void forward_grad4(const T* const x[4], T y[4], int i, T dy_dxi[4], int status[4],
                                 uint32_t* clamped_mask = nullptr) const noexcept {
    using P = decltype(p_);
    if (i < 0 || i >= p_.n_in) {
      for (int b = 0; b < 4; ++b) {
        dy_dxi[b] = T(0);
        status[b] = forward(x[b], &y[b], clamped_mask ? &clamped_mask[b] : nullptr);
      }
      return;
    }
#if DN_KERNEL_SMALL && defined(DN_KERNEL_FUSED1)
    if constexpr (P::kCapH2 == 0)  // the one forward this build has (dispatch)
      return detail::forward_batch<T, P::kCapIn, kDynamic, P, true, 4>(p_, x, y, clamped_mask, i, dy_dxi, status);
#endif
    if constexpr (P::kCapIn >= 3) {
      if (p_.n_h2 == 0 && p_.n_in == 3)  // the thesis's shape, compiled for its input count
        return detail::forward_batch<T, 3, kDynamic, P, true, 4>(p_, x, y, clamped_mask, i, dy_dxi, status);
    }
    detail::forward_batch<T, kDynamic, kDynamic, P, true, 4>(p_, x, y, clamped_mask, i, dy_dxi, status);
  }
  int n_inputs() const noexcept { return p_.n_in; }
  const T* sat_lo() const noexcept { return p_.sat_lo.data(); }
  const T* sat_hi() const noexcept { return p_.sat_hi.data(); }
  // The folded parameters as the kernel reads them (tests compare the two loads).
  const MlpParams<T, DN_CAP_INPUTS, DN_CAP_HIDDEN, DN_CAP_HIDDEN2>& params() const noexcept { return p_; }

 private:
  // The common shapes (one hidden layer, 1-4 inputs) go to the kernel compiled for their
  // input count and layer count (the dense layer unrolled, no loop over inputs, no second
  // layer's code); the others to the fully run-time one. Same arithmetic, same results.
  template <bool kGrad>
  int dispatch(const T* x, T* y, uint32_t* m, int i, T* g) const noexcept {
    using P = decltype(p_);
#if DN_KERNEL_FUSED1
    // Scalar targets (a microcontroller's flash): one specialised kernel, for the capacity's
    // input count (DN_CAP_INPUTS: the model the build is made for), and the run-time one.
    if constexpr (P::kCapH2 == 0) {
#if DN_KERNEL_SMALL
      // only that one (set-up refuses another input count: small_refuses)
      return detail::forward<T, P::kCapIn, kDynamic, 0, P, kGrad>(p_, x, y, m, i, g);
#else
      if (p_.n_in == P::kCapIn) return detail::forward<T, P::kCapIn, kDynamic, 0, P, kGrad>(p_, x, y, m, i, g);
      return detail::forward<T, kDynamic, kDynamic, 0, P, kGrad>(p_, x, y, m, i, g);
#endif
    }
#endif
    // (Shapes beyond this build's capacity are never compiled: DN_CAP_* in dampnet.h.)
    if (p_.n_h2 == 0) {
      switch (p_.n_in) {
        case 1: return detail::forward<T, 1, kDynamic, 0, P, kGrad>(p_, x, y, m, i, g);
        case 2:
          if constexpr (P::kCapIn >= 2) return detail::forward<T, 2, kDynamic, 0, P, kGrad>(p_, x, y, m, i, g);
          break;
        case 3:
          if constexpr (P::kCapIn >= 3) return detail::forward<T, 3, kDynamic, 0, P, kGrad>(p_, x, y, m, i, g);
          break;
        case 4:
          if constexpr (P::kCapIn >= 4) return detail::forward<T, 4, kDynamic, 0, P, kGrad>(p_, x, y, m, i, g);
          break;
        default: break;
      }
    }
    if constexpr (P::kCapH2 == 0) return detail::forward<T, kDynamic, kDynamic, 0, P, kGrad>(p_, x, y, m, i, g);
    else return detail::forward<T, kDynamic, kDynamic, kDynamic, P, kGrad>(p_, x, y, m, i, g);
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
    if (i < 0 || i >= In) {
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
