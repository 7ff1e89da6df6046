// The quarter-car loop: a 2-DOF point-contact quarter car (thesis eq. 13-14)
// driven by a road, with a damper model and a controller, stepped at a fixed dt.
//
//   LoopModel   constant: vehicle parameters, a copy of the damper, controller.
//   LoopData    mutable: the flat state (DN_LOOP_STATE_LIST) and a counter.
//   step(m, d, in, out)   one step; forward(m, d, in, out) reports without advancing.
//
// Signs: z up, from static equilibrium; damper x = z_s - z_us + x_static and
// v = v_s - v_us are positive in extension; the damper force F (positive when
// resisting extension) pulls the sprung mass down and the unsprung mass up:
//   m_s  a_s  = -k_s (z_s - z_us) - (F - f_static)
//   m_us a_us =  k_s (z_s - z_us) + (F - f_static) - k_t (z_us - z_r) - c_t (v_us - v_r)
//
// Within a step the control u is held (computed by the controller from the
// state at the step start, then through the command filter when u_tau_s > 0,
// whose state u_cmd is the control of the last step); the road is the cubic Hermite interpolant of
// (z_r, v_r) at the step's start (in the state) and end (the step input); the
// lagged control follows its exact first-order response to the held u.
//
// The damper's own states (dampnet.h DN_DAMPER_STATE_LIST: control lag, velocity lag, Dahl
// friction state, ...) are its business (damper_state.hpp): the loop keeps their block at
// DN_LOOP_DAMPER_BASE and, at each evaluation, has the damper advance it from the step start
// over the time since then (half a step for RK4's middle stages) with the control held and the
// motion a ramp from the step start's.
//
// The acceleration feature: the relative acceleration a = a_s - a_us depends on
// the damper force being computed: a = a_free - k (F(a) - f_static), with
// k = 1/m_s + 1/m_us and a_free the relative acceleration with the damper
// carrying f_static. For a neural damper that reads a, the loop solves this
// coupling at every damper evaluation by default (vehicle accel_feature =
// DN_ACCEL_IMPLICIT, see dn_accel_feature in dampnet.h): g(a) = a - a_free +
// k (F(a) - f_static) = 0 by a safeguarded Newton iteration (the MLP's analytic
// slope) of at most DN_ACCEL_MAX_EVALS evaluations, starting from the explicit
// value; the force of the converged evaluation is the stage's force.
// DN_ACCEL_LINEAR takes one linearised Newton step (one evaluation). With DN_ACCEL_EXPLICIT (and
// for every other damper, including callbacks, which are never re-evaluated)
// a = a_rel(state, road, F = f_last), the equations of motion evaluated with
// the force of the most recent damper evaluation (f_last, in the state): per
// RK4 stage the previous stage's force (stage 1: the previous step's stage 4,
// at this step's start time); with one evaluation per step (DN_EVAL_PER_STEP
// or semi-implicit Euler) the previous step's force, a lag of one dt in the
// force part of a only. The explicit scheme is stable only while
// |dF/da| k < 1 (the damper's apparent mass below the reduced mass); the
// implicit one for any dF/da >= 0; the linearised one takes its step only where
// 1 + k dF/da >= DN_ACCEL_LINEAR_MIN_SLOPE and otherwise keeps the explicit value
// (DN_W_ACCEL_FALLBACK; see evaluate()).
#pragma once

#include <cmath>
#include <initializer_list>
#include <limits>
#include <type_traits>
#include <cstdint>
#include <utility>

#include "dampnet/damper.hpp"
#include "dampnet/dampnet.h"
#include "dampnet/real.hpp"

namespace dampnet {

enum StateIndex {
#define DN_STATE_ENUM_(i, name, doc) S_##name = i,
  DN_LOOP_STATE_LIST(DN_STATE_ENUM_)
#undef DN_STATE_ENUM_
};

inline dn_vehicle default_vehicle() noexcept {
  dn_vehicle v;
#define DN_FIELD_DEF_(type, name, def, doc) v.name = def;
  DN_VEHICLE_FIELDS(DN_FIELD_DEF_)
#undef DN_FIELD_DEF_
  return v;
}

inline dn_controller default_controller(int kind = DN_CTRL_PASSIVE) noexcept {
  dn_controller c;
#define DN_FIELD_DEF_(type, name, def, doc) c.name = def;
  DN_CONTROLLER_FIELDS(DN_FIELD_DEF_)
#undef DN_FIELD_DEF_
  c.kind = kind;
  return c;
}

namespace detail {
inline real clamp(real x, real lo, real hi) noexcept {
  return x < lo ? lo : (x > hi ? hi : x);
}
}  // namespace detail

// [RT] The control law (see DN_CONTROLLER_FIELDS / dn_controller_kind in dampnet.h).
// v_s, v_us absolute velocities, v = v_s - v_us; u_ext for DN_CTRL_EXTERNAL.
inline real control_law(const dn_controller& c, real v_s, real v_us, real u_ext) noexcept {
  const real v = v_s - v_us;
  real d = 0, u;
  switch (c.kind) {
    case DN_CTRL_PASSIVE:
      return detail::clamp(c.u_passive, c.u_min, c.u_max);
    case DN_CTRL_EXTERNAL:
      return detail::clamp(u_ext, c.u_min, c.u_max);
    case DN_CTRL_SKYHOOK_ONOFF:
      d = v_s * v > 0 ? 1 : 0;
      break;
    case DN_CTRL_GROUNDHOOK_ONOFF:
      d = -v_us * v > 0 ? 1 : 0;
      break;
    case DN_CTRL_SKYHOOK_CONTINUOUS:
      if (v_s * v > 0) d = detail::clamp((c.c_sky * v_s / v - c.c_min) / (c.c_max - c.c_min), 0, 1);
      break;
    case DN_CTRL_GROUNDHOOK_CONTINUOUS:
      if (-v_us * v > 0)
        d = detail::clamp((-c.c_gnd * v_us / v - c.c_min) / (c.c_max - c.c_min), 0, 1);
      break;
    default:
      break;
  }
  if (d != d) d = 1;  // only from an infinite ratio of infinities; state is finite
  u = c.u_soft + d * (c.u_hard - c.u_soft);
  return detail::clamp(u, c.u_min, c.u_max);
}

// Whether this build runs a law (DN_CONTROLLER_KINDS).
constexpr bool controller_built(int kind) noexcept {
  return kind >= 0 && kind < 32 && ((DN_CONTROLLER_KINDS >> kind) & 1);
}

// Whether a law is force-tracking: it demands a force and commands the damper's inverse of it
// (false for a law the build leaves out: the inverse's call is then dead code).
inline bool is_force_law(int kind) noexcept {
  return (controller_built(DN_CTRL_SKYHOOK_FORCE) && kind == DN_CTRL_SKYHOOK_FORCE) ||
         (controller_built(DN_CTRL_GROUNDHOOK_FORCE) && kind == DN_CTRL_GROUNDHOOK_FORCE) ||
         (controller_built(DN_CTRL_HYBRID_FORCE) && kind == DN_CTRL_HYBRID_FORCE) ||
         (controller_built(DN_CTRL_CLIPPED_OPTIMAL) && kind == DN_CTRL_CLIPPED_OPTIMAL);
}

// [RT] The force a force-tracking law demands [N] (see DN_CONTROLLER_KIND_LIST), positive
// resisting extension: v_s, v_us absolute velocities [m/s], travel = z_s - z_us [m], tyre =
// z_us - z_r [m]. 0 unless dissipative (F_d v > 0), and 0 for the other laws.
inline real force_demand(const dn_controller& c, real v_s, real v_us, real travel, real tyre) noexcept {
  const real v = v_s - v_us;
  const real sky = v_s * v > 0 ? c.c_sky * v_s : 0;
  const real gnd = -v_us * v > 0 ? -c.c_gnd * v_us : 0;
  real f = 0;
  switch (c.kind) {
    case DN_CTRL_SKYHOOK_FORCE:
      f = sky;
      break;
    case DN_CTRL_GROUNDHOOK_FORCE:
      f = gnd;
      break;
    case DN_CTRL_HYBRID_FORCE:
      f = c.alpha * sky + (1 - c.alpha) * gnd;
      break;
    case DN_CTRL_CLIPPED_OPTIMAL:
      f = c.k_travel * travel + c.k_vs * v_s + c.k_tyre * tyre + c.k_vus * v_us;
      break;
    default:
      break;
  }
  return f * v > 0 ? f : 0;  // NaN (from an overflowed product) is 0 too
}

namespace detail {
// Whether x is one of an enum list's values: is_one_of(x, {DN_..._LIST(DN_ENUM_VALUE_)}).
#define DN_ENUM_VALUE_(id, value, name, doc) value,
inline bool is_one_of(int x, std::initializer_list<int> values) noexcept {
  for (int v : values)
    if (x == v) return true;
  return false;
}
inline bool is_integrator(int x) noexcept { return is_one_of(x, {DN_INTEGRATOR_LIST(DN_ENUM_VALUE_)}); }
inline bool is_damper_eval(int x) noexcept { return is_one_of(x, {DN_DAMPER_EVAL_LIST(DN_ENUM_VALUE_)}); }
inline bool is_accel_feature(int x) noexcept {
  return is_one_of(x, {DN_ACCEL_FEATURE_LIST(DN_ENUM_VALUE_)});
}
inline bool is_controller_kind(int x) noexcept {
  return is_one_of(x, {DN_CONTROLLER_KIND_LIST(DN_ENUM_VALUE_)});
}
#undef DN_ENUM_VALUE_
}  // namespace detail

// The smallest step accepted [s]: 1 ns, far below any real loop (a 1 MHz loop is 1 us);
// below it the Hermite road's rate (dz_r / dt) and the lag coefficients lose their
// meaning, and a subnormal dt (1e-320) overflows every difference quotient.
constexpr real kMinDt = R(1e-9);

namespace detail {
// dt w <= limit with w^2 = w2 (dampnet.h DN_STABLE_WDT_*), in the caller's type: the loop's real
// (float on a microcontroller, whose FPU has no double). A product that underflows to 0 is a tiny
// dt w: stable, the right answer; one that overflows (or a NaN) is refused.
template <class T>
inline bool stable_step(T dt, T w2, T limit) noexcept {
  return dt * dt * w2 <= limit * limit;
}

// The new state of one corner within DN_PLAUSIBLE_LIST (NaN fails too): travel, wheel to road,
// damper velocity. In the loop's own type T (float on a microcontroller: no double arithmetic).
template <class T>
inline bool plausible_corner(T travel, T wheel_road, T damper_speed) noexcept {
  return std::fabs(travel) <= T(DN_PLAUSIBLE_TRAVEL_M) && std::fabs(wheel_road) <= T(DN_PLAUSIBLE_WHEEL_ROAD_M) &&
         std::fabs(damper_speed) <= T(DN_PLAUSIBLE_DAMPER_SPEED_M_S);
}

inline bool finite_field(real x) noexcept { return std::isfinite(x); }
inline bool finite_field(int) noexcept { return true; }  // enum fields: checked by value
}  // namespace detail

// Validation of a vehicle and a controller (dn_vehicle_check, dn_controller_check,
// LoopModel::init): DN_OK or a DN_E_* error. Every real field must be finite.
#define DN_CHECK_FINITE_(type, name, def, doc) \
  if (!detail::finite_field(s.name)) return DN_E_NONFINITE_PARAM;
inline int check_vehicle(const dn_vehicle& s) noexcept {
  DN_VEHICLE_FIELDS(DN_CHECK_FINITE_)
  const dn_vehicle& v = s;
  if (!(v.m_s > 0) || !(v.m_us > 0) || v.k_s < 0 || !(v.k_t > 0) || v.c_t < 0 ||
      !(v.dt >= kMinDt) || v.dt > R(0.1))
    return DN_E_PARAM;
  // a subnormal mass (1e-320 kg) is > 0 but its reciprocal overflows
  if (!std::isfinite(1 / v.m_s) || !std::isfinite(1 / v.m_us)) return DN_E_PARAM;
  if (!detail::stable_step<real>(v.dt, v.k_s / v.m_s + (v.k_s + v.k_t) / v.m_us,
                                 R(v.integrator == DN_INT_SEMI_EULER ? DN_STABLE_WDT_SEMI_EULER : DN_STABLE_WDT_RK4)))
    return DN_E_PARAM;
  if (!detail::is_integrator(v.integrator) || !detail::is_damper_eval(v.damper_eval) ||
      !detail::is_accel_feature(v.accel_feature) || !((DN_ACCEL_FEATURES >> v.accel_feature) & 1) ||
      !((DN_DAMPER_EVALS >> v.damper_eval) & 1))
    return DN_E_PARAM;
  return DN_OK;
}

inline int check_controller(const dn_controller& s) noexcept {
  DN_CONTROLLER_FIELDS(DN_CHECK_FINITE_)
  const dn_controller& c = s;
  if (!detail::is_controller_kind(c.kind) || !controller_built(c.kind)) return DN_E_PARAM;
  if (!(c.u_min <= c.u_max) || c.c_sky < 0 || c.c_gnd < 0 || c.u_tau_s < 0) return DN_E_PARAM;
  if ((c.kind == DN_CTRL_SKYHOOK_CONTINUOUS || c.kind == DN_CTRL_GROUNDHOOK_CONTINUOUS) &&
      !(c.c_max > c.c_min))
    return DN_E_PARAM;
  if (!(c.alpha >= 0 && c.alpha <= 1)) return DN_E_PARAM;
  return DN_OK;
}
#undef DN_CHECK_FINITE_

// A damper as a fixed-step host runs it, with its controller: the quarter car's one corner, and
// each of the full car's four. Constant after init.
struct Corner {
  Damper damper;
  dn_controller ctrl = default_controller();
  DamperSpan half, full;    // the damper state's update over dt / 2 and dt
  real cmd_keep = 0;        // exp(-dt / u_tau_s): the command filter; 0 = unfiltered
  bool implicit_a = false;  // solve the acceleration coupling (see dn_accel_feature)
  bool linear_a = false;    // ... by one linearised Newton step (DN_ACCEL_LINEAR)
  real f_eps = R(1e-12);    // relative force rounding of the MLP (convergence test)

  // Validate the controller and derive; DN_OK or a DN_E_* error. dt checked by the host.
  int init(const Damper& d, const dn_controller& c, real dt, int accel_feature) noexcept {
    const int st = check_controller(c);
    if (st != DN_OK) return st;
    real u_lo, u_hi;  // a force-tracking law needs a damper whose force the control sets
    if (is_force_law(c.kind) && d.control_range(&u_lo, &u_hi) != DN_OK) return DN_E_MISMATCH;
    ctrl = c;
    if (&d != &damper) damper = d;  // dn_loop_model_init_neural builds it in place
    half = d.span(R(0.5) * dt);
    full = d.span(dt);
    cmd_keep = c.u_tau_s > 0 && c.kind != DN_CTRL_EXTERNAL ? std::exp(-dt / c.u_tau_s) : 0;
    // a neural damper reading the acceleration (Damper::accel_input) couples it to the force
    implicit_a = accel_feature != DN_ACCEL_EXPLICIT && d.kind == DN_DAMPER_NEURAL && d.accel_input >= 0;
    linear_a = accel_feature == DN_ACCEL_LINEAR;
    f_eps = d.precision == DN_PRECISION_FLOAT ? R(1e-5) : R(1e-12);
    return DN_OK;
  }

  // [RT] The control over a step starting with absolute velocities v_s, v_us: the law, then the
  // command filter.
  real command(real v_s, real v_us, real u_ext, real u_cmd) const noexcept {
    return filtered(control_law(ctrl, v_s, v_us, u_ext), u_cmd);
  }
  // The command filter from u_cmd (the last step's) to the law's u, clamped again because a
  // caller's set_state may put u_cmd out of range.
  real filtered(real u, real u_cmd) const noexcept {
    return cmd_keep > 0 ? detail::clamp(u + (u_cmd - u) * cmd_keep, ctrl.u_min, ctrl.u_max) : u;
  }
  // [RT] A force-tracking law's control over a step: the damper's inverse of f_static + the
  // demand at the step start's damper input `in` (its states filled; in.u not read), from the
  // last step's command u_cmd (inverse_near: the control moves little in a step), u_soft when
  // nothing is demanded (not dissipative), then the command filter. The inverse's evaluations
  // are added to *n_evals; an inverse that fails (a runaway input) leaves the centre of the
  // range, and the force's evaluation then reports the failure.
  DN_REALTIME real command_force(const dn_damper_input& in, real f_static, real demand, real u_cmd,
                                 int64_t* n_evals) const noexcept {
    real u = ctrl.u_soft, f = 0;
    if (demand != 0) {  // no dissipative demand: the least damping, not the control nearest 0 N
      int evals = 0;    // (a damper whose force lags its velocity gives no 0 N near a reversal)
      damper.inverse_near(in, f_static + demand, u_cmd, &u, &f, &evals);
      *n_evals += evals;
    }
    return filtered(detail::clamp(u, ctrl.u_min, ctrl.u_max), u_cmd);
  }
  // The control at rest (the reset's: a filtered law starts settled; an external one at 0; a
  // force-tracking one at u_soft, control_law's d = 0: no demand at rest).
  real command_at_rest() const noexcept {
    return ctrl.kind == DN_CTRL_EXTERNAL ? 0 : control_law(ctrl, 0, 0, 0);
  }
  // [RT] The damper's states at rest with control u0 (x_static: the mid position's x).
  DamperState rest_state(real x_static, real u0) const noexcept {
    dn_damper_input at{};
    at.x = x_static;
    at.u = u0;
    return Damper::rest(at);
  }
};

// The quarter car: the vehicle around one corner.
struct LoopModel : Corner {
  dn_vehicle veh = default_vehicle();
  real inv_ms = 0, inv_mus = 0;
  real k_rel = 0;  // 1/m_s + 1/m_us: da/dF of the relative acceleration

  // Validate and derive; DN_OK or a DN_E_* error.
  int init(const dn_vehicle& v, const Damper& d, const dn_controller& c) noexcept {
    int st = check_vehicle(v);
    if (st != DN_OK) return st;
    st = Corner::init(d, c, v.dt, v.accel_feature);
    if (st != DN_OK) return st;
    veh = v;
    inv_ms = 1 / v.m_s;
    inv_mus = 1 / v.m_us;
    k_rel = inv_ms + inv_mus;
    return DN_OK;
  }
};

struct LoopData {
  real s[DN_LOOP_STATE_SIZE] = {};
  int64_t n_evals = 0;
};

namespace detail {

struct Body {
  real zs, vs, zus, vus;
};
struct Accel {
  real as, aus;
};

// Accelerations for a given applied damper force F (model force, before f_static).
inline Accel accel(const LoopModel& m, const Body& b, real zr, real vr, real F) noexcept {
  const dn_vehicle& p = m.veh;
  const real fs = p.k_s * (b.zs - b.zus);
  const real fa = F - p.f_static;
  return {(-fs - fa) * m.inv_ms,
          (fs + fa - p.k_t * (b.zus - zr) - p.c_t * (b.vus - vr)) * m.inv_mus};
}

// A damper input with every real field NaN (ints 0) before damper_input fills its own: a
// field appended to DN_DAMPER_INPUT_FIELDS for a new feature but not filled below reaches the
// model as NaN, so the step fails (DN_E_DIVERGED) instead of reading stack garbage. The
// compiler drops the stores that damper_input overwrites.
template <class T>
constexpr T unfilled_value() noexcept {
  if constexpr (std::is_floating_point_v<T>) return std::numeric_limits<T>::quiet_NaN();
  else return T{};
}
inline dn_damper_input unfilled_input() noexcept {
  dn_damper_input in;
#define DN_UNFILLED_(type, name, role, doc) in.name = unfilled_value<type>();
  DN_DAMPER_INPUT_FIELDS(DN_UNFILLED_)
#undef DN_UNFILLED_
  return in;
}

// The damper's input at one evaluation (the acceleration feature from f_last), its states
// not yet filled (see Damper::advance / fill).
inline dn_damper_input damper_input(const LoopModel& m, const Body& b, real zr, real vr,
                                    real u, real f_last, real temperature, real t, int stage) noexcept {
  const Accel a = accel(m, b, zr, vr, f_last);
  dn_damper_input in = unfilled_input();
  in.x = b.zs - b.zus + m.veh.x_static;
  in.v = b.vs - b.vus;
  in.a = a.as - a.aus;
  in.u = u;
  in.temperature = temperature;
  in.t = t;
  in.dt = m.veh.dt;
  in.stage = stage;
  return in;
}

// Inside the loop every damper input is computed from a finite state and a finite
// step input (both checked), so a non-finite damper input means the computation
// overflowed: the state is running away (a road of 1e308, a dt so small that the
// road's rate overflows, an unstable stiff step). So is a model force overflowing on
// finite inputs. Both are DN_E_DIVERGED, not an input error of the caller's (a
// callback's non-finite force is the callback's error and stays one).
inline int diverged_if_overflow(const Corner& m, int st) noexcept {
  if (st == DN_E_NONFINITE_INPUT) return DN_E_DIVERGED;
  return (st == DN_E_NONFINITE_OUTPUT && m.damper.kind != DN_DAMPER_CALLBACK) ? int(DN_E_DIVERGED)
                                                                               : st;
}

// [RT] One damper evaluation of the loop. in.a holds the explicit acceleration
// feature (from f_last) on entry and the feature actually used on return. With
// m.implicit_a the coupling g(a) = a - a_free + k (F(a) - f_static) = 0 is
// solved (see dn_accel_feature): Newton from the explicit value with the
// damper's analytic slope dF/da (forward-mode through the MLP), bisection
// whenever a sign change is bracketed and the step would leave the bracket; at
// most DN_ACCEL_MAX_EVALS evaluations. Adds the
// evaluations made to *n_evals. Returns the damper's status of the chosen
// evaluation, | DN_W_ACCEL_UNCONVERGED when the iteration did not converge.
inline int evaluate(const LoopModel& m, dn_damper_input& in, real f_last, real* f,
                    real* feat_out, uint32_t* mask, int64_t* n_evals) noexcept {
  if (!m.implicit_a) {
    *n_evals += 1;
    return diverged_if_overflow(m, m.damper.force(in, f, feat_out, mask));
  }
  const real k = m.k_rel, fs = m.veh.f_static;
  const real a_free = in.a + k * (f_last - fs);
  if (m.linear_a) {  // one Newton step with the slope, force linearised (DN_ACCEL_LINEAR)
    real f0 = 0, dfda = 0;
    uint32_t mk = 0;
    const int st = diverged_if_overflow(m, m.damper.force_da(in, &f0, &dfda, &mk));
    *n_evals += 1;
    if (mask) *mask = mk;
    const real g = in.a - a_free + k * (f0 - fs), gp = 1 + k * dfda;
    if (st < 0 || !std::isfinite(g) || !std::isfinite(gp)) {  // as the explicit scheme
      *f = f0;
      return st;
    }
    // The step's force correction is dF = -dF/da g / g'. Since |k dF/da| = |g' - 1|,
    // |dF| = |g' - 1| / g' |g| / k <= |g| / k = |F0 - f_last| exactly when g' >= 1/2: the
    // correction never exceeds the force change since the last evaluation. Below that
    // (a negative apparent mass dF/da < -m_red / 2, m_red = 1/k) it grows as 1/g' without
    // bound (issue 14's 30-400 kN spikes at g' ~ 0.02), so the step is refused and the
    // explicit value is kept: one evaluation still, and its force is a model evaluation,
    // bounded by the model's output range.
    const real a1 = in.a - g / gp;
    const bool ok = gp >= R(DN_ACCEL_LINEAR_MIN_SLOPE) && std::isfinite(a1);
    *f = ok ? f0 + dfda * (a1 - in.a) : f0;
    if (ok) in.a = a1;
    if (feat_out) m.damper.feature_values(in, feat_out);
    return ok ? st : (st | DN_W_ACCEL_FALLBACK);
  }
  if (!((DN_ACCEL_FEATURES >> DN_ACCEL_IMPLICIT) & 1)) {  // not in this build: never reached
    *n_evals += 1;  // (check_vehicle refuses it); the constant test drops the iteration below
    return diverged_if_overflow(m, m.damper.force(in, f, feat_out, mask));
  }
  struct It {
    real a, f, g, gp;  // acceleration, force, g(a), g'(a) = 1 + k dF/da
    int st;
    uint32_t mask;
  };
  int evals = 0;
  auto eval = [&](real a, It& r) noexcept -> bool {
    in.a = a;
    r.a = a;
    r.mask = 0;
    real dfda = 0;
    r.st = diverged_if_overflow(m, m.damper.force_da(in, &r.f, &dfda, &r.mask));
    ++evals;
    r.g = a - a_free + k * (r.f - fs);
    r.gp = 1 + k * dfda;
    return r.st >= 0 && std::isfinite(r.g) && std::isfinite(r.gp);
  };
  auto converged = [&](const It& r) noexcept {
    const real tol = R(1e-7) * (1 + std::fabs(a_free)) + k * m.f_eps * (1 + std::fabs(r.f));
    return std::fabs(r.g) <= tol;
  };
  It cur{}, best{}, lo{}, hi{};  // lo: a point with g < 0, hi: g > 0
  bool has_lo = false, has_hi = false, done = false;
  auto note = [&](const It& r) noexcept {
    if (r.g < 0) lo = r, has_lo = true;
    else if (r.g > 0) hi = r, has_hi = true;
    if (std::fabs(r.g) < std::fabs(best.g)) best = r;
  };
  if (!eval(in.a, cur)) {  // an error (non-finite input/output): as the explicit scheme
    *n_evals += evals;
    *f = cur.f;
    if (mask) *mask = cur.mask;
    return cur.st;
  }
  best = cur;
  note(cur);
  done = converged(cur);
  // Newton with the network's analytic slope; where g' is too small (dF/da near -1/k,
  // the coupling is nearly singular) the fixed-point step; bisection whenever a root
  // is bracketed and the step would leave the bracket.
  while (!done && evals < DN_ACCEL_MAX_EVALS) {
    real a_new;
    if (cur.gp > R(1e-3)) a_new = cur.a - cur.g / cur.gp;
    else a_new = cur.a - cur.g;
    if (has_lo && has_hi) {
      const real b0 = std::fmin(lo.a, hi.a), b1 = std::fmax(lo.a, hi.a);
      if (!(a_new > b0 && a_new < b1)) a_new = R(0.5) * (lo.a + hi.a);
    }
    if (!std::isfinite(a_new) || a_new == cur.a) break;
    It nxt;
    if (!eval(a_new, nxt)) break;
    cur = nxt;
    note(cur);
    done = converged(cur);
  }
  *n_evals += evals;
  const It& r = done ? cur : best;
  in.a = r.a;
  *f = r.f;
  if (mask) *mask = r.mask;
  if (feat_out) m.damper.feature_values(in, feat_out);
  return done ? r.st : (r.st | DN_W_ACCEL_UNCONVERGED);
}

// Everything at the step start: control, first damper evaluation, report.
struct Start {
  real u;
  real force;
  Accel acc;  // the accelerations with this force: the report's, and RK4's first stage
  dn_damper_input in;
  int status;
};

// [RT] A force-tracking law's step start: the damper's input (states filled) at the step start,
// the control its inverse gives for the law's demand (Corner::command_force), written into it.
// Out of line: the other laws' step start stays small.
DN_REALTIME DN_OUTLINE inline real force_law_start(const LoopModel& m, const Body& b, const real* s,
                                                    dn_damper_input* in, int64_t* n_evals) noexcept {
  *in = damper_input(m, b, s[S_z_r], s[S_v_r], 0, s[S_f_last], s[S_temperature], s[S_t], 0);
  Damper::fill(DamperState::load(s + DN_LOOP_DAMPER_BASE), *in);
  const real demand = force_demand(m.ctrl, b.vs, b.vus, b.zs - b.zus, b.zus - s[S_z_r]);
  // A damper reading the acceleration with the coupling solved (DN_ACCEL_IMPLICIT): the step's
  // acceleration is a_free - k_rel (F - f_static), so at the demanded force it is the explicit
  // value (from f_last) moved by -k_rel (f_static + demand - f_last). The inverse is evaluated
  // there, so that the step's solved force is the demand (the default model on the study's
  // roads: 0.0-0.2 % RMS off it, from up to 20 % at f_last's acceleration; bench/RESULTS.md,
  // bench/experiments/force_tracking.py). Not for the linearised scheme: its one Newton step from
  // the explicit value is not the solved coupling; tried, the shift tracked worse there (up to
  // 3.7 % against the 1.4 % it tracks to as it is).
  const real a_explicit = in->a;
  if (m.implicit_a && !m.linear_a) in->a -= m.k_rel * (m.veh.f_static + demand - s[S_f_last]);
  const real u = m.command_force(*in, m.veh.f_static, demand, s[S_u_cmd], n_evals);
  in->a = a_explicit;  // (the step's evaluation starts from the explicit value)
  in->u = u;
  return u;
}

// Inlined into its two callers on the host (gcc -O3 stopped inlining it when the force laws came,
// and the quarter-car HIL step paid a call and its arguments through memory); DN_SMALL_CODE
// builds (flash) leave it to the compiler.
#if defined(__GNUC__) && !(defined(DN_SMALL_CODE) && DN_SMALL_CODE)
#define DN_LOOP_START_INLINE __attribute__((always_inline))
#else
#define DN_LOOP_START_INLINE
#endif
DN_LOOP_START_INLINE inline Start start(const LoopModel& m, const real* s, real u_ext, dn_loop_out* out,
                   uint32_t* mask, int64_t* n_evals) noexcept {
  Start r;
  const Body b{s[S_z_s], s[S_v_s], s[S_z_us], s[S_v_us]};
  if (is_force_law(m.ctrl.kind)) {
    r.u = force_law_start(m, b, s, &r.in, n_evals);
  } else {  // the law's control first, then the damper's input with it
    r.u = m.command(s[S_v_s], s[S_v_us], u_ext, s[S_u_cmd]);
    r.in = damper_input(m, b, s[S_z_r], s[S_v_r], r.u, s[S_f_last], s[S_temperature], s[S_t], 0);
    Damper::fill(DamperState::load(s + DN_LOOP_DAMPER_BASE), r.in);
  }
  real* feat = nullptr;
  if (out) {
    feat = out->features;
    for (int i = 0; i < DN_MAX_INPUTS; ++i) feat[i] = 0;  // fixed length: two vector stores
  }
  r.status = evaluate(m, r.in, s[S_f_last], &r.force, feat, mask, n_evals);
  r.acc = accel(m, b, s[S_z_r], s[S_v_r], r.force);
  // A finite but huge state (e.g. from set_state) can overflow the accelerations or the
  // relative motion: a runaway, and no report may be non-finite with a success status
  // (a sum is non-finite when any term is, or when it overflows).
  if (r.status >= 0 && !std::isfinite(r.acc.as + r.acc.aus + r.in.a + r.in.x + r.in.v))
    r.status = DN_E_DIVERGED;
  if (out) {
    out->force = r.force;
    out->u = r.u;
    out->x = r.in.x;
    out->v = r.in.v;
    out->a = r.in.a;
    out->acc_s = r.acc.as;
    out->acc_us = r.acc.aus;
    out->n_features = m.damper.kind == DN_DAMPER_NEURAL ? m.damper.n_feat : 0;
    out->clamped_mask = mask ? *mask : 0u;
  }
  return r;
}
#undef DN_LOOP_START_INLINE

}  // namespace detail

// [RT] Reset to rest (see dn_loop_reset).
inline void reset(const LoopModel& m, LoopData& d) noexcept {
  for (real& x : d.s) x = 0;
  d.s[S_u_cmd] = m.command_at_rest();
  d.s[S_f_last] = m.veh.f_static;
  d.s[S_temperature] = m.veh.temperature;
  m.rest_state(m.veh.x_static, d.s[S_u_cmd]).store(d.s + DN_LOOP_DAMPER_BASE);
}

// [RT] What step() would report, without advancing.
DN_REALTIME inline int forward(const LoopModel& m, const LoopData& d, const dn_loop_input& in,
                               dn_loop_out* out) noexcept {
  if (!std::isfinite(in.u) && m.ctrl.kind == DN_CTRL_EXTERNAL) return DN_E_NONFINITE_INPUT;
  uint32_t mask = 0;
  int64_t n_evals = 0;
  const detail::Start r = detail::start(m, d.s, in.u, out, &mask, &n_evals);
  return r.status;
}

// [RT] One step (see the file comment and dn_loop_step).
DN_REALTIME inline int step(const LoopModel& m, LoopData& d, const dn_loop_input& in,
                            dn_loop_out* out) noexcept {
  using detail::Accel;
  using detail::Body;
  if (!std::isfinite(in.z_r) || !std::isfinite(in.v_r)) return DN_E_NONFINITE_INPUT;
  if (m.ctrl.kind == DN_CTRL_EXTERNAL && !std::isfinite(in.u)) return DN_E_NONFINITE_INPUT;
  const real* s = d.s;
  const real h = m.veh.dt;
  uint32_t mask = 0;
  const detail::Start r = detail::start(m, s, in.u, out, &mask, &d.n_evals);
  int status = r.status;
  if (status < 0) return status;

  const real u = r.u, t0 = s[S_t];
  const real temp = s[S_temperature];
  const real zr0 = s[S_z_r], vr0 = s[S_v_r], zr1 = in.z_r, vr1 = in.v_r;
  const Body b0{s[S_z_s], s[S_v_s], s[S_z_us], s[S_v_us]};
  const DamperState ds0 = DamperState::load(s + DN_LOOP_DAMPER_BASE);
  real ns[DN_LOOP_STATE_SIZE];
  for (int i = 0; i < DN_LOOP_STATE_SIZE; ++i) ns[i] = s[i];
  real f_last = r.force;

  if (m.veh.integrator == DN_INT_SEMI_EULER) {
    ns[S_v_s] = b0.vs + h * r.acc.as;
    ns[S_v_us] = b0.vus + h * r.acc.aus;
    ns[S_z_s] = b0.zs + h * ns[S_v_s];
    ns[S_z_us] = b0.zus + h * ns[S_v_us];
  } else {
    // road at mid-step: cubic Hermite of (zr0, vr0) -> (zr1, vr1)
    const real zrm = R(0.5) * (zr0 + zr1) + R(0.125) * h * (vr0 - vr1);
    const real vrm = R(1.5) * (zr1 - zr0) / h - R(0.25) * (vr0 + vr1);
    const bool per_stage = ((DN_DAMPER_EVALS >> DN_EVAL_PER_STAGE) & 1) && m.veh.damper_eval == DN_EVAL_PER_STAGE;
    // A stage's force: evaluated per stage, else the step start's (tested at the call sites, so
    // a per-step loop makes no call: the Cortex-M4F build keeps the lambda out of line).
    auto force_at = [&](const Body& b, real zr, real vr, real t, int stage) noexcept -> real {
      dn_damper_input di = detail::damper_input(m, b, zr, vr, u, f_last, temp, t, stage);
      DamperState ds;
      m.damper.advance(stage < 3 ? m.half : m.full, ds0, r.in, di, ds);
      Damper::fill(ds, di);
      real f = 0;
      const int st = detail::evaluate(m, di, f_last, &f, nullptr, nullptr, &d.n_evals);
      if (st < 0) status = st;
      else status |= st;
      f_last = f;
      return f;
    };
    const Accel& k1 = r.acc;
    const Body b1{b0.zs + R(0.5) * h * b0.vs, b0.vs + R(0.5) * h * k1.as, b0.zus + R(0.5) * h * b0.vus,
                  b0.vus + R(0.5) * h * k1.aus};
    const Accel k2 = detail::accel(m, b1, zrm, vrm, per_stage ? force_at(b1, zrm, vrm, t0 + R(0.5) * h, 1) : r.force);
    const Body b2{b0.zs + R(0.5) * h * b1.vs, b0.vs + R(0.5) * h * k2.as, b0.zus + R(0.5) * h * b1.vus,
                  b0.vus + R(0.5) * h * k2.aus};
    const Accel k3 = detail::accel(m, b2, zrm, vrm, per_stage ? force_at(b2, zrm, vrm, t0 + R(0.5) * h, 2) : r.force);
    const Body b3{b0.zs + h * b2.vs, b0.vs + h * k3.as, b0.zus + h * b2.vus, b0.vus + h * k3.aus};
    const Accel k4 = detail::accel(m, b3, zr1, vr1, per_stage ? force_at(b3, zr1, vr1, t0 + h, 3) : r.force);
    if (status < 0) return status;
    const real h6 = h / 6;
    ns[S_z_s] = b0.zs + h6 * (b0.vs + 2 * b1.vs + 2 * b2.vs + b3.vs);
    ns[S_v_s] = b0.vs + h6 * (k1.as + 2 * k2.as + 2 * k3.as + k4.as);
    ns[S_z_us] = b0.zus + h6 * (b0.vus + 2 * b1.vus + 2 * b2.vus + b3.vus);
    ns[S_v_us] = b0.vus + h6 * (k1.aus + 2 * k2.aus + 2 * k3.aus + k4.aus);
  }
  ns[S_t] = t0 + h;
  ns[S_z_r] = zr1;
  ns[S_v_r] = vr1;
  ns[S_u_cmd] = u;
  ns[S_f_last] = f_last;
  // The damper's states at the step's end: its motion there, the control held.
  dn_damper_input end = r.in;
  end.x = ns[S_z_s] - ns[S_z_us] + m.veh.x_static;
  end.v = ns[S_v_s] - ns[S_v_us];
  DamperState ds1;
  m.damper.advance(m.full, ds0, r.in, end, ds1);
  ds1.store(ns + DN_LOOP_DAMPER_BASE);
  // Only the integrated states can run away (time, road, control and force are finite
  // here); a sum is non-finite when any term is (or when it overflows: diverged too).
  real check = ns[S_z_s] + ns[S_v_s] + ns[S_z_us] + ns[S_v_us];
  for (int k = 0; k < DN_DAMPER_STATE_SIZE; ++k) check += ds1.s[k];
  if (!std::isfinite(check)) return DN_E_DIVERGED;
  if (!detail::plausible_corner(ns[S_z_s] - ns[S_z_us], ns[S_z_us] - zr1, ns[S_v_s] - ns[S_v_us]))
    return DN_E_DIVERGED;  // a runaway: beyond any car (dampnet.h DN_PLAUSIBLE_LIST)
  for (int i = 0; i < DN_LOOP_STATE_SIZE; ++i) d.s[i] = ns[i];
  return status;
}

}  // namespace dampnet
