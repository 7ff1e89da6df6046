// Damper models behind one interface: Damper::force(input) -> force [N].
//
// Kinds (dn_damper_kind): linear, parametric (thesis eq. 1-3), lookup table,
// neural (the MLP on named features, DN_FEATURE_LIST), callback; any kind may
// carry physics terms (DN_TERM_LIST) added to its force, which makes a neural
// damper with terms the hybrid model. A Damper is a plain value of fixed size
// (no heap): the loop model holds a copy.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <type_traits>

#include "dampnet/damper_state.hpp"
#include "dampnet/dampnet.h"
#include "dampnet/mlp.hpp"
#include "dampnet/real.hpp"
#include "dampnet/terms.hpp"

// A damper's evaluations stay out of line: the loops call them from several places, and -O3
// inlining the MLP kernel into each made detail::evaluate alone 25 KB on the Cortex-M4F (where
// flash is scarce, DN_SMALL_CODE) and Damper::force_da 40 KB on the host, every kernel of every
// input count and precision in one function, against a 32 KB L1i (issue 30). DN_OUTLINE_HOST:
// out of line on the host only (the freestanding builds inline those, as before).
#if defined(__clang__)
#define DN_OUTLINE __attribute__((noinline))  // (clang has no noclone)
#elif defined(__GNUC__)
#define DN_OUTLINE __attribute__((noinline, noclone))
#else
#define DN_OUTLINE
#endif
#if defined(__GNUC__) && !(defined(DN_SMALL_CODE) && DN_SMALL_CODE)
#define DN_OUTLINE_HOST DN_OUTLINE
#else
#define DN_OUTLINE_HOST
#endif
// DN_SMALL_OUTLINE: out of line where flash is scarce only (the host inlines it, on a chain).
#if defined(DN_SMALL_CODE) && DN_SMALL_CODE
#define DN_SMALL_OUTLINE DN_OUTLINE
#else
#define DN_SMALL_OUTLINE
#endif

namespace dampnet {

namespace features {

struct Info {
  const char* name;
  real dn_damper_input::*field;
  int param;  // the dn_feature_param it needs, or DN_FPARAM_NONE
};

// Indexed by dn_feature.
inline const Info* table() noexcept {
  static const Info t[] = {
#define DN_FEATURE_ROW_(id, name, field, param) {name, &dn_damper_input::field, param},
      DN_FEATURE_LIST(DN_FEATURE_ROW_)
#undef DN_FEATURE_ROW_
  };
  return t;
}

inline int id_of(const char* name) noexcept {
  if (!name) return -1;
  for (int k = 0; k < DN_N_FEATURES; ++k)
    if (std::strcmp(table()[k].name, name) == 0) return k;
  return -1;
}

// The feature parameter (dn_feature_param) a derived feature needs, or -1 (DN_FPARAM_NONE).
inline int required_param(int id) noexcept {
  return id >= 0 && id < DN_N_FEATURES ? table()[id].param : int(DN_FPARAM_NONE);
}

inline int param_id_of(const char* name) noexcept {
  static const char* const names[] = {
#define DN_FPARAM_ROW_(id, name, text) name,
      DN_FEATURE_PARAM_LIST(DN_FPARAM_ROW_)
#undef DN_FPARAM_ROW_
  };
  if (!name) return -1;
  for (int k = 0; k < DN_N_FEATURE_PARAMS; ++k)
    if (std::strcmp(names[k], name) == 0) return k;
  return -1;
}

}  // namespace features

struct LinearParams {
  real c = 0;  // [N s/m]
};

struct TableParams {
  int n_v = 0, n_u = 0;
  real v[DN_CAP_TABLE_V] = {};
  real u[DN_CAP_TABLE_U] = {};
  real f[DN_CAP_TABLE_U * DN_CAP_TABLE_V] = {};  // [n_u][n_v]
};

// The cold inverse's first iterate (Damper::inverse_guess): a neural damper's force on a grid of
// velocity (the model's velocity range) x control (control_range), at zero acceleration, with its
// slope in the acceleration there; the other inputs at rest (x = 0, 20 degC, a lag at its source,
// Dahl 0). inverse() starts its Newton steps where the grid's force, interpolated in v and moved
// linearly in a, crosses the demand, instead of at the two limits: on the default model 2.3
// evaluations a call for 5.3 (bench/RESULTS.md). Built at set-up (set_neural_features, add_term);
// floats, as a first iterate needs no more. Every grid is the capacity's, DN_CAP_INVERSE_V x
// DN_CAP_INVERSE_U; ready false: none (not a neural damper with a velocity input and a control, a
// range that is not finite, a force that is not, or a build without: DN_CAP_INVERSE_V 0).
struct InverseGuess {
  static constexpr int kV = DN_CAP_INVERSE_V, kU = DN_CAP_INVERSE_U;
  static constexpr int kCap = kV * kU > 0 ? kV * kU : 1;
  bool ready = false;
  real v0 = 0, v_step_inv = 0;  // the first velocity [m/s], 1 / the velocity step [s/m]
  real a_lo = 0, a_hi = 0;      // the acceleration range the model reads [m/s^2] (0, 0: none)
  real u_lo = 0, u_hi = 0, u_step = 0;  // the control range and step [V or A]
  float f[kCap] = {};   // [kV][kU] force [N] at a = 0
  float fa[kCap] = {};  // [kV][kU] dF/da there [N s^2/m]
};

class Damper {
 public:
  int kind = DN_DAMPER_LINEAR;
  LinearParams lin;
  dn_parametric_params par{};
  TableParams tab;
  // neural
  MlpDouble md;  // Mlp<double>, or with DN_DOUBLE_KERNEL 0 only the sizes and ranges
  Mlp<float> mf;
  int precision = DN_PRECISION_DOUBLE;
  // mf.out_bound() [N], set by set_neural_features: the float force's rounding scale, where the
  // inverse stops (summed once, not at every call: ~190 instructions a call on a Cortex-M4F)
  float out_bound_f = 0.0f;
  int n_feat = 0;
  int accel_input = -1;  // neural: index of the "acceleration" input, or -1
  int feat[DN_MAX_INPUTS] = {};
  real fparams[DN_N_FEATURE_PARAMS > 0 ? DN_N_FEATURE_PARAMS : 1] = {};
  bool fparam_set[DN_N_FEATURE_PARAMS > 0 ? DN_N_FEATURE_PARAMS : 1] = {};
  // callback
  dn_damper_fn fn = nullptr;
  void* user = nullptr;
  // terms
  int n_terms = 0;
  TermStore<DN_CAP_TERMS> terms;
  // the cold inverse's first iterate (set-up: build_inverse_guess)
  InverseGuess guess;

  // A feature parameter's value, 0 when not set (every parameter is > 0 when set).
  real fparam(int id) const noexcept { return fparam_set[id] ? fparams[id] : real(0); }

  // ---- its state (DN_DAMPER_STATE_LIST; the formulas in damper_state.hpp) ----
  // A state moves by its dynamics when the model sets its parameter; otherwise a lag follows
  // its source and a Dahl state stays at rest.
  // Whether the model reads state k (a neural feature reads its field).
  bool state_read(int k) const noexcept {
    const features::Info* t = features::table();
    for (int i = 0; i < n_feat && kind == DN_DAMPER_NEURAL; ++i) {
      switch (k) {
#define DN_DS_READ_(id, name, unit, dyn, source, param, doc) \
  case id:                                                   \
    if (t[feat[i]].field == &dn_damper_input::name) return true; \
    break;
        DN_DAMPER_STATE_LIST(DN_DS_READ_)
#undef DN_DS_READ_
        default:
          break;
      }
    }
    return false;
  }
  // The coefficients of an interval of T > 0 seconds (a fixed-step host prepares dt / 2 and dt).
  DamperSpan span(real T) const noexcept {
    DamperSpan sp;
    real spare_keep = 0, spare_gain = 0;  // a coefficient the state's dynamics does not use
#define DN_DS_SPAN_(id, name, unit, dyn, source, param, doc)                          \
  if (fparam_set[param])                                                              \
    dynamics::Rule<dyn>::coefficients(fparams[param], T, sp.keep_slot<id>(spare_keep), \
                                      sp.gain_slot<id>(spare_gain));
    DN_DAMPER_STATE_LIST(DN_DS_SPAN_)
#undef DN_DS_SPAN_
    return sp;
  }
  // [RT] The states T after an interval's start (T of sp), from s0 there where the input was in0,
  // to the input in now (its sources x, v, u set).
  void advance(const DamperSpan& sp, const DamperState& s0, const dn_damper_input& in0,
               const dn_damper_input& in, DamperState& s) const noexcept {
#define DN_DS_ADVANCE_(id, name, unit, dyn, source, param, doc)                                  \
  s.s[id] = dynamics::Rule<dyn>::advance(fparam_set[param], s0.s[id], in0.source, in.source, \
                                         sp.keep<id>(), sp.gain<id>());
    DN_DAMPER_STATE_LIST(DN_DS_ADVANCE_)
#undef DN_DS_ADVANCE_
  }
  // [RT] Write the states into the input fields of their names.
  static void fill(const DamperState& s, dn_damper_input& in) noexcept {
#define DN_DS_FILL_(id, name, unit, dyn, source, param, doc) in.name = s.s[id];
    DN_DAMPER_STATE_LIST(DN_DS_FILL_)
#undef DN_DS_FILL_
  }
  // [RT] The states at rest with the input `at` (its sources): a lag at its source, Dahl 0.
  static DamperState rest(const dn_damper_input& at) noexcept {
    DamperState s;
#define DN_DS_REST_(id, name, unit, dyn, source, param, doc) s.s[id] = dynamics::Rule<dyn>::rest(at.source);
    DN_DAMPER_STATE_LIST(DN_DS_REST_)
#undef DN_DS_REST_
    return s;
  }
  // [RT] The states' time derivatives at input in (model exchange); 0 for a state that is off.
  void rates(const DamperState& s, const dn_damper_input& in, DamperState& ds) const noexcept {
#define DN_DS_RATE_(id, name, unit, dyn, source, param, doc) \
  ds.s[id] = fparam_set[param] ? dynamics::Rule<dyn>::rate(s.s[id], in.source, in.v, fparams[param]) : real(0);
    DN_DAMPER_STATE_LIST(DN_DS_RATE_)
#undef DN_DS_RATE_
  }

  // ---- set-up ----
  int set_linear(double c) noexcept {
    if (!kind_built(DN_DAMPER_LINEAR)) return DN_E_PARAM;  // not in this build
    const real cr = static_cast<real>(c);
    if (!std::isfinite(cr)) return DN_E_NONFINITE_PARAM;
    if (cr < 0) return DN_E_PARAM;  // negative damping feeds energy in: a runaway, never a damper
    kind = DN_DAMPER_LINEAR;
    lin.c = cr;
    return DN_OK;
  }

  int set_parametric(const dn_parametric_params* p) noexcept {
    if (!p) return DN_E_NULL;
    if (!kind_built(DN_DAMPER_PARAMETRIC)) return DN_E_PARAM;
    const real v[] = {p->c_min, p->c_max, p->gamma, p->f0, p->v_max, p->v_smooth};
    for (real x : v)
      if (!std::isfinite(x)) return DN_E_NONFINITE_PARAM;
    if (p->c_min < 0 || p->c_max < p->c_min || p->gamma < 0 || p->f0 < 0 || !(p->v_max > 0) ||
        p->v_smooth < 0)
      return DN_E_PARAM;
    kind = DN_DAMPER_PARAMETRIC;
    par = *p;
    return DN_OK;
  }

  // The grid is validated in dn_real (finite, strictly increasing after the conversion).
  int set_table(const double* vs, int n_v, const double* us, int n_u, const double* fs) noexcept {
    if (!vs || !us || !fs) return DN_E_NULL;
    if (!kind_built(DN_DAMPER_TABLE)) return DN_E_PARAM;
    if (n_v < 2 || n_v > DN_CAP_TABLE_V || n_u < 1 || n_u > DN_CAP_TABLE_U) return DN_E_SIZE;
    TableParams t;
    t.n_v = n_v;
    t.n_u = n_u;
    for (int i = 0; i < n_v; ++i) t.v[i] = static_cast<real>(vs[i]);
    for (int j = 0; j < n_u; ++j) t.u[j] = static_cast<real>(us[j]);
    for (int k = 0; k < n_u * n_v; ++k) t.f[k] = static_cast<real>(fs[k]);
    for (int i = 0; i < n_v; ++i)
      if (!std::isfinite(t.v[i])) return DN_E_NONFINITE_PARAM;
    for (int j = 0; j < n_u; ++j)
      if (!std::isfinite(t.u[j])) return DN_E_NONFINITE_PARAM;
    for (int k = 0; k < n_u * n_v; ++k)
      if (!std::isfinite(t.f[k])) return DN_E_NONFINITE_PARAM;
    for (int i = 1; i < n_v; ++i)
      if (!(t.v[i] > t.v[i - 1])) return DN_E_PARAM;
    for (int j = 1; j < n_u; ++j)
      if (!(t.u[j] > t.u[j - 1])) return DN_E_PARAM;
    kind = DN_DAMPER_TABLE;
    tab = t;
    return DN_OK;
  }

  // The MLP itself is loaded by the caller into md and mf before this.
  DN_SETUP_SIZE int set_neural_features(const char* const* names, int n, const char* const* pnames,
                          const double* pvalues, int n_params, int prec) noexcept {
    if (n > 0 && !names) return DN_E_NULL;
    if (n_params > 0 && (!pnames || !pvalues)) return DN_E_NULL;
    if (!kind_built(DN_DAMPER_NEURAL)) return DN_E_PARAM;  // not in this build
    if (n < 1 || n > DN_MAX_INPUTS || n_params < 0) return DN_E_SIZE;
    if (n != md.n_inputs()) return DN_E_MISMATCH;
    if (prec != DN_PRECISION_DOUBLE && prec != DN_PRECISION_FLOAT) return DN_E_PARAM;
    if (prec == DN_PRECISION_DOUBLE && !DN_DOUBLE_KERNEL) return DN_E_PARAM;  // float-only build
    int ids[DN_MAX_INPUTS];
    for (int i = 0; i < n; ++i) {
      ids[i] = features::id_of(names[i]);
      if (ids[i] < 0) return DN_E_UNKNOWN_NAME;
    }
    bool set[DN_N_FEATURE_PARAMS] = {};
    real vals[DN_N_FEATURE_PARAMS] = {};
    for (int i = 0; i < n_params; ++i) {
      const int id = features::param_id_of(pnames[i]);
      if (id < 0) return DN_E_UNKNOWN_NAME;
      const real value = static_cast<real>(pvalues[i]);
      if (!std::isfinite(value)) return DN_E_NONFINITE_PARAM;
      if (!(value > 0)) return DN_E_PARAM;  // time constants and lengths
      vals[id] = value;
      set[id] = true;
    }
    for (int i = 0; i < n; ++i) {
      const int need = features::required_param(ids[i]);
      if (need >= 0 && !set[need]) return DN_E_PARAM;
    }
    // Valid: only now change the damper.
    for (int i = 0; i < n; ++i) feat[i] = ids[i];
    for (int k = 0; k < DN_N_FEATURE_PARAMS; ++k) {
      fparams[k] = vals[k];
      fparam_set[k] = set[k];
    }
    kind = DN_DAMPER_NEURAL;
    n_feat = n;
    accel_input = -1;
    for (int i = 0; i < n; ++i)
      if (feat[i] == DN_FEAT_ACCELERATION) accel_input = i;
    precision = prec;
    out_bound_f = mf.out_bound();
    build_inverse_guess();
    return DN_OK;
  }

  int set_callback(dn_damper_fn f, void* u) noexcept {
    if (!f) return DN_E_NULL;
    if (!kind_built(DN_DAMPER_CALLBACK)) return DN_E_PARAM;
    kind = DN_DAMPER_CALLBACK;
    fn = f;
    user = u;
    return DN_OK;
  }

  int add_term(const char* kind_name, const double* params, int n_params) noexcept {
    if (n_terms >= DN_CAP_TERMS) return DN_E_SIZE;
    Term t;
    const int st = terms::make(t, kind_name, params, n_params);
    if (st != DN_OK) return st;
    if constexpr (DN_CAP_TERMS > 0) static_cast<Term*>(terms)[n_terms++] = t;
    build_inverse_guess();  // (the terms are part of the force)
    return DN_OK;
  }

  // Set-up (bounded: DN_CAP_INVERSE_V x DN_CAP_INVERSE_U force evaluations with their slope in
  // the acceleration, no allocation): the cold inverse's first-iterate grid (InverseGuess).
  DN_SETUP_SIZE void build_inverse_guess() noexcept {
    guess.ready = false;
    constexpr int nv = InverseGuess::kV, nu = InverseGuess::kU;
    if (nv < 2 || nu < 2 || !kind_built(DN_DAMPER_NEURAL) || kind != DN_DAMPER_NEURAL) return;
    real u_lo = 0, u_hi = 0, v_lo = 0, v_hi = 0, a_lo = 0, a_hi = 0;
    const int vi = input_reading(&dn_damper_input::v);
    if (control_range(&u_lo, &u_hi) != DN_OK || vi < 0) return;
    input_range(vi, &v_lo, &v_hi);
    if (accel_input >= 0) input_range(accel_input, &a_lo, &a_hi);
    if (!(u_hi > u_lo) || !(v_hi > v_lo) || !std::isfinite(u_hi - u_lo) || !std::isfinite(v_hi - v_lo) ||
        !std::isfinite(a_hi - a_lo))
      return;
    const real v_step = (v_hi - v_lo) / (nv - 1), u_step = (u_hi - u_lo) / (nu - 1);
    for (int i = 0; i < nv; ++i)
      for (int k = 0; k < nu; ++k) {
        dn_damper_input in{};
        in.v = i == nv - 1 ? v_hi : v_lo + i * v_step;
        in.u = k == nu - 1 ? u_hi : u_lo + k * u_step;
        in.temperature = 20;
        fill(rest(in), in);
        real f = 0, dfda = 0;
        const real a_in = 0 < a_lo ? a_lo : (0 > a_hi ? a_hi : real(0));  // (in the model's range)
        in.a = a_in;
        if (force_da(in, &f, &dfda) < 0 || !std::isfinite(f) || !std::isfinite(dfda) ||
            !(std::fabs(f) < real(3e38)) || !(std::fabs(dfda) < real(3e38)))
          return;  // (no grid: the search starts at the limits)
        guess.f[i * nu + k] = static_cast<float>(f - dfda * a_in);
        guess.fa[i * nu + k] = static_cast<float>(dfda);
      }
    guess.v0 = v_lo;
    guess.v_step_inv = 1 / v_step;
    guess.a_lo = a_lo;
    guess.a_hi = a_hi;
    guess.u_lo = u_lo;
    guess.u_hi = u_hi;
    guess.u_step = u_step;
    guess.ready = true;
  }

  // ---- evaluation ----

  // [RT] The neural inputs for an evaluation (unsaturated), into x[n_feat].
  void feature_values(const dn_damper_input& in, real* x) const noexcept {
    const features::Info* t = features::table();
#pragma GCC unroll 1
    for (int i = 0; i < n_feat; ++i) x[i] = in.*(t[feat[i]].field);  // (rolled: 1-4 inputs)
  }

  // [RT] Force [N] of the model plus its terms. feat_out (nullable) receives the
  // neural inputs. Returns DN_OK, warnings, or DN_E_NONFINITE_INPUT /
  // DN_E_NONFINITE_OUTPUT (force set to 0).
  DN_REALTIME DN_OUTLINE int force(const dn_damper_input& in, real* f, real* feat_out = nullptr,
                        uint32_t* clamped_mask = nullptr) const noexcept {
    int st = DN_OK;
    real y = 0;
    if (clamped_mask) *clamped_mask = 0;
    // A kind left out of this build (DN_DAMPER_KINDS) cannot be set, so its case is dead: the
    // `kind_built` tests let the compiler drop its code (and its libm functions) from flash.
    switch (kind) {
      case DN_DAMPER_LINEAR:
        if (!kind_built(DN_DAMPER_LINEAR)) return fail(f, DN_E_PARAM);
        if (!std::isfinite(in.v)) return fail(f, DN_E_NONFINITE_INPUT);
        y = lin.c * in.v;
        break;
      case DN_DAMPER_PARAMETRIC:
        if (!kind_built(DN_DAMPER_PARAMETRIC)) return fail(f, DN_E_PARAM);
        if (!std::isfinite(in.v) || !std::isfinite(in.u)) return fail(f, DN_E_NONFINITE_INPUT);
        y = parametric(in.v, in.u);
        break;
      case DN_DAMPER_TABLE:
        if (!kind_built(DN_DAMPER_TABLE)) return fail(f, DN_E_PARAM);
        if (!std::isfinite(in.v) || !std::isfinite(in.u)) return fail(f, DN_E_NONFINITE_INPUT);
        y = table(in.v, in.u, &st);
        break;
      case DN_DAMPER_NEURAL: {
        if (!kind_built(DN_DAMPER_NEURAL)) return fail(f, DN_E_PARAM);
        real x[DN_MAX_INPUTS];
        feature_values(in, x);
        for (int i = 0; i < n_feat; ++i)
          if (!std::isfinite(x[i])) return fail(f, DN_E_NONFINITE_INPUT);
        if (feat_out)
          for (int i = 0; i < n_feat; ++i) feat_out[i] = x[i];
        if (precision == DN_PRECISION_FLOAT) {
          float xf[DN_MAX_INPUTS], yf = 0.0f;
          for (int i = 0; i < n_feat; ++i) xf[i] = static_cast<float>(x[i]);
          st = mf.forward(xf, &yf, clamped_mask);
          y = yf;
        } else {
          st = double_forward(md, x, &y, clamped_mask);
        }
        if (st < 0) return fail(f, st);
        break;
      }
      case DN_DAMPER_CALLBACK:
        if (!kind_built(DN_DAMPER_CALLBACK)) return fail(f, DN_E_PARAM);
        y = fn(user, &in);
        break;
      default:
        return fail(f, DN_E_PARAM);
    }
    if (DN_CAP_TERMS > 0 && n_terms > 0) {
      if (!terms::inputs_finite(terms, n_terms, in)) return fail(f, DN_E_NONFINITE_INPUT);
      y += terms::sum(terms, n_terms, in);
    }
    if (!std::isfinite(y)) return fail(f, DN_E_NONFINITE_OUTPUT);
    *f = y;
    return st;
  }

  // [RT] As force(), plus dF/da [N s^2/m] of the model (terms do not depend on a):
  // analytic for a neural damper that reads the acceleration, 0 for the others.
  DN_REALTIME DN_OUTLINE_HOST int force_da(const dn_damper_input& in, real* f, real* df_da,
                           uint32_t* clamped_mask = nullptr) const noexcept {
    *df_da = 0;
    if (!kind_built(DN_DAMPER_NEURAL) || kind != DN_DAMPER_NEURAL || accel_input < 0) return force(in, f, nullptr, clamped_mask);
    if (clamped_mask) *clamped_mask = 0;
    real x[DN_MAX_INPUTS];
    feature_values(in, x);
    for (int i = 0; i < n_feat; ++i)
      if (!std::isfinite(x[i])) return fail(f, DN_E_NONFINITE_INPUT);
    real y = 0;
    int st;
    if (precision == DN_PRECISION_FLOAT) st = float_forward_grad(mf, x, n_feat, &y, accel_input, df_da, clamped_mask);
    else st = double_forward_grad(md, x, &y, accel_input, df_da, clamped_mask);
    if (st < 0) return fail(f, st);
    if (DN_CAP_TERMS > 0 && n_terms > 0) {
      if (!terms::inputs_finite(terms, n_terms, in)) return fail(f, DN_E_NONFINITE_INPUT);
      y += terms::sum(terms, n_terms, in);
    }
    if (!std::isfinite(y)) return fail(f, DN_E_NONFINITE_OUTPUT);
    *f = y;
    return st;
  }

  // force_da4 as four force_da calls (not a float neural damper reading the acceleration, or
  // an input with a non-finite feature): out of force_da4's batched code on the host.
  DN_OUTLINE_HOST void force_da_each(const dn_damper_input* in, real* f, real* df_da, int* status,
                                     uint32_t* clamped_mask) const noexcept {
    for (int b = 0; b < 4; ++b)
      status[b] = force_da(in[b], &f[b], &df_da[b], clamped_mask ? &clamped_mask[b] : nullptr);
  }

  // [RT] force_da of four inputs to this damper in one pass of the MLP kernel (a float neural
  // damper reading the acceleration: Mlp::forward_grad4; every other damper, or an input with
  // a non-finite feature, four force_da calls). Each result is identical to its own call's.
  // Nullable: clamped_mask (4).
  DN_REALTIME DN_OUTLINE_HOST void force_da4(const dn_damper_input* in, real* f, real* df_da, int* status,
                             uint32_t* clamped_mask = nullptr) const noexcept {
    bool batch = kind_built(DN_DAMPER_NEURAL) && kind == DN_DAMPER_NEURAL && accel_input >= 0 && precision == DN_PRECISION_FLOAT;
    float xf[4][DN_MAX_INPUTS] = {};
#pragma GCC unroll 1
    for (int b = 0; b < 4 && batch; ++b) {  // rolled: one copy of the features' gathering
      real x[DN_MAX_INPUTS];
      feature_values(in[b], x);
      for (int i = 0; i < n_feat; ++i) {
        if (!std::isfinite(x[i])) batch = false;
        xf[b][i] = static_cast<float>(x[i]);
      }
      if (DN_CAP_TERMS > 0 && n_terms > 0 && !terms::inputs_finite(terms, n_terms, in[b])) batch = false;
    }
    if (!batch) return force_da_each(in, f, df_da, status, clamped_mask);
    const float* xp[4] = {xf[0], xf[1], xf[2], xf[3]};
    float yf[4], gf[4];
    mf.forward_grad4(xp, yf, accel_input, gf, status, clamped_mask);
    for (int b = 0; b < 4; ++b) {
      df_da[b] = gf[b];  // as force_da, also on an error
      if (status[b] < 0) {
        f[b] = 0;
        continue;
      }
      real y = yf[b];
      if (DN_CAP_TERMS > 0 && n_terms > 0) y += terms::sum(terms, n_terms, in[b]);
      if (!std::isfinite(y)) {
        f[b] = 0;
        status[b] = DN_E_NONFINITE_OUTPUT;
        continue;
      }
      f[b] = y;
    }
  }

  // ---- the inverse: the control that gives a demanded force ----

  // The neural input reading field `field` of dn_damper_input: its index, -1 for none, -2 when
  // two inputs read it.
  int input_reading(real dn_damper_input::*field) const noexcept {
    const features::Info* t = features::table();
    int k = -1;
    for (int i = 0; i < n_feat; ++i)
      if (t[feat[i]].field == field) {
        if (k >= 0) return -2;
        k = i;
      }
    return k;
  }
  // A neural input's saturation range (the MLP's clamp) [its unit].
  void input_range(int k, real* lo, real* hi) const noexcept {
    if (precision == DN_PRECISION_FLOAT || !DN_DOUBLE_KERNEL) {  // (a float-only build: no double copy's
      *lo = static_cast<real>(mf.sat_lo()[k]);                   // ranges to convert in the step)
      *hi = static_cast<real>(mf.sat_hi()[k]);
    } else {
      *lo = static_cast<real>(md.sat_lo()[k]);
      *hi = static_cast<real>(md.sat_hi()[k]);
    }
  }

  // [RT] The cold inverse's first iterate: the control [V or A] where the first-iterate grid's
  // force at in.v (interpolated linearly; clamped to the grid) and in.a (linearly from a = 0, a
  // clamped to the model's range) crosses `demand`, linearly within the crossing cell, found by a
  // bisection over the grid's controls (log2(n_u - 1) steps, selects rather than branches): the
  // one crossing of a monotone row, one of those of a row that turns back. A demand outside the
  // row's forces at both ends: the limit whose end is nearer (u_lo or u_hi exactly). NaN without
  // a grid, or for a non-finite velocity or acceleration or a demand beyond float's range (the
  // search then starts at the limits).
  real inverse_guess(const dn_damper_input& in, real demand) const noexcept {
    const InverseGuess& g = guess;
    if constexpr (InverseGuess::kV < 2) return std::numeric_limits<real>::quiet_NaN();  // (no code)
    constexpr int nv = InverseGuess::kV > 1 ? InverseGuess::kV : 2, nu = InverseGuess::kU > 1 ? InverseGuess::kU : 2;
    if (!g.ready || !std::isfinite(demand) || !std::isfinite(in.v) || !std::isfinite(in.a))
      return std::numeric_limits<real>::quiet_NaN();
    real t = (in.v - g.v0) * g.v_step_inv;
    t = t > 0 ? (t < real(nv - 1) ? t : real(nv - 1)) : real(0);
    int i = static_cast<int>(t);
    if (i > nv - 2) i = nv - 2;
    const real w = t - real(i), a = in.a < g.a_lo ? g.a_lo : (in.a > g.a_hi ? g.a_hi : in.a);
    const float *f0 = g.f + i * nu, *f1 = f0 + nu, *s0 = g.fa + i * nu, *s1 = s0 + nu;
    // the grid's force at control k less the demand, in float (a first iterate)
    const float wf = static_cast<float>(w), af = static_cast<float>(a), df = static_cast<float>(demand);
    if (!std::isfinite(df)) return std::numeric_limits<real>::quiet_NaN();
    auto resid = [&](int k) noexcept { return (1 - wf) * (f0[k] + af * s0[k]) + wf * (f1[k] + af * s1[k]) - df; };
    float r_lo = resid(0), r_hi = resid(nu - 1);
    if ((r_lo > 0) == (r_hi > 0) || r_lo == 0 || r_hi == 0)  // beyond the row's forces: the nearer end
      return std::fabs(r_lo) <= std::fabs(r_hi) ? g.u_lo : g.u_hi;
    // (selects rather than branches: random motions would mispredict them; a vectorised count of
    // the controls short of the demand was no faster on the host and dearer on a Cortex-M4F)
    int lo = 0, hi = nu - 1;
    while (hi - lo > 1) {
      const int mid = (lo + hi) >> 1;
      const float r = resid(mid);
      const bool same = (r > 0) == (r_lo > 0);
      lo = same ? mid : lo;
      r_lo = same ? r : r_lo;
      hi = same ? hi : mid;
      r_hi = same ? r_hi : r;
    }
    real x = real(lo) + (r_lo != r_hi ? real(r_lo / (r_lo - r_hi)) : real(0.5));
    x = x > real(lo) ? (x < real(lo + 1) ? x : real(lo + 1)) : real(lo);  // (within the cell)
    const real u = g.u_lo + x * g.u_step;
    return u < g.u_hi ? u : g.u_hi;
  }

  // The control's range [u_min, u_max] (V or A, as in.u): a neural damper's saturation limits
  // of its input reading in.u (voltage or current), a parametric damper's [0, v_max], a table's
  // first and last control. *input (nullable): the neural input reading in.u, else -1.
  // DN_OK, or DN_E_MISMATCH when the force does not depend on in.u (linear; a neural damper
  // without a voltage/current input, or with two) or the range is unknown (callback).
  int control_range(real* lo, real* hi, int* input = nullptr) const noexcept {
    *lo = *hi = 0;
    if (input) *input = -1;
    switch (kind) {
      case DN_DAMPER_PARAMETRIC:
        *hi = par.v_max;
        return DN_OK;
      case DN_DAMPER_TABLE:
        if (tab.n_u < 1) return DN_E_MISMATCH;
        *lo = tab.u[0];
        *hi = tab.u[tab.n_u - 1];
        return DN_OK;
      case DN_DAMPER_NEURAL: {
        const int k = input_reading(&dn_damper_input::u);
        if (k < 0) return DN_E_MISMATCH;  // none, or two inputs read the control (-2)
        input_range(k, lo, hi);
        if (input) *input = k;
        return DN_OK;
      }
      default:
        return DN_E_MISMATCH;
    }
  }

  // [RT] The inverse: the control u in [u_min, u_max] (control_range) at which the force at the
  // input `in` (in.u ignored) equals `demand` [N]; *f the force [N] at *u.
  //  - A neural damper with its first-iterate grid (InverseGuess): inverse_near() from the grid's
  //    control (inverse_guess), so that a reachable demand usually costs two evaluations and
  //    neither limit. Without a grid, and where those steps do not settle it:
  //  - F at both limits; a demand outside [min, max] of those two (also +-Inf): the limit whose
  //    force is nearer, and DN_W_UNREACHABLE (not when equal). A flat range (u_min == u_max,
  //    or equal forces at both): u_min.
  //  - else the sign change of F(u) - demand is bracketed and narrowed by safeguarded Newton
  //    steps (dF/du analytic for a neural damper, the bracket's secant for the others; Halley's
  //    where d2F/du2 is known too, root_step): a step
  //    that leaves the bracket, or one that is not under half the last step while the bracket
  //    has not halved in two steps, is a bisection. At most DN_INVERSE_MAX_ITERS evaluations;
  //    it stops once the bracket, a step or the Newton step the last evaluation asks for is
  //    below DN_INVERSE_TOL_REL * (u_max - u_min), or |F - demand| is within the force's
  //    rounding (dn_types.h). The evaluated control with
  //    the smallest |F - demand| is returned. A model not monotone in u still gets one of the
  //    controls at which F = demand: with a grid the one found near its first iterate, even
  //    where the limits' forces do not straddle the demand; else the nearer limit.
  //  - errors: DN_E_MISMATCH (control_range), DN_E_NONFINITE_INPUT (a NaN demand or a
  //    non-finite input the model reads), the force's errors: *u the centre of the range (0
  //    without one) and *f = 0.
  // The warnings of the evaluations (DN_W_SATURATED: a motion input outside its range) are
  // OR-ed in. *n_evals (nullable): every force evaluation made, the limits' included (at most
  // DN_INVERSE_WARM_EVALS + 2 + DN_INVERSE_MAX_ITERS).
  DN_REALTIME int inverse(const dn_damper_input& in, real demand, real* u, real* f,
                                     int* n_evals = nullptr) const noexcept {
    return inverse_near(in, demand, std::numeric_limits<real>::quiet_NaN(), u, f, n_evals);
  }

  // [RT] inverse() from a control near the answer, u_start [V or A] (a controller's last
  // command): up to DN_INVERSE_WARM_EVALS Newton steps from it, on the analytic dF/du of a
  // neural damper, before any limit is evaluated. They stop as inverse()'s do (a Newton step
  // below the tolerance, or the force within its rounding of the demand); once two of them
  // straddle the demand, inverse()'s bracketed steps go on between those two. A step that
  // would leave the control range through a limit L: F(L) is evaluated (not when the step
  // starts at L); a demand between F at the step's start and F(L) is bracketed there. Else
  // (the demand may be unreachable), dF/du 0 or not finite, or the warm steps spent:
  // inverse() from the limits, reusing those the warm steps evaluated (a start at a limit, as
  // a saturated command's, costs no second evaluation there). For a model monotone in u this
  // is inverse()'s answer (to its tolerance); for one that is not, a control giving the demand
  // found near u_start is returned even where inverse() finds the demand outside the limits'
  // forces. u_start NaN or outside the range: inverse() (from the first-iterate grid's control,
  // or the limits); a damper without an analytic dF/du: the search from the limits. *n_evals
  // (nullable): every force evaluation made, the limits' included (at most
  // DN_INVERSE_WARM_EVALS + 2 + DN_INVERSE_MAX_ITERS).
  DN_REALTIME int inverse_near(const dn_damper_input& in, real demand, real u_start, real* u, real* f,
                                          int* n_evals = nullptr) const noexcept {
    int n_limits = 0, n_other = 0;
    const int st = search(in, demand, u_start, u, f, &n_limits, &n_other);
    if (n_evals) *n_evals = n_limits + n_other;
    return st;
  }

  // Set-up (bounded, no allocation): scan F on n_v x n_u points of v in [v_min, v_max] [m/s]
  // and u over control_range, the other inputs as in `at`, and report where F(u) turns back
  // against its direction at a velocity (that of F(u_max) - F(u_min), the inverse's bracket):
  // the largest fall of direction * F after a rise over the u grid, rows beyond tol_N [N]
  // counted. DN_OK; control_range's DN_E_MISMATCH; DN_E_SIZE (n_v < 1, n_u < 2, either beyond
  // DN_MONOTONICITY_MAX_GRID); DN_E_PARAM (v_min > v_max, tol_N < 0); DN_E_NONFINITE_PARAM
  // (v_min, v_max or tol_N not finite); a force's error (the scan stops, the report zeroed).
  int control_monotonicity(const dn_damper_input& at, real v_min, real v_max, int n_v, int n_u,
                           real tol_N, dn_monotonicity* rep) const noexcept {
    *rep = dn_monotonicity{};
    real lo = 0, hi = 0;
    const int st = control_range(&lo, &hi);
    if (st < 0) return st;
    if (n_v < 1 || n_u < 2 || n_v > DN_MONOTONICITY_MAX_GRID || n_u > DN_MONOTONICITY_MAX_GRID)
      return DN_E_SIZE;
    if (!std::isfinite(v_min) || !std::isfinite(v_max) || !std::isfinite(tol_N)) return DN_E_NONFINITE_PARAM;
    if (v_min > v_max || tol_N < 0) return DN_E_PARAM;
    dn_damper_input w = at;
    for (int i = 0; i < n_v; ++i) {
      w.v = n_v == 1 ? v_min : v_min + (v_max - v_min) * real(i) / real(n_v - 1);
      real f_lo = 0, f_hi = 0;
      w.u = lo;
      int s = force(w, &f_lo);
      w.u = hi;
      if (s >= 0) s = force(w, &f_hi);
      if (s < 0) {
        *rep = dn_monotonicity{};
        return s;
      }
      const real dir = f_hi >= f_lo ? real(1) : real(-1);
      real run_max = dir * f_lo, row_drop = 0, u_max_at = lo, from = lo, to = lo;
      for (int j = 1; j < n_u; ++j) {
        const real u = j == n_u - 1 ? hi : lo + (hi - lo) * real(j) / real(n_u - 1);
        real f = 0;
        w.u = u;
        s = force(w, &f);
        if (s < 0) {
          *rep = dn_monotonicity{};
          return s;
        }
        const real g = dir * f;
        if (g > run_max) run_max = g, u_max_at = u;
        if (run_max - g > row_drop) row_drop = run_max - g, from = u_max_at, to = u;
      }
      if (row_drop > tol_N) ++rep->n_reversed;
      if (row_drop > rep->reversal_N) {
        rep->reversal_N = row_drop;
        rep->v_worst = w.v;
        rep->u_from = from;
        rep->u_to = to;
      }
    }
    if (rep->n_reversed == 0) *rep = dn_monotonicity{};  // within the tolerance: monotone
    return DN_OK;
  }

  // Thesis eq. 1-3.
  real parametric(real v, real u) const noexcept {
    const real V = u < 0 ? real(0) : (u > par.v_max ? par.v_max : u);
    real c = V > 0 ? par.gamma / V + par.c_min : par.c_max;
    if (c > par.c_max) c = par.c_max;  // also +Inf from a denormal V
    if (c < par.c_min) c = par.c_min;
    real s;
    if (par.v_smooth > 0) s = std::tanh(v / par.v_smooth);
    else s = v > 0 ? 1 : (v < 0 ? -1 : 0);
    return c * v + par.f0 * s;
  }

  // Bilinear in (v, u), clamped to the grid.
  real table(real v, real u, int* st) const noexcept {
    const int nv = tab.n_v, nu = tab.n_u;
    if (v < tab.v[0] || v > tab.v[nv - 1]) {
      v = v < tab.v[0] ? tab.v[0] : tab.v[nv - 1];
      *st |= DN_W_SATURATED;
    }
    const int i = segment(tab.v, nv, v);
    const real wv = (v - tab.v[i]) / (tab.v[i + 1] - tab.v[i]);
    auto row = [&](int j) {
      const real* fr = tab.f + j * nv;
      return (1 - wv) * fr[i] + wv * fr[i + 1];  // exact at grid points
    };
    if (nu == 1) return row(0);
    if (u < tab.u[0] || u > tab.u[nu - 1]) {
      u = u < tab.u[0] ? tab.u[0] : tab.u[nu - 1];
      *st |= DN_W_SATURATED;
    }
    const int j = segment(tab.u, nu, u);
    const real wu = (u - tab.u[j]) / (tab.u[j + 1] - tab.u[j]);
    const real f0 = row(j), f1 = row(j + 1);
    return (1 - wu) * f0 + wu * f1;
  }

 private:
  // What search() evaluates F at one control with: the input (its u set per evaluation) and,
  // for a neural damper, its features but the control gathered, checked (and for a float one
  // converted) once.
  struct UCursor {
    dn_damper_input w;
    real xr[DN_MAX_INPUTS];
    float xf[DN_MAX_INPUTS];
    int ui;
    int gather_st;
    bool neural;
  };
  void start_cursor(const dn_damper_input& in, int ui, UCursor* c) const noexcept {
    c->w = in;
    c->ui = ui;
    c->gather_st = DN_OK;
    c->neural = kind_built(DN_DAMPER_NEURAL) && kind == DN_DAMPER_NEURAL && ui >= 0;
    if (!c->neural) return;
    feature_values(in, c->xr);
    for (int i = 0; i < n_feat; ++i) {
      if (i != ui && !std::isfinite(c->xr[i])) c->gather_st = DN_E_NONFINITE_INPUT;
      c->xf[i] = static_cast<float>(c->xr[i]);
    }
  }
  // [RT] F [N] at control u, and dF/du [N per V or A] and d2F/du2 [N per (V or A)^2] where the
  // model gives them analytically (a neural damper; the curvature for one hidden layer, with
  // the terms' where each that reads u has it: terms::CurvU); NaN otherwise (search() then takes
  // a secant, or Newton).
  // slope false: the force alone (the network's forward, F the same bits), d and d2 NaN.
  // Out of line where flash is scarce (DN_SMALL_CODE: search() calls it from five places).
  DN_SMALL_OUTLINE int eval_u(UCursor& c, real u, real* f, real* d, real* d2, bool slope = true) const noexcept {
    c.w.u = u;
    *d = *d2 = std::numeric_limits<real>::quiet_NaN();
    if (!c.neural) return force(c.w, f);
    if (c.gather_st < 0 || !std::isfinite(u)) return fail(f, DN_E_NONFINITE_INPUT);
    real y = 0;
    int st;
    if (precision == DN_PRECISION_FLOAT) {
      c.xf[c.ui] = static_cast<float>(u);
      float yf = 0.0f, gf = 0.0f, g2f = 0.0f;
      st = slope ? mf.forward_grad_curv(c.xf, &yf, c.ui, &gf, &g2f, nullptr) : mf.forward(c.xf, &yf, nullptr);
      y = yf;
      if (slope) *d = gf, *d2 = g2f;
    } else {
      c.xr[c.ui] = u;
      st = slope ? double_forward_grad_curv(md, c.xr, &y, c.ui, d, d2) : double_forward(md, c.xr, &y, nullptr);
    }
    if (st < 0) return fail(f, st);
    if (DN_CAP_TERMS > 0 && n_terms > 0) {  // a valve term reads u too: its slope and curvature are added
      if (!terms::inputs_finite(terms, n_terms, c.w)) return fail(f, DN_E_NONFINITE_INPUT);
      real g[3], g2 = 0;
      y += terms::sum_grad(terms, n_terms, c.w, g, &g2);
      *d += g[2];
      *d2 += g2;  // (NaN from a term reading u without its curvature: Newton's steps)
    }
    if (!std::isfinite(y)) return fail(f, DN_E_NONFINITE_OUTPUT);
    *f = y;
    return st;
  }
  // inverse() and inverse_near(): Newton steps from u_start (finite, inside the control range,
  // a neural damper reading in.u: dF/du analytic), then, unless they found the control or two
  // of them straddle the demand, the search from the limits. *n_limits: the evaluations at the
  // limits (0-2); *n_other: the others (incremented).
  DN_REALTIME DN_OUTLINE int search(const dn_damper_input& in, real demand, real u_start, real* u, real* f, int* n_limits,
                         int* n_other) const noexcept {
    real lo = 0, hi = 0;
    int ui = -1;
    int st = control_range(&lo, &hi, &ui);
    if (st < 0) {
      *u = 0;
      return fail(f, st);
    }
    const real mid = lo + (hi - lo) / 2;
    if (std::isnan(demand)) {
      *u = mid;
      return fail(f, DN_E_NONFINITE_INPUT);
    }
    const real tol = real(DN_INVERSE_TOL_REL) * (hi - lo);
    // The force's own rounding, below which a residual says nothing more about u (Newton would
    // only wander): 8 epsilons of the force (float's for a float model), and for a float model
    // at least an epsilon of the largest sum its output can make, whatever the force (the
    // default model: 2.0e-3 N; its float force jitters in u by up to 1.5e-3 N, at 25 N as at
    // 1,700 N: bench/experiments/float_force_jitter.py). The bound is kept by set_neural_features
    // (out_bound_f); the rest is computed first, off the chain (a lazy copy was slower on the
    // host and larger on the Cortex-M4F).
    const bool float_net = kind_built(DN_DAMPER_NEURAL) && kind == DN_DAMPER_NEURAL && precision == DN_PRECISION_FLOAT;
    const real eps = float_net ? real(std::numeric_limits<float>::epsilon()) : std::numeric_limits<real>::epsilon();
    const real f_round = float_net ? eps * real(out_bound_f) : real(0);
    auto rounding = [&](real fa, real fb) noexcept {
      const real r = 8 * eps * (std::fabs(fa) > std::fabs(fb) ? std::fabs(fa) : std::fabs(fb));
      return r > f_round ? r : f_round;
    };
    UCursor cur;
    start_cursor(in, ui, &cur);
    auto eval = [&](real c, real* fc, real* dc, real* d2c, bool slope = true) noexcept {
      return eval_u(cur, c, fc, dc, d2c, slope);
    };
    real a = lo, b = hi, ga = 0, gb = 0, x = mid, noise = 0;
    real best_u = mid, best_f = 0, best_g = std::numeric_limits<real>::infinity();
    bool bracketed = false;
    // Limits the warm steps evaluated (bit 0: u_min, bit 1: u_max), for the search from the limits.
    int known = 0, ks_lo = 0, ks_hi = 0;
    real kf_lo = 0, kd_lo = 0, kc_lo = 0, kf_hi = 0, kd_hi = 0, kc_hi = 0;
    auto keep_limit = [&](real at, int s, real fv, real dv, real cv) {
      if (at == lo) known |= 1, ks_lo = s, kf_lo = fv, kd_lo = dv, kc_lo = cv;
      if (at == hi) known |= 2, ks_hi = s, kf_hi = fv, kd_hi = dv, kc_hi = cv;
    };
    st = DN_OK;
    // A warm evaluation at c (counted, a limit kept, the best updated): < 0 its error, 1 the
    // force within its rounding of the demand (done), 0 go on.
    auto warm_eval = [&](real c, real* fc, real* dc, real* cc, real* gc) noexcept -> int {
      const int sc = eval(c, fc, dc, cc);
      ++*n_other;
      if (sc < 0) return sc;
      keep_limit(c, sc, *fc, *dc, *cc);
      st |= sc;
      *gc = *fc - demand;
      if (std::fabs(*gc) < std::fabs(best_g)) best_u = c, best_f = *fc, best_g = *gc;
      return std::fabs(*gc) <= rounding(*fc, 0) ? 1 : 0;
    };
    // The bracket between two evaluated controls whose residuals differ in sign, and its first
    // iterate: xn when inside it, else the secant's, else the middle.
    auto bracket = [&](real p, real fp, real gp, real q, real fq, real gq, real xn) noexcept {
      if (p < q) a = p, ga = gp, b = q, gb = gq;
      else a = q, ga = gq, b = p, gb = gp;
      noise = rounding(fp, fq);
      x = xn;
      if (!(x > a && x < b)) x = a - ga * (b - a) / (gb - ga);
      if (!(x > a && x < b)) x = a + (b - a) / 2;
      bracketed = true;
    };
    // Cold (no start inside the range): the first-iterate grid's control, when there is one.
    if (!(u_start >= lo && u_start <= hi)) u_start = inverse_guess(in, demand);
    // Warm: Newton from u_start while it stays inside the range, until it converges or two
    // evaluations straddle the demand (a bracket without the limits).
    if (cur.neural && hi > lo && u_start >= lo && u_start <= hi) {
      real px = 0, pf = 0, pg = 0;
      x = u_start;
      for (int k = 0; k < DN_INVERSE_WARM_EVALS; ++k) {
        real fx = 0, dx = 0, cx = 0, g = 0;
        const int r = warm_eval(x, &fx, &dx, &cx, &g);
        if (r < 0) {
          *u = mid;
          return fail(f, r);
        }
        if (r > 0) return found(best_u, best_f, u, f, st);
        const real xn = x + root_step(g, dx, cx);  // (dx 0 or NaN, g infinite: not finite)
        // Converged: the root within the step asked for (first: a step that has just crossed
        // the demand, as Halley's usually does, would otherwise bracket and evaluate again).
        if (xn >= lo && xn <= hi && std::fabs(xn - x) <= tol) return found(best_u, best_f, u, f, st);
        if (k > 0 && (g > 0) != (pg > 0)) {
          bracket(px, pf, pg, x, fx, g, xn);
          break;
        }
        if (xn != xn) break;  // (dx 0 or NaN)
        if (xn < lo || xn > hi) {  // toward the limit L beyond which Newton puts the demand
          const real lim = xn < lo ? lo : hi;
          if (x != lim) {
            real fl = 0, dl = 0, cl = 0, gl = 0;
            const int rl = warm_eval(lim, &fl, &dl, &cl, &gl);
            if (rl < 0) {
              *u = mid;
              return fail(f, rl);
            }
            if (rl > 0) return found(best_u, best_f, u, f, st);
            // the demand between x and L: bracketed there (first iterate: the secant)
            if ((gl > 0) != (g > 0)) bracket(x, fx, g, lim, fl, gl, std::numeric_limits<real>::quiet_NaN());
          }
          break;  // else beyond F(L) as seen from x: the other limit decides (a model may turn back)
        }
        px = x, pf = fx, pg = g;
        x = xn;
      }
    }
    if (!bracketed) {  // from the limits (those the warm steps evaluated kept), as inverse()
      st = DN_OK;
      real f_lo = kf_lo, f_hi = kf_hi, d_lo = kd_lo, d_hi = kd_hi, c_lo = kc_lo, c_hi = kc_hi;
      int s_lo = ks_lo, s_hi = ks_hi;
      // After the warm steps went out through one limit, the demand is most likely beyond it
      // (a command that stays saturated): the other limit's force alone decides, so its slope
      // is not computed (a bracket there starts from the kept limit, or the secant).
      const bool slope = known == 0;
      if (!(known & 1)) {
        s_lo = eval(lo, &f_lo, &d_lo, &c_lo, slope);
        ++*n_limits;
      }
      if (!(hi > lo)) {
        s_hi = s_lo, f_hi = f_lo, d_hi = d_lo, c_hi = c_lo;
      } else if (!(known & 2)) {
        s_hi = eval(hi, &f_hi, &d_hi, &c_hi, slope);
        ++*n_limits;
      }
      if (s_lo < 0 || s_hi < 0) {
        *u = mid;
        return fail(f, s_lo < 0 ? s_lo : s_hi);
      }
      st = s_lo | s_hi;
      a = lo, b = hi, ga = f_lo - demand, gb = f_hi - demand;
      // Outside the limits' forces (or on one of them): the nearer limit.
      if (!(hi > lo) || ga == 0 || gb == 0 || (ga > 0) == (gb > 0)) {
        const bool take_lo = !(hi > lo) || (std::isinf(demand) ? (demand > 0) == (f_lo >= f_hi)
                                                               : std::fabs(ga) <= std::fabs(gb));
        *u = take_lo ? lo : hi;
        *f = take_lo ? f_lo : f_hi;
        return (take_lo ? ga : gb) == 0 ? st : (st | DN_W_UNREACHABLE);
      }
      noise = rounding(f_lo, f_hi);
      best_u = std::fabs(ga) <= std::fabs(gb) ? a : b;
      best_f = std::fabs(ga) <= std::fabs(gb) ? f_lo : f_hi;
      best_g = std::fabs(ga) <= std::fabs(gb) ? ga : gb;
      // First iterate: Newton (Halley) from the nearer limit, else the secant through both.
      x = best_u + (best_u == a ? root_step(best_g, d_lo, c_lo) : root_step(best_g, d_hi, c_hi));
      if (!(x > a && x < b)) x = a - ga * (b - a) / (gb - ga);
      if (!(x > a && x < b)) x = a + (b - a) / 2;
    }
    real step = b - a;  // the last step's length
    real w_prev = b - a, w_prev2 = 2 * (b - a);  // the bracket one and two steps ago
    int k = 0;
    for (; k < DN_INVERSE_MAX_ITERS; ++k) {
      real fx = 0, dx = 0, cx = 0;
      const int sx = eval(x, &fx, &dx, &cx);
      if (sx < 0) break;  // (not expected: the same finite inputs as at the limits)
      st |= sx;
      const real g = fx - demand;
      if (std::fabs(g) < std::fabs(best_g)) best_u = x, best_f = fx, best_g = g;
      if (std::fabs(g) <= noise || std::fabs(step) <= tol) {
        ++k;
        break;
      }
      if ((g > 0) == (ga > 0)) a = x, ga = g;
      else b = x, gb = g;
      if (b - a <= tol) {
        ++k;
        break;
      }
      real xn = std::isfinite(dx) && dx != 0 ? x + root_step(g, dx, cx) : x - g * (b - a) / (gb - ga);
      // The root is within the step Newton (Halley) asks for (inside the bracket, converging): x is
      // within tol of it; no evaluation more to confirm.
      if (std::isfinite(dx) && std::fabs(xn - x) <= tol && xn > a && xn < b) {
        ++k;
        break;
      }
      // Newton while it stays inside and either its step is under half the last one (it is
      // converging) or the bracket has halved in two steps; else bisect.
      const bool newton = xn > a && xn < b &&
                          (std::fabs(xn - x) <= std::fabs(step) / 2 || b - a <= w_prev2 / 2);
      if (!newton) xn = a + (b - a) / 2;
      w_prev2 = w_prev;
      w_prev = b - a;
      step = xn - x;
      x = xn;
    }
    *n_other += k;
    return found(best_u, best_f, u, f, st);
  }
  // The step toward the root of g(u) (the force less the demand) with slope d and curvature c:
  // Halley's, -g / (d - g c / (2 d)), where the curvature is known and its correction to
  // Newton's step -g / d is under a half; else Newton's. (Halley's converges cubically: from a
  // controller's last command, one step usually lands within the tolerance.)
  static real root_step(real g, real d, real c) noexcept {
    const real gc = g * c, dd = d * d;  // the correction's share: gc / (2 dd)
    const real newton = -g / d, halley = -2 * g * d / (2 * dd - gc);  // (two divisions side by side)
    return std::fabs(gc) <= dd ? halley : newton;  // (false for NaN, as an infinite g or d)
  }
  static int found(real best_u, real best_f, real* u, real* f, int st) noexcept {
    *u = best_u;
    *f = best_f;
    return st;
  }
  static int fail(real* f, int st) noexcept {
    *f = 0;
    return st;
  }
  static constexpr bool kind_built(int k) noexcept { return (DN_DAMPER_KINDS >> k) & 1; }
  // The double-precision MLP on the loop's reals (a float loop converts its inputs).
  static int double_forward(const MlpDouble& m, const double* x, double* y, uint32_t* mask) noexcept {
    return m.forward(x, y, mask);
  }
  static int double_forward(const MlpDouble& m, const float* x, float* y, uint32_t* mask) noexcept {
    double xd[DN_MAX_INPUTS], yd = 0;
    for (int i = 0; i < m.n_inputs(); ++i) xd[i] = x[i];
    const int st = m.forward(xd, &yd, mask);
    *y = static_cast<float>(yd);
    return st;
  }
  // force_da's model calls, each out of line on the host (DN_OUTLINE_HOST): a damper runs one
  // precision, so the other's kernel dispatch stays out of the code its step touches.
  DN_OUTLINE_HOST static int float_forward_grad(const Mlp<float>& m, const real* x, int n, real* y, int i,
                                                real* g, uint32_t* mask) noexcept {
    float xf[DN_MAX_INPUTS], yf = 0.0f, gf = 0.0f;
    for (int k = 0; k < n; ++k) xf[k] = static_cast<float>(x[k]);
    const int st = m.forward_grad(xf, &yf, i, &gf, mask);
    *y = yf;
    *g = gf;
    return st;
  }
  static int double_forward_grad_curv(const MlpDouble& m, const double* x, double* y, int i, double* g,
                                      double* g2) noexcept {
    return m.forward_grad_curv(x, y, i, g, g2);
  }
  static int double_forward_grad_curv(const MlpDouble& m, const float* x, float* y, int i, float* g,
                                      float* g2) noexcept {
    double xd[DN_MAX_INPUTS], yd = 0, gd = 0, g2d = 0;
    for (int k = 0; k < m.n_inputs(); ++k) xd[k] = x[k];
    const int st = m.forward_grad_curv(xd, &yd, i, &gd, &g2d);
    *y = static_cast<float>(yd);
    *g = static_cast<float>(gd);
    *g2 = static_cast<float>(g2d);
    return st;
  }
  DN_OUTLINE_HOST static int double_forward_grad(const MlpDouble& m, const double* x, double* y, int i, double* g,
                                                 uint32_t* mask) noexcept {
    return m.forward_grad(x, y, i, g, mask);
  }
  DN_OUTLINE_HOST static int double_forward_grad(const MlpDouble& m, const float* x, float* y, int i, float* g,
                                                 uint32_t* mask) noexcept {
    double xd[DN_MAX_INPUTS], yd = 0, gd = 0;
    for (int k = 0; k < m.n_inputs(); ++k) xd[k] = x[k];
    const int st = m.forward_grad(xd, &yd, i, &gd, mask);
    *y = static_cast<float>(yd);
    *g = static_cast<float>(gd);
    return st;
  }
  // Index i of the grid segment [g[i], g[i+1]] holding x (g[0] <= x <= g[n-1], n >= 2).
  static int segment(const real* g, int n, real x) noexcept {
    int lo = 0, hi = n - 1;  // invariant: g[lo] <= x, and x <= g[hi]
    while (hi - lo > 1) {    // at most log2(64) = 6 iterations
      const int mid = (lo + hi) / 2;
      if (g[mid] <= x) lo = mid;
      else hi = mid;
    }
    return lo;
  }
};

}  // namespace dampnet
