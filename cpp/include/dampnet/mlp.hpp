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
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
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

namespace dampnet {

constexpr int kDynamic = -1;

// Hidden layers are stored padded to a multiple of 8 neurons with zero weights,
// so every loop runs over whole SIMD vectors (no scalar tails). A padded neuron
// has pre-activation 0 and a zero output weight: it adds exactly +0 to the sum.
constexpr int kPad = 8;
constexpr int pad(int n) { return n <= 0 ? 0 : (n + kPad - 1) / kPad * kPad; }

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
// SSE/AVX use the instructions directly; the values are finite here.
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
inline void clamp_tanh_args(double*, int) noexcept {}  // std::tanh needs no clamp

// Hidden activations in passes (scale, clamp, rational, shift): with IEEE
// trapping semantics GCC will not vectorise a loop that both branches and divides.
// h is 32-byte aligned and n a multiple of 8 (padded layers).
template <typename T, int kN>
inline void activate_all(Activation act, T* h, int n) noexcept {
  const int nn = kN > 0 ? kN : n;
  if (act == Activation::sigmoid)
    for (int j = 0; j < nn; ++j) h[j] *= T(0.5);
  clamp_tanh_args(h, nn);
  for (int j = 0; j < nn; ++j) h[j] = tanh_rational(h[j]);
  if (act == Activation::sigmoid)
    for (int j = 0; j < nn; ++j) h[j] = T(0.5) + T(0.5) * h[j];
}

// sum_j w[j] a[j] over n (a multiple of 8) in eight interleaved partial sums,
// part[l] = sum_k w[8k+l] a[8k+l], combined as ((p0+p4)+(p1+p5))+((p2+p6)+(p3+p7)):
// the adds pipeline instead of forming one long chain. The SIMD versions keep
// exactly this order, so every path gives the same bits.
template <typename T, int kN>
inline T dot_padded(const T* __restrict w, const T* __restrict a, int n) noexcept {
  const int nn = kN > 0 ? kN : n;
#if defined(__SSE__)
  if constexpr (std::is_same<T, float>::value) {
    __m128 lo = _mm_setzero_ps(), hi = _mm_setzero_ps();  // part[0..3], part[4..7]
    for (int j = 0; j < nn; j += kPad) {
      lo = _mm_add_ps(lo, _mm_mul_ps(_mm_load_ps(w + j), _mm_load_ps(a + j)));
      hi = _mm_add_ps(hi, _mm_mul_ps(_mm_load_ps(w + j + 4), _mm_load_ps(a + j + 4)));
    }
    alignas(16) float s[4];
    _mm_store_ps(s, _mm_add_ps(lo, hi));  // p0+p4, p1+p5, p2+p6, p3+p7
    return (s[0] + s[1]) + (s[2] + s[3]);
  }
#endif
  alignas(32) T part[kPad] = {};
  for (int j = 0; j < nn; j += kPad)
    for (int l = 0; l < kPad; ++l) part[l] += w[j + l] * a[j + l];
  return ((part[0] + part[4]) + (part[1] + part[5])) + ((part[2] + part[6]) + (part[3] + part[7]));
}

// Saturate and scale the inputs; returns the warning bits, sets the mask.
template <typename T, int kIn, class P>
inline int prepare_inputs(const P& p, const T* x, T* xs, uint32_t& mask) noexcept {
  const int ni = kIn > 0 ? kIn : p.n_in;
  int status = DN_OK;
  for (int i = 0; i < ni; ++i) {
    T v = x[i];
    const T lo = p.sat_lo[i], hi = p.sat_hi[i];
    if (v != v) {  // NaN: the centre of the training range is the least surprising value
      v = T(0.5) * (lo + hi);
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
    xs[i] = (v - p.in_offset[i]) * p.in_gain[i] + p.in_ymin;
  }
  return status;
}

// Derivative of the activation from its output h: tanh' = 1 - h^2, sigmoid' = h (1 - h).
template <typename T>
inline void activation_slopes(Activation act, const T* h, T* d, int n) noexcept {
  if (act == Activation::sigmoid)
    for (int j = 0; j < n; ++j) d[j] = h[j] * (T(1) - h[j]);
  else
    for (int j = 0; j < n; ++j) d[j] = T(1) - h[j] * h[j];
}

// The forward pass shared by Mlp and StaticMlp. kH2 == 0: one hidden layer.
// Sizes used here are the padded ones (pad()). With kGrad, *dy_dxi also receives
// dy/dx[grad_input] (output units per input unit) by forward-mode differentiation;
// it is 0 when that input was clamped (the saturated model does not depend on it).
template <typename T, int kIn, int kH1, int kH2, class P, bool kGrad = false>
DN_REALTIME inline int forward(const P& p, const T* x, T* y, uint32_t* clamped_mask,
                               int grad_input = 0, T* dy_dxi = nullptr) noexcept {
  constexpr int kP1 = kH1 > 0 ? pad(kH1) : kDynamic;
  constexpr int kP2 = kH2 > 0 ? pad(kH2) : (kH2 == 0 ? 0 : kDynamic);
  constexpr int cap_in = kIn > 0 ? kIn : DN_MAX_INPUTS;
  constexpr int cap_h1 = kH1 > 0 ? kP1 : DN_MAX_HIDDEN;
  constexpr int cap_h2 = kH2 > 0 ? kP2 : DN_MAX_HIDDEN;
  const int h1 = kP1 > 0 ? kP1 : p.n_h1p;
  const int h2 = kP2 >= 0 ? kP2 : p.n_h2p;

  uint32_t mask = 0;
  alignas(32) T xs[cap_in];
  int status = prepare_inputs<T, kIn>(p, x, xs, mask);

  alignas(32) T a1[cap_h1];
  dense_t<T, kIn, kP1>(p.w1t.data(), p.b1.data(), xs, a1, p.n_in, h1);
  activate_all<T, kP1>(p.act, a1, h1);

  // Forward mode: t1 = d(a1)/dx_i = act'(z1) * W1[:, i] * gain_i.
  alignas(32) T t1[kGrad ? cap_h1 : kPad] = {};
  if constexpr (kGrad) {
    activation_slopes(p.act, a1, t1, h1);
    const bool clamped = (mask >> grad_input) & 1u;
    const T g = clamped ? T(0) : p.in_gain[grad_input];
    const T* col = p.w1t.data() + grad_input * h1;
    for (int j = 0; j < h1; ++j) t1[j] *= col[j] * g;
  }

  int n_last = h1;
  bool n_last_is_a2 = false;
  alignas(32) T a2[cap_h2 > 0 ? cap_h2 : kPad];
  alignas(32) T t2[kGrad && cap_h2 > 0 ? cap_h2 : kPad];
  if constexpr (kH2 != 0) {  // compiled out for one hidden layer
    if (h2 > 0) {
      dense_t<T, kP1, kP2>(p.w2t.data(), p.b2.data(), a1, a2, h1, h2);
      activate_all<T, kP2>(p.act, a2, h2);
      if constexpr (kGrad) {
        alignas(32) T zero[cap_h2 > 0 ? cap_h2 : kPad] = {};
        alignas(32) T lin[cap_h2 > 0 ? cap_h2 : kPad];
        dense_t<T, kP1, kP2>(p.w2t.data(), zero, t1, lin, h1, h2);  // W2 t1
        activation_slopes(p.act, a2, t2, h2);
        for (int j = 0; j < h2; ++j) t2[j] *= lin[j];
      }
      n_last = h2;
      n_last_is_a2 = true;
    }
  }
  if constexpr (kGrad) {
    const T dys = n_last_is_a2 ? dot_padded<T, kP2>(p.w_out.data(), t2, n_last)
                               : dot_padded<T, kP1>(p.w_out.data(), t1, n_last);
    *dy_dxi = dys / p.out_gain;
  }

  const T ys = p.b_out + (n_last_is_a2 ? dot_padded<T, kP2>(p.w_out.data(), a2, n_last)
                                        : dot_padded<T, kP1>(p.w_out.data(), a1, n_last));
  T out = (ys - p.out_ymin) / p.out_gain + p.out_offset;
  if (!std::isfinite(out)) {
    out = p.out_offset;
    status = DN_E_NONFINITE_OUTPUT;
  }
  *y = out;
  if (clamped_mask) *clamped_mask = mask;
  return status;
}

// Validate a description against fixed sizes (kDynamic = any) and copy it in.
template <typename T, int kIn, int kH1, int kH2, class P>
inline int load(P& p, const dn_mlp_desc* d) noexcept {
  if (!d || !d->w1 || !d->b1 || !d->w_out || !d->b_out || !d->in_offset || !d->in_gain ||
      !d->sat_lo || !d->sat_hi)
    return DN_E_NULL;
  if (d->n_inputs < 1 || d->n_inputs > DN_MAX_INPUTS || d->n_hidden1 < 1 ||
      d->n_hidden1 > DN_MAX_HIDDEN || d->n_hidden2 < 0 || d->n_hidden2 > DN_MAX_HIDDEN)
    return DN_E_SIZE;
  if ((kIn > 0 && d->n_inputs != kIn) || (kH1 > 0 && d->n_hidden1 != kH1) ||
      (kH2 >= 0 && d->n_hidden2 != kH2))
    return DN_E_MISMATCH;
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

  const int h1p = pad(h1), h2p = pad(h2);
  p.n_in = ni;
  p.n_h1 = h1;
  p.n_h2 = h2;
  p.n_h1p = h1p;
  p.n_h2p = h2p;
  p.act = static_cast<Activation>(d->activation);
  // Zero everything first: the padding must hold zeros even when a model is reloaded.
  p.w1t.fill(T(0));
  p.b1.fill(T(0));
  p.w2t.fill(T(0));
  p.b2.fill(T(0));
  p.w_out.fill(T(0));
  for (int j = 0; j < h1; ++j)
    for (int i = 0; i < ni; ++i) p.w1t[i * h1p + j] = static_cast<T>(d->w1[j * ni + i]);
  for (int j = 0; j < h1; ++j) p.b1[j] = static_cast<T>(d->b1[j]);
  for (int j = 0; j < h2; ++j)
    for (int k = 0; k < h1; ++k) p.w2t[k * h2p + j] = static_cast<T>(d->w2[j * h1 + k]);
  for (int j = 0; j < h2; ++j) p.b2[j] = static_cast<T>(d->b2[j]);
  for (int j = 0; j < n_last; ++j) p.w_out[j] = static_cast<T>(d->w_out[j]);
  p.b_out = static_cast<T>(d->b_out[0]);
  for (int i = 0; i < ni; ++i) {
    p.in_offset[i] = static_cast<T>(d->in_offset[i]);
    p.in_gain[i] = static_cast<T>(d->in_gain[i]);
    p.sat_lo[i] = static_cast<T>(d->sat_lo[i]);
    p.sat_hi[i] = static_cast<T>(d->sat_hi[i]);
  }
  p.in_ymin = static_cast<T>(d->in_ymin);
  p.out_offset = static_cast<T>(d->out_offset);
  p.out_gain = static_cast<T>(d->out_gain);
  p.out_ymin = static_cast<T>(d->out_ymin);
  return DN_OK;
}

}  // namespace detail

// Parameters of an MLP with capacities In x H1 x H2 (storage only; see load()).
template <typename T, int In, int H1, int H2>
struct MlpParams {
  static_assert(In >= 1 && In <= DN_MAX_INPUTS, "1..8 inputs");
  static_assert(H1 >= 1 && H1 <= DN_MAX_HIDDEN, "1..64 neurons in hidden layer 1");
  static_assert(H2 >= 0 && H2 <= DN_MAX_HIDDEN, "0..64 neurons in hidden layer 2");
  static constexpr int P1 = pad(H1), P2 = pad(H2);
  int n_in = 0, n_h1 = 0, n_h2 = 0;  // real sizes
  int n_h1p = 0, n_h2p = 0;          // padded sizes the loops run over
  Activation act = Activation::tanh;
  alignas(32) std::array<T, In * P1> w1t{};  // [in][h1 padded]
  alignas(32) std::array<T, P1> b1{};
  alignas(32) std::array<T, (H2 > 0 ? P1 * P2 : 0)> w2t{};  // [h1 padded][h2 padded]
  alignas(32) std::array<T, P2> b2{};
  alignas(32) std::array<T, (H2 > 0 ? P2 : P1)> w_out{};
  T b_out{};
  std::array<T, In> in_offset{}, in_gain{}, sat_lo{}, sat_hi{};
  T in_ymin{-1}, out_offset{}, out_gain{1}, out_ymin{-1};
};

// A model whose sizes are chosen at run time (up to the DN_MAX_* capacities).
template <typename T>
class Mlp {
 public:
  // Validate and copy a description; returns DN_OK or a DN_E_* error.
  int load(const dn_mlp_desc* d) noexcept {
    return detail::load<T, kDynamic, kDynamic, kDynamic>(p_, d);
  }
  // [RT] One sample; see dn_mlp_forward for the input policy.
  DN_REALTIME int forward(const T* x, T* y, uint32_t* clamped_mask = nullptr) const noexcept {
    return detail::forward<T, kDynamic, kDynamic, kDynamic>(p_, x, y, clamped_mask);
  }
  // [RT] As forward, plus dy/dx[i] (see detail::forward) in *dy_dxi.
  // An input index out of range gives dy/dx = 0.
  DN_REALTIME int forward_grad(const T* x, T* y, int i, T* dy_dxi,
                               uint32_t* clamped_mask = nullptr) const noexcept {
    if (i < 0 || i >= p_.n_in) {
      *dy_dxi = T(0);
      return forward(x, y, clamped_mask);
    }
    return detail::forward<T, kDynamic, kDynamic, kDynamic, decltype(p_), true>(p_, x, y, clamped_mask,
                                                                               i, dy_dxi);
  }
  int n_inputs() const noexcept { return p_.n_in; }
  const T* sat_lo() const noexcept { return p_.sat_lo.data(); }
  const T* sat_hi() const noexcept { return p_.sat_hi.data(); }

 private:
  MlpParams<T, DN_MAX_INPUTS, DN_MAX_HIDDEN, DN_MAX_HIDDEN> p_;
};

// A model whose sizes are compile-time constants (H2 = 0: one hidden layer).
template <typename T, int In, int H1, int H2 = 0>
class StaticMlp {
 public:
  static constexpr int kInputs = In;
  // Validate and copy a description of exactly these sizes (else DN_E_MISMATCH).
  int load(const dn_mlp_desc* d) noexcept { return detail::load<T, In, H1, H2>(p_, d); }
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

}  // namespace dampnet
