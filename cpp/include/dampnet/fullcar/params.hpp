// The full car's parameters: the state's layout, the defaults, their validation, the corner
// geometry and mobility; and the step's inlining attributes (DN_FC_*). Part of fullcar.hpp.
#pragma once

#include <cmath>
#include <cstdint>

#include "dampnet/damper.hpp"
#include "dampnet/dampnet.h"
#include "dampnet/loop.hpp"

// The step's big helpers each exist once (issue 30: the code one step touches <= 16 KB, against a
// 32 KB L1i; bench/RESULTS.md "The code one full-car step calls"): -O3 would inline free_forces,
// corner_inputs, the RK4 stage, ... into the step, its stage and fc_start, a copy each; the rarely
// run paths (the report, the explicit scheme, the per-corner or batched evaluation, the Newton
// iteration a configuration does not use, the preview driver, the linear scheme's fallback and
// solve4's row exchange: DN_FC_COLD) stay out of the hot functions; loops over the corners whose
// unrolled copies cost more bytes than their rolled form costs time are rolled (#pragma GCC
// unroll 1), each row of K (f - fs) once (mobility_times). With the batched kernel's samples
// rolled too (simd_x86.hpp) and each damper precision's kernel call out of line (damper.hpp),
// 16,127 B at most at -O3 (bench/RESULTS.md "Under 16 KB"). DN_FC_OUTLINE / DN_FC_NOINLINE: out
// of line at the translation unit's -O3. (Tried: the helpers at -O2 by an optimize attribute cost
// the per-stage step ~3-4 %, and GCC 12 at -O2 fused derivative's multiply-adds into a vfmaddsub
// despite -ffp-contract=off: tests/python/test_bench_footprint.py checks that no FMA appears
// outside the MLP kernels.) DN_FC_INLINE: the
// small helpers every caller inlines.
#if defined(__clang__)
#define DN_FC_OUTLINE __attribute__((noinline))
#define DN_FC_NOINLINE __attribute__((noinline))
#define DN_FC_INLINE __attribute__((always_inline))
#define DN_FC_OUTLINE_LAMBDA  // (clang takes no attribute after a lambda's noexcept; it keeps it out of line)
#define DN_FC_COLD __attribute__((noinline, cold))
#elif defined(__GNUC__)
#define DN_FC_OUTLINE __attribute__((noinline, noclone))
#define DN_FC_NOINLINE __attribute__((noinline, noclone))
#define DN_FC_INLINE __attribute__((always_inline))
#define DN_FC_OUTLINE_LAMBDA DN_FC_OUTLINE
#define DN_FC_COLD __attribute__((noinline, noclone, cold))
#else
#define DN_FC_OUTLINE
#define DN_FC_NOINLINE
#define DN_FC_INLINE
#define DN_FC_OUTLINE_LAMBDA
#define DN_FC_COLD
#endif

namespace dampnet {

constexpr int kCorners = DN_FULLCAR_CORNERS;

enum FullCarStateIndex {
#define DN_FC_STATE_ENUM_(i, name, doc) FC_##name = i,
  DN_FULLCAR_STATE_LIST(DN_FC_STATE_ENUM_)
#undef DN_FC_STATE_ENUM_
};
enum FullCarCornerIndex {
#define DN_FC_CORNER_ENUM_(i, name, doc) FCC_##name = i,
  DN_FULLCAR_CORNER_STATE_LIST(DN_FC_CORNER_ENUM_)
#undef DN_FC_CORNER_ENUM_
};
#define DN_FC_COUNT_(i, name, doc) +1
static_assert(DN_FULLCAR_CORNER_BASE == 0 DN_FULLCAR_STATE_LIST(DN_FC_COUNT_), "corner base");
static_assert(DN_FULLCAR_CORNER_DAMPER == 0 DN_FULLCAR_CORNER_STATE_LIST(DN_FC_COUNT_), "corner damper block");
#undef DN_FC_COUNT_
static_assert(DN_FULLCAR_STATE_SIZE == DN_FULLCAR_CORNER_BASE + kCorners * DN_FULLCAR_CORNER_SIZE,
              "DN_FULLCAR_STATE_SIZE");

// Index of corner i's state k in the flat state.
constexpr int fc_corner(int i, int k) noexcept {
  return DN_FULLCAR_CORNER_BASE + i * DN_FULLCAR_CORNER_SIZE + k;
}

inline dn_fullcar_params default_fullcar() noexcept {
  dn_fullcar_params p;
#define DN_FIELD_DEF_(type, name, def, doc) p.name = def;
  DN_FULLCAR_FIELDS(DN_FIELD_DEF_)
#undef DN_FIELD_DEF_
  return p;
}

namespace detail {
#define DN_ENUM_VALUE_(id, value, name, doc) value,
inline bool is_tyre_model(int x) noexcept { return is_one_of(x, {DN_TYRE_MODEL_LIST(DN_ENUM_VALUE_)}); }
inline bool is_steer_mode(int x) noexcept { return is_one_of(x, {DN_STEER_MODE_LIST(DN_ENUM_VALUE_)}); }
#undef DN_ENUM_VALUE_
}  // namespace detail

// Validation (dn_fullcar_check, FullCarModel::init): DN_OK or a DN_E_* error.
inline int check_fullcar(const dn_fullcar_params& s) noexcept {
#define DN_CHECK_FINITE_(type, name, def, doc) \
  if (!detail::finite_field(s.name)) return DN_E_NONFINITE_PARAM;
  DN_FULLCAR_FIELDS(DN_CHECK_FINITE_)
#undef DN_CHECK_FINITE_
  const dn_fullcar_params& p = s;
  auto pos = [](double x) { return x > 0 && std::isfinite(1.0 / x); };  // > 0, not subnormal
  if (!pos(p.m_s) || !pos(p.i_xx) || !pos(p.i_yy) || !pos(p.i_zz) || !pos(p.m_us_f) ||
      !pos(p.m_us_r) || !pos(p.k_t) || !pos(p.tyre_fz0))
    return DN_E_PARAM;
  if (!(p.a > 0) || !(p.b > 0) || !(p.t_f > 0) || !(p.t_r > 0) || !(p.h_cg > 0)) return DN_E_PARAM;
  if (!(p.a + p.b <= 100) || !(p.t_f <= 10) || !(p.t_r <= 10) || !(p.h_cg <= 10)) return DN_E_PARAM;
  if (p.h_rc_f < 0 || !(p.h_rc_f < p.h_cg) || p.h_rc_r < 0 || !(p.h_rc_r < p.h_cg)) return DN_E_PARAM;
  if (p.k_s_f < 0 || p.k_s_r < 0 || p.k_arb_f < 0 || p.k_arb_r < 0 || p.c_t < 0) return DN_E_PARAM;
  if (!(p.tyre_pky1 > 0) || !(p.tyre_pky2 > 0) || !(p.tyre_mu0 > 0) || !(p.tyre_pdy2 > -1) ||
      !(p.tyre_pdy2 < 1) || !(p.tyre_c > 1) || !(p.tyre_c <= 2) || !(p.tyre_e >= -10) ||
      !(p.tyre_e <= 1))
    return DN_E_PARAM;
  if (p.speed < 0 || p.speed > 100 || p.g < 0) return DN_E_PARAM;
  if (!(p.steer_max > 0) || !(p.driver_preview_s > 0) || !(p.driver_preview_min_m > 0) ||
      !(p.driver_gain > 0) || p.driver_tau_s < 0 || !(p.driver_rate_max > 0))
    return DN_E_PARAM;
  if (!(p.dt >= kMinDt) || p.dt > 0.1) return DN_E_PARAM;
  if (!detail::stable_step<double>(p.dt, (p.k_s_f + 2 * p.k_arb_f + p.k_t) / p.m_us_f, DN_STABLE_WDT_RK4) ||
      !detail::stable_step<double>(p.dt, (p.k_s_r + 2 * p.k_arb_r + p.k_t) / p.m_us_r, DN_STABLE_WDT_RK4))
    return DN_E_PARAM;
  if (!detail::is_tyre_model(p.tyre_model) || !detail::is_steer_mode(p.steer_mode) ||
      !detail::is_damper_eval(p.damper_eval) || !detail::is_accel_feature(p.accel_feature))
    return DN_E_PARAM;
  return DN_OK;
}

// The corner positions (x_i, y_i) [m] of corner i (0 FL, 1 FR, 2 RL, 3 RR).
inline double corner_x(const dn_fullcar_params& p, int i) noexcept { return i < 2 ? p.a : -p.b; }
inline double corner_y(const dn_fullcar_params& p, int i) noexcept {
  return ((i % 2) == 0 ? 0.5 : -0.5) * (i < 2 ? p.t_f : p.t_r);
}

// The corner mobility K [1/kg]: a = a_free - K (F - f_static) (see the file comment).
inline void corner_mobility(const dn_fullcar_params& p, double K[kCorners][kCorners]) noexcept {
  for (int i = 0; i < kCorners; ++i)
    for (int j = 0; j < kCorners; ++j)
      K[i][j] = 1.0 / p.m_s + corner_x(p, i) * corner_x(p, j) / p.i_yy +
                corner_y(p, i) * corner_y(p, j) / p.i_xx +
                (i == j ? 1.0 / (i < 2 ? p.m_us_f : p.m_us_r) : 0.0);
}

}  // namespace dampnet
