// Physics terms of hybrid dampers: one table, keyed by the kind names of
// DN_TERM_LIST (dampnet.h). Mirrored in numpy by python/dampnet/terms.py.
//
// To add a kind: one DN_TERM_LIST line in dampnet.h, and here one force
// function, one validation function, one gradient function and its reads_ and
// optional_ constants, named after the kind's id.
#pragma once

#include <cmath>
#include <cstring>
#include <limits>

#include "dampnet/dampnet.h"
#include "dampnet/float_math.hpp"
#include "dampnet/real.hpp"

namespace dampnet {

struct Term {
  int kind = 0;
  real p[DN_MAX_TERM_PARAMS] = {};
};

// A damper's terms: N of them, used as a Term pointer. None at all where the build has no terms
// (DN_CAP_TERMS 0, a microcontroller's): one unused Term is 44 B of the quarter car's 2 KB of RAM.
template <int N>
struct TermStore {
  Term t[N];
  operator Term*() noexcept { return t; }
  operator const Term*() const noexcept { return t; }
};
template <>
struct TermStore<0> {
  operator Term*() noexcept { return nullptr; }  // (read n_terms = 0 times)
  operator const Term*() const noexcept { return nullptr; }
};

namespace terms {

// ---- position_poly: F = p0 + p1 x + p2 x^2 + p3 x^3 ----
inline real force_DN_TERM_POSITION_POLY(const real* p, const dn_damper_input& in) noexcept {
  const real x = in.x;
  return p[0] + x * (p[1] + x * (p[2] + x * p[3]));
}
inline int validate_DN_TERM_POSITION_POLY(const real*) noexcept { return DN_OK; }
inline real grad_DN_TERM_POSITION_POLY(const real* p, const dn_damper_input& in, real* g) noexcept {
  const real x = in.x;
  g[0] = p[1] + x * (2 * p[2] + 3 * x * p[3]);
  g[1] = g[2] = 0;
  return force_DN_TERM_POSITION_POLY(p, in);
}
constexpr unsigned reads_DN_TERM_POSITION_POLY = 1u;  // x
constexpr int optional_DN_TERM_POSITION_POLY = 0;  // trailing params that may all be left out (then 0)

// ---- bump_stop: F = sgn(x) k (|x| - x_free)^n beyond x_free ----
inline real force_DN_TERM_BUMP_STOP(const real* p, const dn_damper_input& in) noexcept {
  const real ax = std::fabs(in.x), over = ax - p[0];
  if (!(over > 0)) return 0;
  const real f = p[1] * std::pow(over, p[2]);
  return in.x > 0 ? f : -f;
}
inline int validate_DN_TERM_BUMP_STOP(const real* p) noexcept {
  return (p[0] >= 0 && p[1] >= 0 && p[2] > 0) ? DN_OK : DN_E_PARAM;
}
inline real grad_DN_TERM_BUMP_STOP(const real* p, const dn_damper_input& in, real* g) noexcept {
  const real over = std::fabs(in.x) - p[0];
  g[0] = over > 0 ? p[1] * p[2] * std::pow(over, p[2] - 1) : real(0);  // even in x
  g[1] = g[2] = 0;
  return force_DN_TERM_BUMP_STOP(p, in);
}
constexpr unsigned reads_DN_TERM_BUMP_STOP = 1u;  // x
constexpr int optional_DN_TERM_BUMP_STOP = 0;

// ---- valve: bleed orifice + preloaded blow-off valve per direction, scaled by the control ----
// p = {v_k_ext [m/s], c_b_ext [N s^2/m^2], c_v_ext [N s/m], v_k_comp, c_b_comp, c_v_comp,
//      g_num [1/u], g_den [1/u], k_d_ext [s/m], k_d_comp [s/m]}; the formula and its bounds:
//      DN_TERM_LIST's text. The digressions k_d came later: a valve given 8 parameters (a model
//      written before them) has k_d = 0, today's straight blow-off line, bit for bit.
// F(v, u) = sgn(v) s(u) g_d(|v|), d the direction of v (ext: v > 0, comp: v < 0):
//   below the knee (w = |v| <= v_k) the bleed alone, g = c_b w^2 [N];
//   above it the valve opens: g = c_b v_k^2 + c_v z + (2 c_b v_k - c_v) v_k (1 - e),
//   e = exp(-z / v_k), z = ln(1 + k_d (w - v_k)) / k_d the opening (z = w - v_k at k_d = 0):
//   value c_b v_k^2 (the preload) and slope 2 c_b v_k at the knee (C1: dz/dw = 1 there),
//   slope c_v / (1 + k_d (w - v_k)) well above it (a shim stack's digressive opening law; the
//   straight line c_v at k_d = 0); g' = (c_v + (2 c_b v_k - c_v) e) / (1 + k_d (w - v_k)) >= 0.
//   s(u) = (1 + g_num u) / (1 + g_den u) [-], u clamped to [0, DN_TERM_VALVE_U_MAX]: g_den = 0
//   an affine gain (a current-controlled valve, harder or softer with the current); g_num <
//   g_den a force falling from 1 to g_num / g_den like the thesis's c = gamma / V + c_min.
// Bounded: |v| is clamped to DN_TERM_VALVE_V_MAX_M_S, u to its range, k_d to
// [0, DN_TERM_VALVE_K_D_MAX_S_M] (validated), NaN v gives 0, NaN u is u = 0; F is C1 in v
// everywhere below the clamp (at 0 both sides' slopes are 0).
namespace valve {
// ln(1 + x) for x >= 0 and e^-t - 1 for t >= 0: std's in double; in a float build (a
// microcontroller's float loop) dampnet::fmath's, within 4 float epsilons and about half of
// newlib's cycles on a Cortex-M4F (float_math.hpp).
inline double log1p_pos(double x) noexcept { return std::log1p(x); }
inline float log1p_pos(float x) noexcept { return fmath::log1p_f(x); }
inline double expm1_neg(double t) noexcept { return std::expm1(-t); }
inline float expm1_neg(float t) noexcept { return fmath::expm1_neg_f(t); }
// g_d(w) and g_d'(w) of one direction, w in [0, DN_TERM_VALVE_V_MAX_M_S].
inline real magnitude(real vk, real cb, real cv, real kd, real w, real* dg) noexcept {
  if (w <= vk) {
    *dg = 2 * cb * w;
    return cb * w * w;
  }
  const real d = w - vk, x = kd * d;  // x <= DN_TERM_VALVE_K_D_MAX_S_M * DN_TERM_VALVE_V_MAX_M_S
  // z = d ln(1 + x) / x and r = dz/dd; exactly d and 1 at x = 0 (k_d = 0, or x underflowing)
  const bool bends = x > 0;
  const real z = bends ? d * (log1p_pos(x) / x) : d, r = bends ? 1 / (1 + x) : real(1);
  const real one_minus_e = -expm1_neg(z / vk), m = 2 * cb * vk - cv;
  *dg = r * (cv + m * (1 - one_minus_e));
  return cb * vk * vk + cv * z + m * vk * one_minus_e;
}
// s(u) and ds/du; *d2s (nullable) d2s/du2 = -2 g_den (g_num - g_den) / (1 + g_den u)^3 (0 where u
// is clamped: s is constant there).
inline real scale(real g_num, real g_den, real u, real* ds, real* d2s = nullptr) noexcept {
  const real u_max = real(DN_TERM_VALVE_U_MAX);
  const bool inside = u > 0 && u < u_max;  // NaN: outside, as u = 0
  const real uc = inside ? u : (u >= u_max ? u_max : real(0));
  const real den = 1 + g_den * uc;
  *ds = inside ? (g_num - g_den) / (den * den) : real(0);
  if (d2s) *d2s = inside ? -2 * g_den * *ds / den : real(0);
  return (1 + g_num * uc) / den;
}
// F, and g = {dF/dx, dF/dv, dF/du}.
inline real eval(const real* p, const dn_damper_input& in, real* g) noexcept {
  g[0] = g[1] = g[2] = 0;
  const real v = in.v, v_max = real(DN_TERM_VALVE_V_MAX_M_S);
  if (!(v != 0 && v == v)) return 0;  // 0 or NaN
  const bool ext = v > 0;
  const real* q = ext ? p : p + 3;
  const real w_raw = std::fabs(v), w = w_raw < v_max ? w_raw : v_max;
  real dg = 0, ds = 0;
  const real mag = magnitude(q[0], q[1], q[2], ext ? p[8] : p[9], w, &dg), s = scale(p[6], p[7], in.u, &ds);
  const real sgn = ext ? real(1) : real(-1);
  g[1] = w_raw < v_max ? s * dg : real(0);  // even in v
  g[2] = sgn * ds * mag;
  return sgn * s * mag;
}
}  // namespace valve
inline real force_DN_TERM_VALVE(const real* p, const dn_damper_input& in) noexcept {
  real g[3];
  return valve::eval(p, in, g);
}
inline int validate_DN_TERM_VALVE(const real* p) noexcept {
  for (int d = 0; d < 6; d += 3)
    if (!(p[d] > 0) || p[d + 1] < 0 || p[d + 2] < 0) return DN_E_PARAM;
  const real kd_max = real(DN_TERM_VALVE_K_D_MAX_S_M);
  for (int d = 8; d < 10; ++d)
    if (!(p[d] >= 0 && p[d] <= kd_max)) return DN_E_PARAM;
  return (p[6] >= 0 && p[7] >= 0) ? DN_OK : DN_E_PARAM;
}
inline real grad_DN_TERM_VALVE(const real* p, const dn_damper_input& in, real* g) noexcept {
  return valve::eval(p, in, g);
}
// d2F/du2 [N/u^2] from the term's force f at `in`: F = sgn(v) s(u) g_d(|v|) reads u through s
// alone (s > 0), so F'' = f s''(u) / s(u) (valve::scale's, 0 where u is clamped).
inline real curv_u_DN_TERM_VALVE(const real* p, const dn_damper_input& in, real f) noexcept {
  real ds = 0, d2s = 0;
  const real s = valve::scale(p[6], p[7], in.u, &ds, &d2s);
  return f * d2s / s;
}
constexpr unsigned reads_DN_TERM_VALVE = 2u | 4u;  // v, u
constexpr int optional_DN_TERM_VALVE = 2;  // k_d_ext, k_d_comp: 0 (the straight line) when left out

struct KindInfo {
  const char* name;
  int n_params;      // DN_TERM_LIST's count: the most a term of the kind takes
  int min_params;    // or this many: the trailing optional_<id> ones all left out, then 0
  real (*force)(const real*, const dn_damper_input&) noexcept;
  int (*validate)(const real*) noexcept;
  // F, and g[3] = {dF/dx [N/m], dF/dv [N s/m], dF/du [N/u]} (dF/da = 0: no term reads a)
  real (*grad)(const real*, const dn_damper_input&, real*) noexcept;
  unsigned reads;  // the inputs the force reads: bit 0 x, bit 1 v, bit 2 u
  // d2F/du2 from the term's force there (CurvU; nullptr: a kind reading u without it)
  real (*curv_u)(const real*, const dn_damper_input&, real) noexcept;
};

// A kind's d2F/du2 (KindInfo::curv_u): curv_u_<id> where a kind reading u has one (the inverse's
// Halley steps use it; without it, Newton's). A kind that does not read u needs none: its 0.
template <int Kind>
struct CurvU {
  static constexpr real (*fn)(const real*, const dn_damper_input&, real) noexcept = nullptr;
};
template <>
struct CurvU<DN_TERM_VALVE> {
  static constexpr real (*fn)(const real*, const dn_damper_input&, real) noexcept = &curv_u_DN_TERM_VALVE;
};

// Indexed by dn_term_kind (values are consecutive from 0).
inline const KindInfo* table() noexcept {
  static const KindInfo t[] = {
#define DN_TERM_ROW_(id, value, name, n, text) \
  {name, n, n - optional_##id, &force_##id, &validate_##id, &grad_##id, reads_##id, CurvU<id>::fn},
      DN_TERM_LIST(DN_TERM_ROW_)
#undef DN_TERM_ROW_
  };
  return t;
}

// The kind id of a name, or -1.
inline int kind_of(const char* name) noexcept {
  if (!name) return -1;
  for (int k = 0; k < DN_N_TERM_KINDS; ++k)
    if (std::strcmp(table()[k].name, name) == 0) return k;
  return -1;
}

// Validate and fill a term from (kind name, params; each finite also in dn_real): the kind's
// n_params of them, or its min_params (the optional ones left out: 0).
inline int make(Term& t, const char* kind, const double* params, int n_params) noexcept {
  const int k = kind_of(kind);
  if (k < 0) return DN_E_UNKNOWN_NAME;
  const KindInfo& info = table()[k];
  if (n_params != info.n_params && n_params != info.min_params) return DN_E_SIZE;
  if (n_params > 0 && !params) return DN_E_NULL;
  real p[DN_MAX_TERM_PARAMS] = {};
  for (int i = 0; i < n_params; ++i) {
    p[i] = static_cast<real>(params[i]);
    if (!std::isfinite(p[i])) return DN_E_NONFINITE_PARAM;
  }
  const int st = info.validate(p);
  if (st != DN_OK) return st;
  t.kind = k;
  for (int i = 0; i < DN_MAX_TERM_PARAMS; ++i) t.p[i] = p[i];
  return DN_OK;
}

// [RT] Sum of the terms' forces.
inline real sum(const Term* ts, int n, const dn_damper_input& in) noexcept {
  real f = 0;
  for (int i = 0; i < n; ++i) f += table()[ts[i].kind].force(ts[i].p, in);
  return f;
}

// [RT] Sum of the terms' forces and g[3] = {dF/dx, dF/dv, dF/du} of the sum; *curv_u (nullable)
// its d2F/du2 [N/u^2]: 0 from the terms that do not read u, NaN when one that does has no
// curv_u.
inline real sum_grad(const Term* ts, int n, const dn_damper_input& in, real* g, real* curv_u = nullptr) noexcept {
  real f = 0;
  g[0] = g[1] = g[2] = 0;
  if (curv_u) *curv_u = 0;
  for (int i = 0; i < n; ++i) {
    real gi[3];
    const KindInfo& k_info = table()[ts[i].kind];
    const real fi = k_info.grad(ts[i].p, in, gi);
    f += fi;
    for (int k = 0; k < 3; ++k) g[k] += gi[k];
    if (curv_u && (k_info.reads & 4u))
      *curv_u += k_info.curv_u ? k_info.curv_u(ts[i].p, in, fi) : std::numeric_limits<real>::quiet_NaN();
  }
  return f;
}

// [RT] Whether the inputs the terms read (x, and v and u for a valve) are finite.
inline bool inputs_finite(const Term* ts, int n, const dn_damper_input& in) noexcept {
  unsigned reads = 0;
  for (int i = 0; i < n; ++i) reads |= table()[ts[i].kind].reads;
  return ((reads & 1u) == 0 || std::isfinite(in.x)) && ((reads & 2u) == 0 || std::isfinite(in.v)) &&
         ((reads & 4u) == 0 || std::isfinite(in.u));
}

}  // namespace terms
}  // namespace dampnet
