// The full vehicle: a ride-and-handling model with four dampers (the thesis's chapter 5.2),
// beside the quarter-car loop and built like it (loop.hpp):
//
//   FullCarModel   constant: parameters, per corner a Corner (loop.hpp: its damper copy with the
//                  damper state's step coefficients, its controller), the corner-mobility
//                  matrix, the driver's path.
//   FullCarData    mutable: the flat state (DN_FULLCAR_STATE_LIST + corners) and a counter.
//   step(m, d, in, out)   one step; forward(m, d, in, out) reports without advancing.
//
// Frame ISO 8855: x forward, y left, z up. Corners i = 0 FL, 1 FR, 2 RL, 3 RR at
// x_i = +a (front) / -b (rear), y_i = +t/2 (left) / -t/2 (right). Body heave z (at the CG),
// roll phi (positive lifts the left side), pitch theta (positive pushes the nose down), all
// from static equilibrium; small-angle kinematics for the suspension:
//   z_b,i = z + y_i phi - x_i theta,   v_b,i = vz + y_i p - x_i q
// Damper i as the quarter car's: x_i = z_b,i - z_us,i + x_static, v_i = v_b,i - v_us,i
// (extension positive), force F_i positive resisting extension.
//
// Forces (from static equilibrium; d_i = z_b,i - z_us,i the suspension deflection):
//   F_arb,i = k_arb (d_i - d_j)              j the other wheel of i's axle
//   F_s,i   = -k_s d_i - (F_i - f_static) - F_arb,i          upward on the body at corner i
//   F_tz,i  = max(-k_t (z_us,i - z_r,i) - c_t (v_us,i - v_r,i), -N0_i)   upward on wheel i
//   N_i     = N0_i + F_tz,i >= 0   (lift-off), N0_i = g (m_s c_i + m_us,i) the static load,
//             c_i = b / (2 L) front, a / (2 L) rear, L = a + b
// Lateral tyre force per wheel, from the axle's slip angle (alpha_f, alpha_r below; track effect
// on slip ignored):
//   magic_formula: K(N) = pky1 Fz0 sin(2 atan(N / (pky2 Fz0))), D = mu0 (1 + pdy2 dfz) N,
//     dfz = (N - Fz0) / Fz0, B = K / (C D), Fy = D sin(C atan(B alpha - E (B alpha -
//     atan(B alpha)))); Fy = 0 when N = 0
//   linear: Fy = K(N0_i) alpha (0 when N = 0)
// Lateral and yaw at the constant forward speed U of the whole car (m = m_s + sum m_us, its CG
// a_h = a - x_m behind the front axle and b_h = b + x_m ahead of the rear one, x_m = 2 (m_us_f a -
// m_us_r b) / m: the unsprung masses at the axles, as the static loads N0_i put them; vy, r, X,
// Y, psi and a_y are that point's; i_zz about it):
//   alpha_f = delta - atan((vy + a_h r) / U),   alpha_r = -atan((vy - b_h r) / U)
//   Fy_f = (Fy_0 + Fy_1) cos delta,  Fy_r = Fy_2 + Fy_3
//   m (vy' + U r) = Fy_f + Fy_r,  a_y = vy' + U r,  i_zz r' = a_h Fy_f - b_h Fy_r
//   psi' = r,  X' = U cos psi - vy sin psi,  Y' = U sin psi + vy cos psi
//   With U = 0 these are frozen (Fy = 0, all their rates 0).
// Sprung mass, roll about the roll axis (the lateral forces act at the roll centres: the
// roll-axis model; h = h_cg - (b h_rc_f + a h_rc_r) / L the CG's height above the axis):
//   m_s z''      = sum F_s,i
//   i_yy theta'' = sum (-x_i) F_s,i
//   i_xx phi''   = sum y_i F_s,i + m_s h a_y + m_s g h phi
// Wheels, with the links' geometric load transfer Fy_axle h_rc / t per axle (a left turn,
// Fy > 0, lifts the left wheel and pushes the right, outside, one into the road):
//   m_us,i z_us,i'' = -F_s,i + F_tz,i + F_geo,i,  F_geo = +Fy_axle h_rc / t left, - right
//
// Acceleration feature (neural dampers reading "acceleration"): a_i = z_b,i'' - z_us,i''.
// The four are coupled to the four damper forces by the constant corner mobility
//   K_ij = G_ij + delta_ij / m_us,i,  G_ij = 1/m_s + x_i x_j / i_yy + y_i y_j / i_xx,
//   a = a_free - K (F - f_static)
// (a_free with every damper at f_static). accel_feature, the quarter car's in vector form:
//   EXPLICIT  a from f_last (the most recent evaluations' forces).
//   LINEAR    one evaluation per corner with its slope D_i = dF_i/da_i, one Newton step of
//             (I + K D) da = -g(a0), g(a) = a - a_free + K (F(a) - f_static), forces
//             linearised F0 + D da; taken when every 1 + K_ii D_i >= DN_ACCEL_LINEAR_MIN_SLOPE
//             and the step is finite, else the explicit forces and DN_W_ACCEL_FALLBACK.
//   IMPLICIT  Newton steps with fresh evaluations until every |g_i| <= 1e-7 (1 + |a_free,i|)
//             + K_ii eps (1 + |F_i|), at most DN_ACCEL_MAX_EVALS evaluations per corner;
//             not converged: the iterate of the smallest max |g_i|, DN_W_ACCEL_UNCONVERGED.
//   Corners whose damper does not read a (and callbacks) keep their explicit force; their
//   slope is 0 in the system.
//
// Within a step, as the quarter car: controls held (each corner's law and command filter at
// the step start), steering held (driver or input, then its lag), road per corner the cubic
// Hermite interpolant between the step's start and end, RK4 (damper_eval per_stage: four
// evaluations per corner; per_step: one, forces held, and the tyres' lateral forces too:
// the real-time configuration, first order in the forces). Open loop: the input's angle,
// clamped to +-steer_max, through a first-order lag driver_tau_s sampled per step:
// delta = delta_cmd + (delta_prev - delta_cmd) exp(-dt/tau).
// Driver (steer_mode driver): MacAdam's optimal preview control (IEEE Trans. SMC-11(6), 1981;
// CarSim's driver), discrete preview form: the command held over the preview window that
// minimises the squared lateral path error at kDriverPoints points t_j = j T / kDriverPoints,
// j = 1..kDriverPoints, equally weighted. Its internal model, built at init: the linear single
// track at speed U (mass m, i_zz, axle cornering stiffnesses C_f = K(N0_0) + K(N0_1), C_r
// likewise) with the steering lag, state w = (y, psi, vy, r, delta) in the frame of the current
// heading, input delta_cmd held:
//   y' = U psi + vy, psi' = r, m (vy' + U r) = C_f alpha_f + C_r alpha_r,
//   i_zz r' = a_h C_f alpha_f - b_h C_r alpha_r, delta' = (delta_cmd - delta) / tau
// (linear slips). T = max(driver_preview_s, driver_preview_min_m / U). At t_j the predicted
// lateral offset is y_j = c_j . (vy, r, delta) + g_j delta_cmd (exp of the augmented 6 x 6
// matrix [[A, B], [0, 0]] t_j). Per step: preview points P_j = (X + U t_j cos psi, Y + U t_j
// sin psi), e_j = cos psi (Y_path(P_j,x) - P_j,y) the path's offset there across the heading;
// least squares: delta_cmd = driver_gain sum_j g_j (e_j - c_j . w) / sum_j g_j^2, i.e.
// sum_j k_j e_j - kc . (vy, r, delta_prev) with k_j, kc precomputed; clamped to +-steer_max;
// then the lag as above, then the rate limit |delta - delta_prev| <= driver_rate_max dt.
//
// Limits: small angles in the suspension kinematics; no longitudinal dynamics (constant
// speed, no pitch from braking); the roll centres are fixed; slip per axle, not per wheel;
// no tyre relaxation length; the unsprung masses have no roll inertia of their own.
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

struct FullCarModel {
  dn_fullcar_params p = default_fullcar();
  Corner corner[kCorners];  // damper copy with its state's coefficients, controller
  double xc[kCorners] = {}, yc[kCorners] = {};  // corner positions [m]
  double xs[kCorners] = {};  // x_static per corner: the damper's x at static equilibrium [m]
  double ks[kCorners] = {}, inv_mus[kCorners] = {}, n0[kCorners] = {}, k_lin[kCorners] = {};
  double fs[kCorners] = {};  // f_static per corner [N]
  double karb[2] = {}, geo[2] = {};  // per axle: ARB rate, h_rc / t
  double K[kCorners][kCorners] = {};  // corner mobility [1/kg]
  double inv_ms = 0, inv_ixx = 0, inv_iyy = 0, inv_izz = 0, inv_m = 0;
  double h_roll = 0;  // CG height above the roll axis [m]
  double a_h = 0, b_h = 0;  // the whole car's CG (unsprung masses included) to the axles [m]
  double steer_keep = 0;  // exp(-dt / driver_tau_s); 0 = no lag
  // The preview driver (steer_mode driver, speed > 0; see the file comment), set at init:
  static constexpr int kDriverPoints = 8;
  double drv_l[kDriverPoints] = {};  // preview distances U t_j [m]
  double drv_k[kDriverPoints] = {};  // command per path offset at each point [rad/m]
  double drv_kc[3] = {};  // command per vy [rad s/m], r [s], delta [-]
  double drv_step = 0;    // driver_rate_max dt: the largest change of the angle in a step [rad]
  double drv_alpha = 0;   // the front tyres' slip angle of peak force at the static load [rad]
                          // (Magic Formula; 0: no limit, the linear tyre)
  bool any_implicit = false;  // some corner's damper reads a and accel_feature != explicit
  // The four corners share one damper object (the same dn_damper / Damper passed four times)
  // whose model is a float MLP reading a: its four evaluations go through the kernel in one
  // pass (Damper::force_da4), each result identical to four single calls.
  bool batch4 = false;
  int n_path = 0;
  double path_x[DN_FULLCAR_MAX_PATH] = {}, path_y[DN_FULLCAR_MAX_PATH] = {};

  // Validate and derive; DN_OK or a DN_E_* error. dampers and ctrls: 4 each.
  int init(const dn_fullcar_params& v, const Damper* const* dampers, const dn_controller* ctrls,
           const double* px, const double* py, int np) noexcept {
    int st = check_fullcar(v);
    if (st != DN_OK) return st;
    if (np < 0 || np > DN_FULLCAR_MAX_PATH || np == 1) return DN_E_SIZE;
    if (v.steer_mode == DN_STEER_DRIVER && np < 2) return DN_E_PARAM;
    if (np > 0 && (!px || !py)) return DN_E_NULL;
    for (int k = 0; k < np; ++k) {
      if (!std::isfinite(px[k]) || !std::isfinite(py[k])) return DN_E_NONFINITE_PARAM;
      if (k > 0 && !(px[k] > px[k - 1])) return DN_E_PARAM;
    }
    p = v;
    n_path = np;
    for (int k = 0; k < np; ++k) path_x[k] = px[k], path_y[k] = py[k];
    const double L = v.a + v.b;
    inv_ms = 1.0 / v.m_s;
    inv_ixx = 1.0 / v.i_xx;
    inv_iyy = 1.0 / v.i_yy;
    inv_izz = 1.0 / v.i_zz;
    inv_m = 1.0 / (v.m_s + 2 * v.m_us_f + 2 * v.m_us_r);
    const double x_m = 2 * (v.m_us_f * v.a - v.m_us_r * v.b) * inv_m;  // the whole car's CG ahead of the sprung mass's
    a_h = v.a - x_m;
    b_h = v.b + x_m;
    h_roll = v.h_cg - (v.b * v.h_rc_f + v.a * v.h_rc_r) / L;
    karb[0] = v.k_arb_f;
    karb[1] = v.k_arb_r;
    geo[0] = v.h_rc_f / v.t_f;
    geo[1] = v.h_rc_r / v.t_r;
    steer_keep = v.driver_tau_s > 0 ? std::exp(-v.dt / v.driver_tau_s) : 0.0;
    for (int i = 0; i < kCorners; ++i) {
      const bool front = i < 2;
      xc[i] = corner_x(v, i);
      yc[i] = corner_y(v, i);
      ks[i] = front ? v.k_s_f : v.k_s_r;
      const double mus = front ? v.m_us_f : v.m_us_r;
      inv_mus[i] = 1.0 / mus;
      fs[i] = front ? v.f_static_f : v.f_static_r;
      n0[i] = v.g * (v.m_s * (front ? v.b : v.a) / (2 * L) + mus);
      k_lin[i] = cornering_stiffness(n0[i]);
    }
    corner_mobility(v, K);
    preview_gains();
    any_implicit = false;
    for (int i = 0; i < kCorners; ++i) {
      if (!dampers[i]) return DN_E_NULL;
      dn_controller c = ctrls ? ctrls[i] : default_controller(DN_CTRL_PASSIVE);
      if (!ctrls) c.u_passive = 0.0;
      xs[i] = i < 2 ? v.x_static_f : v.x_static_r;
      st = corner[i].init(*dampers[i], c, v.dt, v.accel_feature);
      if (st != DN_OK) return st;
      if (corner[i].implicit_a) any_implicit = true;
    }
    batch4 = dampers[1] == dampers[0] && dampers[2] == dampers[0] && dampers[3] == dampers[0] &&
             corner[0].implicit_a && corner[0].damper.precision == DN_PRECISION_FLOAT;
    return DN_OK;
  }

  // The preview driver's prediction over T (the file comment): drv_l, drv_c, drv_inv_g.
  // Init only (not real-time); with speed 0 or another steer mode the driver is off.
  void preview_gains() noexcept {
    for (int j = 0; j < kDriverPoints; ++j) drv_l[j] = drv_k[j] = 0;
    for (double& c : drv_kc) c = 0;
    drv_step = p.driver_rate_max * p.dt;
    drv_alpha = 0;
    if (p.tyre_model == DN_TYRE_MAGIC_FORMULA) {
      // the peak of D sin(C atan(phi)): phi(x) = x - E (x - atan x) = tan(pi / (2 C)), x = B alpha,
      // phi increasing in x for E <= 1: bisection
      const double target = std::tan(1.5707963267948966 / p.tyre_c);
      double lo = 0, hi = 1;
      auto phi = [&](double x) { return x - p.tyre_e * (x - std::atan(x)); };
      for (int k = 0; k < 60 && phi(hi) < target; ++k) hi *= 2;
      for (int k = 0; k < 100; ++k) {
        const double mid = 0.5 * (lo + hi);
        (phi(mid) < target ? lo : hi) = mid;
      }
      const double n = n0[0], dfz = (n - p.tyre_fz0) / p.tyre_fz0;
      double mu = p.tyre_mu0 * (1.0 + p.tyre_pdy2 * dfz);
      if (mu < 0.05 * p.tyre_mu0) mu = 0.05 * p.tyre_mu0;
      const double B = cornering_stiffness(n) / (p.tyre_c * mu * n);
      drv_alpha = 0.5 * (lo + hi) / B;
    }
    const double U = p.speed;
    if (p.steer_mode != DN_STEER_DRIVER || !(U > 0)) return;
    double T = p.driver_preview_s;
    if (T * U < p.driver_preview_min_m) T = p.driver_preview_min_m / U;
    const double m = 1.0 / inv_m, cf = k_lin[0] + k_lin[1], cr = k_lin[2] + k_lin[3];
    const double a = a_h, b = b_h;
    // M = [[A, B], [0, 0]] T, rows/columns (y, psi, vy, r, delta, delta_cmd)
    double M[6][6] = {};
    M[0][1] = U;
    M[0][2] = 1.0;
    M[1][3] = 1.0;
    M[2][2] = -(cf + cr) / (m * U);
    M[2][3] = -(a * cf - b * cr) / (m * U) - U;
    M[3][2] = -(a * cf - b * cr) / (p.i_zz * U);
    M[3][3] = -(a * a * cf + b * b * cr) / (p.i_zz * U);
    const int in = p.driver_tau_s > 0 ? 4 : 5;  // no lag: the command steers directly
    M[2][in] = cf / m;
    M[3][in] = a * cf / p.i_zz;
    if (p.driver_tau_s > 0) {
      M[4][4] = -1.0 / p.driver_tau_s;
      M[4][5] = 1.0 / p.driver_tau_s;
    }
    double g[kDriverPoints], c[kDriverPoints][3], gg = 0;
    for (int j = 0; j < kDriverPoints; ++j) {
      const double tj = T * (j + 1) / kDriverPoints;
      double E[6][6];
      detail_expm6(M, tj, E);
      drv_l[j] = U * tj;
      c[j][0] = E[0][2];
      c[j][1] = E[0][3];
      c[j][2] = p.driver_tau_s > 0 ? E[0][4] : 0.0;
      g[j] = E[0][5];
      gg += g[j] * g[j];
    }
    if (!std::isfinite(gg) || !(gg > 1e-24)) return;  // no steering authority: the driver holds 0
    for (int j = 0; j < kDriverPoints; ++j) {
      drv_k[j] = p.driver_gain * g[j] / gg;
      for (int k = 0; k < 3; ++k) drv_kc[k] += drv_k[j] * c[j][k];
    }
  }

  // E = exp(M T) (6 x 6) by scaling and squaring of the Taylor series (init only).
  static void detail_expm6(const double M[6][6], double T, double E[6][6]) noexcept {
    double nrm = 0;
    for (int i = 0; i < 6; ++i) {
      double r = 0;
      for (int j = 0; j < 6; ++j) r += std::fabs(M[i][j] * T);
      if (r > nrm) nrm = r;
    }
    int sq = 0;
    double scale = T;
    while (nrm > 0.25 && sq < 60) nrm *= 0.5, scale *= 0.5, ++sq;
    double A[6][6], term[6][6], tmp[6][6];
    for (int i = 0; i < 6; ++i)
      for (int j = 0; j < 6; ++j) {
        A[i][j] = M[i][j] * scale;
        E[i][j] = term[i][j] = i == j ? 1.0 : 0.0;
      }
    for (int k = 1; k <= 18; ++k) {  // |A| <= 1/4: 18 terms reach 4^-18 / 18! << 1e-16
      for (int i = 0; i < 6; ++i)
        for (int j = 0; j < 6; ++j) {
          double acc = 0;
          for (int l = 0; l < 6; ++l) acc += term[i][l] * A[l][j];
          tmp[i][j] = acc / k;
        }
      for (int i = 0; i < 6; ++i)
        for (int j = 0; j < 6; ++j) term[i][j] = tmp[i][j], E[i][j] += tmp[i][j];
    }
    for (int s = 0; s < sq; ++s) {
      for (int i = 0; i < 6; ++i)
        for (int j = 0; j < 6; ++j) {
          double acc = 0;
          for (int l = 0; l < 6; ++l) acc += E[i][l] * E[l][j];
          tmp[i][j] = acc;
        }
      for (int i = 0; i < 6; ++i)
        for (int j = 0; j < 6; ++j) E[i][j] = tmp[i][j];
    }
  }

  // K(N) of the Magic Formula [N/rad].
  // sin(2 atan(x)) = 2 x / (1 + x^2): no transcendental in the step.
  double cornering_stiffness(double n) const noexcept {
    const double x = n / (p.tyre_pky2 * p.tyre_fz0);
    return p.tyre_pky1 * p.tyre_fz0 * 2.0 * x / (1.0 + x * x);
  }

  // [RT] Lateral tyre force [N] at slip angle alpha [rad] and load n >= 0 [N], of wheel i.
  DN_FC_INLINE double tyre_fy(int i, double alpha, double n) const noexcept {
    if (!(n > 0)) return 0.0;
    if (p.tyre_model == DN_TYRE_LINEAR) return k_lin[i] * alpha;
    const double dfz = (n - p.tyre_fz0) / p.tyre_fz0;
    double mu = p.tyre_mu0 * (1.0 + p.tyre_pdy2 * dfz);
    if (mu < 0.05 * p.tyre_mu0) mu = 0.05 * p.tyre_mu0;  // far above Fz0 with pdy2 < 0
    const double D = mu * n, C = p.tyre_c, E = p.tyre_e;
    const double B = cornering_stiffness(n) / (C * D);
    const double ba = B * alpha;
    return D * std::sin(C * std::atan(ba - E * (ba - std::atan(ba))));
  }

  // [RT] The driver's path Y at x [m] (piecewise linear, ends held).
  double path_at(double x) const noexcept {
    if (x <= path_x[0]) return path_y[0];
    if (x >= path_x[n_path - 1]) return path_y[n_path - 1];
    int lo = 0, hi = n_path - 1;
    while (hi - lo > 1) {  // at most log2(256) = 8 iterations
      const int mid = (lo + hi) / 2;
      if (path_x[mid] <= x) lo = mid;
      else hi = mid;
    }
    const double w = (x - path_x[lo]) / (path_x[hi] - path_x[lo]);
    return path_y[lo] + w * (path_y[hi] - path_y[lo]);
  }
};

struct FullCarData {
  double s[DN_FULLCAR_STATE_SIZE] = {};
  int64_t n_evals = 0;
};

namespace detail {

// The integrated motion: body, lateral and wheels (the RK4 vector).
struct FcMotion {
  double z, vz, phi, p, theta, q, vy, r, psi, X, Y;
  double zus[kCorners], vus[kCorners];
};
constexpr int kFcMotion = 11 + 2 * kCorners;
static_assert(sizeof(FcMotion) == kFcMotion * sizeof(double), "FcMotion is a flat vector");

inline const double* vec(const FcMotion& m) noexcept { return &m.z; }
inline double* vec(FcMotion& m) noexcept { return &m.z; }

// Everything of one evaluation point that does not depend on the damper forces.
struct FcFree {
  double zb[kCorners], vb[kCorners];  // body corner height, velocity
  double dfl[kCorners];               // suspension deflection d_i
  double fs_free[kCorners];           // F_s,i without the damper's share
  double ftz[kCorners], load[kCorners], fy[kCorners], fgeo[kCorners];
  double alpha_f, alpha_r, a_y, dvy, dr;
};

// held: the lateral tyre forces of the step start (damper_eval per_step: tyres, like the
// dampers, evaluated once per step and held), or nullptr to evaluate them here.
DN_FC_NOINLINE inline FcFree free_forces(const FullCarModel& m, const FcMotion& y, const double* zr,
                          const double* vr, double delta, double cos_delta,
                          const FcFree* held = nullptr) noexcept {
  const dn_fullcar_params& p = m.p;
  FcFree f;
  for (int i = 0; i < kCorners; ++i) {
    f.zb[i] = y.z + m.yc[i] * y.phi - m.xc[i] * y.theta;
    f.vb[i] = y.vz + m.yc[i] * y.p - m.xc[i] * y.q;
    f.dfl[i] = f.zb[i] - y.zus[i];
    double t = -p.k_t * (y.zus[i] - zr[i]) - p.c_t * (y.vus[i] - vr[i]);
    if (t < -m.n0[i]) t = -m.n0[i];  // lift-off: the tyre cannot pull
    f.ftz[i] = t;
    f.load[i] = m.n0[i] + t;
  }
  for (int ax = 0; ax < 2; ++ax) {
    const int l = 2 * ax, r = l + 1;
    const double farb = m.karb[ax] * (f.dfl[l] - f.dfl[r]);
    f.fs_free[l] = -m.ks[l] * f.dfl[l] - farb;
    f.fs_free[r] = -m.ks[r] * f.dfl[r] + farb;
  }
  const double U = p.speed;
  if (held) {
    for (int i = 0; i < kCorners; ++i) f.fy[i] = held->fy[i], f.fgeo[i] = held->fgeo[i];
    f.alpha_f = held->alpha_f;
    f.alpha_r = held->alpha_r;
    f.a_y = held->a_y;
    f.dr = held->dr;
    f.dvy = f.a_y - U * y.r;
  } else if (U > 0) {
    f.alpha_f = delta - std::atan((y.vy + m.a_h * y.r) / U);
    f.alpha_r = -std::atan((y.vy - m.b_h * y.r) / U);
#pragma GCC unroll 1
    for (int i = 0; i < kCorners; ++i)  // rolled: one copy of the tyre model (libm calls inside)
      f.fy[i] = m.tyre_fy(i, i < 2 ? f.alpha_f : f.alpha_r, f.load[i]);
    const double fyf = (f.fy[0] + f.fy[1]) * cos_delta, fyr = f.fy[2] + f.fy[3];
    f.a_y = (fyf + fyr) * m.inv_m;
    f.dvy = f.a_y - U * y.r;
    f.dr = (m.a_h * fyf - m.b_h * fyr) * m.inv_izz;
    f.fgeo[0] = fyf * m.geo[0];
    f.fgeo[1] = -f.fgeo[0];
    f.fgeo[2] = fyr * m.geo[1];
    f.fgeo[3] = -f.fgeo[2];
  } else {
    f.alpha_f = f.alpha_r = f.a_y = f.dvy = f.dr = 0.0;
    for (int i = 0; i < kCorners; ++i) f.fy[i] = f.fgeo[i] = 0.0;
  }
  return f;
}

// Body and wheel accelerations for damper forces F (dF = F - f_static per corner).
struct FcAccel {
  double az, aphi, atheta, aus[kCorners];
};

DN_FC_INLINE inline FcAccel accelerations(const FullCarModel& m, const FcMotion& y, const FcFree& f,
                             const double* dF) noexcept {
  FcAccel a;
  double sz = 0, sth = 0, sph = 0;
  double fsi[kCorners];
  for (int i = 0; i < kCorners; ++i) {
    fsi[i] = f.fs_free[i] - dF[i];
    sz += fsi[i];
    sth -= m.xc[i] * fsi[i];
    sph += m.yc[i] * fsi[i];
  }
  const double mh = m.p.m_s * m.h_roll;
  a.az = sz * m.inv_ms;
  a.atheta = sth * m.inv_iyy;
  a.aphi = (sph + mh * f.a_y + mh * m.p.g * y.phi) * m.inv_ixx;
  for (int i = 0; i < kCorners; ++i) a.aus[i] = (-fsi[i] + f.ftz[i] + f.fgeo[i]) * m.inv_mus[i];
  return a;
}

// Relative (damper) accelerations a_i = z_b,i'' - z_us,i''.
DN_FC_INLINE inline void relative_accel(const FullCarModel& m, const FcAccel& a, double* out) noexcept {
  for (int i = 0; i < kCorners; ++i)
    out[i] = a.az + m.yc[i] * a.aphi - m.xc[i] * a.atheta - a.aus[i];
}

// The motion's time derivative for given accelerations.
// sin and cos of the heading at a stage, from the step start's (psi0, sin psi0, cos psi0):
// the stage's change d = psi - psi0 is tiny (r h), so sin d and cos d by their series (to
// d^7 / 5040 < 2e-18 for |d| < 0.01 rad), else std::sin / std::cos. Saves two libm calls
// per stage.
struct Heading {
  double psi0, s0, c0;
};
inline void heading_at(const Heading& h, double psi, double* sn, double* cs) noexcept {
  const double d = psi - h.psi0;
  if (std::fabs(d) < 0.01) {
    const double d2 = d * d;
    const double sd = d * (1.0 - d2 / 6.0 * (1.0 - d2 / 20.0 * (1.0 - d2 / 42.0)));
    const double cd = 1.0 - d2 / 2.0 * (1.0 - d2 / 12.0 * (1.0 - d2 / 30.0));
    *sn = h.s0 * cd + h.c0 * sd;
    *cs = h.c0 * cd - h.s0 * sd;
  } else {
    *sn = std::sin(psi);
    *cs = std::cos(psi);
  }
}

DN_FC_NOINLINE inline FcMotion derivative(const FullCarModel& m, const FcMotion& y, const FcFree& f,
                           const FcAccel& a, const Heading& hd) noexcept {
  FcMotion d;
  const double U = m.p.speed;
  d.z = y.vz;
  d.vz = a.az;
  d.phi = y.p;
  d.p = a.aphi;
  d.theta = y.q;
  d.q = a.atheta;
  d.vy = f.dvy;
  d.r = f.dr;
  d.psi = U > 0 ? y.r : 0.0;
  if (U > 0) {
    double sn, cs;
    heading_at(hd, y.psi, &sn, &cs);
    d.X = U * cs - y.vy * sn;
    d.Y = U * sn + y.vy * cs;
  } else {
    d.X = d.Y = 0.0;
  }
  for (int i = 0; i < kCorners; ++i) {
    d.zus[i] = y.vus[i];
    d.vus[i] = a.aus[i];
  }
  return d;
}

// solve4's row exchange: out of its hot code (the vehicles' systems I + K D rarely pivot).
DN_FC_COLD inline void swap_rows(double A[kCorners][kCorners], double* b, int c, int piv) noexcept {
  for (int k = 0; k < kCorners; ++k) {
    const double t = A[c][k];
    A[c][k] = A[piv][k];
    A[piv][k] = t;
  }
  const double t = b[c];
  b[c] = b[piv];
  b[piv] = t;
}

// Solve A x = b (4x4) by Gaussian elimination with partial pivoting; false when singular or
// non-finite. Fixed loops, no allocation.
DN_FC_OUTLINE inline bool solve4(double A[kCorners][kCorners], double* b) noexcept {
  for (int c = 0; c < kCorners; ++c) {
    int piv = c;
    for (int r = c + 1; r < kCorners; ++r)
      if (std::fabs(A[r][c]) > std::fabs(A[piv][c])) piv = r;
    if (!(std::fabs(A[piv][c]) > 1e-300)) return false;
    if (piv != c) swap_rows(A, b, c, piv);
    for (int r = c + 1; r < kCorners; ++r) {
      const double f = A[r][c] / A[c][c];
      for (int k = c; k < kCorners; ++k) A[r][k] -= f * A[c][k];
      b[r] -= f * b[c];
    }
  }
  for (int c = kCorners - 1; c >= 0; --c) {
    double s = b[c];
    for (int k = c + 1; k < kCorners; ++k) s -= A[c][k] * b[k];
    b[c] = s / A[c][c];
  }
  for (int c = 0; c < kCorners; ++c)
    if (!std::isfinite(b[c])) return false;
  return true;
}

// [RT] The corners' neural inputs as evaluated (the report's features).
DN_FC_OUTLINE inline void corner_features(const FullCarModel& m, const dn_damper_input* in,
                                          double* feat_out) noexcept {
  for (int i = 0; i < kCorners; ++i) m.corner[i].damper.feature_values(in[i], feat_out + i * DN_MAX_INPUTS);
}

// [RT] evaluate_corners when no corner's damper reads a: each corner's force as it is.
DN_FC_OUTLINE inline int evaluate_corners_explicit(const FullCarModel& m, const dn_damper_input* in,
                                                   double* F, double* feat_out, uint32_t* mask,
                                                   int64_t* n_evals) noexcept {
  int status = DN_OK;
  for (int i = 0; i < kCorners; ++i) {
    const Corner& c = m.corner[i];
    const int st = diverged_if_overflow(c, c.damper.force(in[i], &F[i],
                                                          feat_out ? feat_out + i * DN_MAX_INPUTS : nullptr,
                                                          mask ? &mask[i] : nullptr));
    if (st < 0) {
      if (status >= 0) status = st;
    } else if (status >= 0) {
      status |= st;
    }
  }
  *n_evals += kCorners;
  return status;
}

// [RT] One evaluation of the four corners sharing one float damper reading a (batch4): one pass
// of the kernel (Damper::force_da4). Returns the OR of the warnings, or the first error.
DN_FC_OUTLINE inline int corners_batch4(const FullCarModel& m, const dn_damper_input* in, double* f0,
                                        double* D, uint32_t* mk, int64_t* n_evals) noexcept {
  int st_it = DN_OK;
  int st4[kCorners];
  m.corner[0].damper.force_da4(in, f0, D, st4, mk);
  for (int i = 0; i < kCorners; ++i) {
    const int st = diverged_if_overflow(m.corner[i], st4[i]);
    if (st < 0) {
      if (st_it >= 0) st_it = st;
    } else if (st_it >= 0) {
      st_it |= st;
    }
  }
  *n_evals += kCorners;
  return st_it;
}

// [RT] One evaluation of each corner (evaluate_corners' iteration it, not batch4): force_da of a
// corner reading a, force of one that does not (at it 0; later its first force stands).
DN_FC_OUTLINE inline int corners_each(const FullCarModel& m, const dn_damper_input* in, int it,
                                      const double* best_F, const uint32_t* best_mask, double* f0,
                                      double* D, uint32_t* mk, int64_t* n_evals) noexcept {
  int st_it = DN_OK;
  for (int i = 0; i < kCorners; ++i) {
    const Corner& c = m.corner[i];
    D[i] = 0.0;
    int st;
    if (c.implicit_a) st = diverged_if_overflow(c, c.damper.force_da(in[i], &f0[i], &D[i], &mk[i]));
    else if (it == 0) st = diverged_if_overflow(c, c.damper.force(in[i], &f0[i], nullptr, &mk[i]));
    else {  // a corner not reading a: its first force stands
      f0[i] = best_F[i];
      mk[i] = best_mask[i];
      continue;
    }
    *n_evals += 1;
    if (st < 0) {
      if (st_it >= 0) st_it = st;
    } else if (st_it >= 0) {
      st_it |= st;
    }
  }
  return st_it;
}

// out = K (f - fs): the corners' accelerations from the forces f [N] beyond static (K the
// corner mobility, 1/kg), each row summed in column order; rolled, one row's code.
DN_FC_INLINE inline void mobility_times(const FullCarModel& m, const double* f, double* out) noexcept {
  double df[kCorners];
  for (int j = 0; j < kCorners; ++j) df[j] = f[j] - m.fs[j];
#pragma GCC unroll 1
  for (int i = 0; i < kCorners; ++i) {
    double s = 0;
    for (int j = 0; j < kCorners; ++j) s += m.K[i][j] * df[j];
    out[i] = s;
  }
}

// evaluate_corners_linear's fallback when its Newton system is singular (the explicit
// scheme's forces; the inputs' a restored): out of its hot code.
DN_FC_COLD inline int linear_fallback(const double* f0, const double* a0, int st_it, double* F,
                                      dn_damper_input* in) noexcept {
  for (int i = 0; i < kCorners; ++i) F[i] = f0[i], in[i].a = a0[i];
  return st_it | DN_W_ACCEL_FALLBACK;
}

// [RT] evaluate_corners for DN_ACCEL_LINEAR: one evaluation with the slopes, one linearised
// Newton step on the 4-vector (evaluate_corners_newton's first iteration with linear set,
// without the convergence bookkeeping it never reads).
DN_FC_OUTLINE inline int evaluate_corners_linear(const FullCarModel& m, dn_damper_input* in,
                                                 const double* f_last, double* F, double* feat_out,
                                                 uint32_t* mask, int64_t* n_evals) noexcept {
  double a_free[kCorners], a0[kCorners], ka[kCorners];
  mobility_times(m, f_last, ka);
  for (int i = 0; i < kCorners; ++i) {
    a0[i] = in[i].a;
    a_free[i] = in[i].a + ka[i];
  }
  double f0[kCorners], D[kCorners], g[kCorners];
  uint32_t mk[kCorners] = {};
  const int st_it = m.batch4 ? corners_batch4(m, in, f0, D, mk, n_evals)
                             : corners_each(m, in, 0, nullptr, nullptr, f0, D, mk, n_evals);
  if (st_it < 0) {  // an error: as the explicit scheme (the error is the step's)
    for (int i = 0; i < kCorners; ++i) F[i] = f0[i];
    return st_it;
  }
  mobility_times(m, f0, ka);
  for (int i = 0; i < kCorners; ++i) g[i] = in[i].a - a_free[i] + ka[i];
  // Newton step: (I + K D) da = -g
  double A[kCorners][kCorners], da[kCorners];
  bool ok = true;
#pragma GCC unroll 1
  for (int i = 0; i < kCorners; ++i) {
    for (int j = 0; j < kCorners; ++j) A[i][j] = 0.0 + m.K[i][j] * D[j];
    A[i][i] = 1.0 + m.K[i][i] * D[i];
    if (!(A[i][i] >= DN_ACCEL_LINEAR_MIN_SLOPE)) ok = false;
    da[i] = -g[i];
  }
  ok = ok && solve4(A, da);
  int status;
  if (!ok) {
    status = linear_fallback(f0, a0, st_it, F, in);
  } else {
    for (int i = 0; i < kCorners; ++i) {
      F[i] = f0[i] + D[i] * da[i];
      in[i].a = a0[i] + da[i];
    }
    status = st_it;
  }
  if (mask)
    for (int i = 0; i < kCorners; ++i) mask[i] = mk[i];
  if (feat_out) corner_features(m, in, feat_out);
  return status;
}

// [RT] evaluate_corners for DN_ACCEL_IMPLICIT: Newton on the 4-vector until converged.
DN_FC_OUTLINE inline int evaluate_corners_newton(const FullCarModel& m, dn_damper_input* in,
                                                 const double* f_last, double* F, double* feat_out,
                                                 uint32_t* mask, int64_t* n_evals) noexcept {
  // The coupled acceleration: a_free from the explicit values, Newton on the 4-vector.
  double a_free[kCorners];
  for (int i = 0; i < kCorners; ++i) {
    double s = 0;
    for (int j = 0; j < kCorners; ++j) s += m.K[i][j] * (f_last[j] - m.fs[j]);
    a_free[i] = in[i].a + s;
  }
  const int max_iter = DN_ACCEL_MAX_EVALS;
  double best_F[kCorners], best_a[kCorners], best_g = INFINITY;
  uint32_t best_mask[kCorners] = {};
  int best_status = DN_OK;
  bool done = false;
  for (int it = 0; it < max_iter && !done; ++it) {
    double f0[kCorners], D[kCorners], g[kCorners];
    uint32_t mk[kCorners] = {};
    const int st_it = m.batch4 ? corners_batch4(m, in, f0, D, mk, n_evals)
                               : corners_each(m, in, it, best_F, best_mask, f0, D, mk, n_evals);
    if (st_it < 0) {  // an error: as the explicit scheme (the error is the step's)
      if (it == 0) {
        for (int i = 0; i < kCorners; ++i) F[i] = f0[i];
        return st_it;
      }
      break;
    }
    double gmax = 0;
    for (int i = 0; i < kCorners; ++i) {
      double s = 0;
      for (int j = 0; j < kCorners; ++j) s += m.K[i][j] * (f0[j] - m.fs[j]);
      g[i] = in[i].a - a_free[i] + s;
      const double tol = 1e-7 * (1.0 + std::fabs(a_free[i])) +
                         m.K[i][i] * m.corner[i].f_eps * (1.0 + std::fabs(f0[i]));
      double rel = std::fabs(g[i]) / tol;
      if (!std::isfinite(rel)) rel = INFINITY;  // never converged, never the best
      if (rel > gmax) gmax = rel;
    }
    if (gmax < best_g || it == 0) {
      best_g = gmax;
      best_status = st_it;
      for (int i = 0; i < kCorners; ++i) best_F[i] = f0[i], best_a[i] = in[i].a, best_mask[i] = mk[i];
    }
    if (gmax <= 1.0) {
      done = true;
      break;
    }
    // Newton step: (I + K D) da = -g
    double A[kCorners][kCorners], da[kCorners];
    bool ok = true;
    for (int i = 0; i < kCorners; ++i) {
      for (int j = 0; j < kCorners; ++j) A[i][j] = (i == j ? 1.0 : 0.0) + m.K[i][j] * D[j];
      da[i] = -g[i];
    }
    ok = ok && solve4(A, da);
    if (!ok) break;
    for (int i = 0; i < kCorners; ++i) in[i].a += da[i];
  }
  for (int i = 0; i < kCorners; ++i) F[i] = best_F[i], in[i].a = best_a[i];
  if (mask)
    for (int i = 0; i < kCorners; ++i) mask[i] = best_mask[i];
  if (feat_out) corner_features(m, in, feat_out);
  return done ? best_status : (best_status | DN_W_ACCEL_UNCONVERGED);
}

// [RT] The four corners' damper evaluations at one point (the one place the dampers are
// called). in[i].a holds the explicit acceleration feature (from f_last) on entry and the
// value used on return; f_last: the forces it came from. Returns the OR of the corners'
// warnings, or the first error.
inline int evaluate_corners(const FullCarModel& m, dn_damper_input* in, const double* f_last,
                            double* F, double* feat_out, uint32_t* mask,
                            int64_t* n_evals) noexcept {
  if (!m.any_implicit) return evaluate_corners_explicit(m, in, F, feat_out, mask, n_evals);
  if (m.p.accel_feature == DN_ACCEL_LINEAR) return evaluate_corners_linear(m, in, f_last, F, feat_out, mask, n_evals);
  return evaluate_corners_newton(m, in, f_last, F, feat_out, mask, n_evals);
}

// The damper inputs at one evaluation point (a from the explicit forces f_last), their states
// not yet filled (Damper::advance / fill).
DN_FC_OUTLINE inline void corner_inputs(const FullCarModel& m, const FcMotion& y, const FcFree& f,
                          const double* f_last, const double* u, const double* temp, double t,
                          int stage, dn_damper_input* in) noexcept {
  double dF[kCorners], arel[kCorners];
  for (int i = 0; i < kCorners; ++i) dF[i] = f_last[i] - m.fs[i];
  relative_accel(m, accelerations(m, y, f, dF), arel);
#pragma GCC unroll 1
  for (int i = 0; i < kCorners; ++i) {  // rolled: one copy of the input's fields
    dn_damper_input d = unfilled_input();
    d.x = f.dfl[i] + m.xs[i];
    d.v = f.vb[i] - y.vus[i];
    d.a = arel[i];
    d.u = u[i];
    d.temperature = temp[i];
    d.t = t;
    d.dt = m.p.dt;
    d.stage = stage;
    in[i] = d;
  }
}

// Corner i's damper state block in the flat state.
inline DamperState corner_damper_state(const double* s, int i) noexcept {
  return DamperState::load(s + fc_corner(i, DN_FULLCAR_CORNER_DAMPER));
}

inline FcMotion motion_of(const double* s) noexcept {
  FcMotion y;
  y.z = s[FC_z];
  y.vz = s[FC_vz];
  y.phi = s[FC_phi];
  y.p = s[FC_p];
  y.theta = s[FC_theta];
  y.q = s[FC_q];
  y.vy = s[FC_vy];
  y.r = s[FC_r];
  y.psi = s[FC_psi];
  y.X = s[FC_x_pos];
  y.Y = s[FC_y_pos];
  for (int i = 0; i < kCorners; ++i) {
    y.zus[i] = s[fc_corner(i, FCC_z_us)];
    y.vus[i] = s[fc_corner(i, FCC_v_us)];
  }
  return y;
}

inline void store_motion(const FcMotion& y, double* s) noexcept {
  s[FC_z] = y.z;
  s[FC_vz] = y.vz;
  s[FC_phi] = y.phi;
  s[FC_p] = y.p;
  s[FC_theta] = y.theta;
  s[FC_q] = y.q;
  s[FC_vy] = y.vy;
  s[FC_r] = y.r;
  s[FC_psi] = y.psi;
  s[FC_x_pos] = y.X;
  s[FC_y_pos] = y.Y;
  for (int i = 0; i < kCorners; ++i) {
    s[fc_corner(i, FCC_z_us)] = y.zus[i];
    s[fc_corner(i, FCC_v_us)] = y.vus[i];
  }
}

// The preview driver's road-wheel angle over the step starting at state s (steer_mode driver;
// see the file comment): command, lag, rate limit. Out of the open loop's code.
DN_FC_OUTLINE inline double driver_steer(const FullCarModel& m, const double* s) noexcept {
  const dn_fullcar_params& p = m.p;
  const double prev = clamp(s[FC_steer], -p.steer_max, p.steer_max);  // a set_state steer may be out of range
  const double c = std::cos(s[FC_psi]), sn = std::sin(s[FC_psi]);
  double cmd = -(m.drv_kc[0] * s[FC_vy] + m.drv_kc[1] * s[FC_r] + m.drv_kc[2] * prev);
  for (int j = 0; j < FullCarModel::kDriverPoints; ++j) {
    const double px = s[FC_x_pos] + m.drv_l[j] * c;
    const double py = s[FC_y_pos] + m.drv_l[j] * sn;
    cmd += m.drv_k[j] * c * (m.path_at(px) - py);
  }
  if (!std::isfinite(cmd)) cmd = 0.0;
  if (m.drv_alpha > 0.0 && p.speed > 0.0) {  // no more front slip than the tyres' peak: beyond it, only less force
    const double a0 = std::atan((s[FC_vy] + m.a_h * s[FC_r]) / p.speed);
    cmd = clamp(cmd, a0 - m.drv_alpha, a0 + m.drv_alpha);
  }
  cmd = clamp(cmd, -p.steer_max, p.steer_max);
  if (m.steer_keep > 0.0) cmd = cmd + (prev - cmd) * m.steer_keep;
  return clamp(cmd, prev - m.drv_step, prev + m.drv_step);
}

// The road-wheel angle applied over the step starting at state s.
DN_FC_OUTLINE inline double steer_for_step(const FullCarModel& m, const double* s, double steer_in) noexcept {
  const dn_fullcar_params& p = m.p;
  if (p.steer_mode == DN_STEER_DRIVER) return driver_steer(m, s);
  double cmd = clamp(steer_in, -p.steer_max, p.steer_max);
  if (m.steer_keep > 0.0) cmd = cmd + (s[FC_steer] - cmd) * m.steer_keep;
  return clamp(cmd, -p.steer_max, p.steer_max);  // a set_state steer may be out of range
}

// [RT] The dampers of one RK4 stage evaluated per stage (damper_eval per_stage): their inputs at
// the stage point (y, f; a from f_last), their states advanced from the step start (ds0, where
// the inputs were in0) over half a step (stages 1, 2) or a step (3), the four evaluations into F.
// Returns the OR of the corners' warnings, or the first error.
DN_FC_NOINLINE inline int stage_dampers(const FullCarModel& m, const FcMotion& y, const FcFree& f,
                                       const double* f_last, const double* u, const dn_damper_input* in0,
                                       const double* temp, double t, int stage, const DamperState* ds0,
                                       double* F, int64_t* n_evals) noexcept {
  dn_damper_input di[kCorners];
  corner_inputs(m, y, f, f_last, u, temp, t, stage, di);
#pragma GCC unroll 1
  for (int i = 0; i < kCorners; ++i) {  // rolled: one copy of the states' update
    const Corner& c = m.corner[i];
    DamperState ds;
    c.damper.advance(stage < 3 ? c.half : c.full, ds0[i], in0[i], di[i], ds);
    Damper::fill(ds, di[i]);
  }
  return evaluate_corners(m, di, f_last, F, nullptr, nullptr, n_evals);
}

// [RT] Corner i at the step's end into the new state ns: its road (z_r, v_r), control u and last
// force f_last, and its damper's states there (its motion at y, the control held; from ds0 at
// the step start, where its input was in0), their sum added to check. Returns whether the
// corner's motion is plausible (dampnet.h DN_PLAUSIBLE_LIST; false: a runaway).
DN_FC_OUTLINE inline bool corner_end(const FullCarModel& m, int i, const FcMotion& y, double z_r, double v_r,
                                     double u, double f_last, const dn_damper_input& in0,
                                     const DamperState& ds0, double* ns, double& check) noexcept {
  const Corner& c = m.corner[i];
  ns[fc_corner(i, FCC_z_r)] = z_r;
  ns[fc_corner(i, FCC_v_r)] = v_r;
  ns[fc_corner(i, FCC_u_cmd)] = u;
  ns[fc_corner(i, FCC_f_last)] = f_last;
  const double zb = y.z + m.yc[i] * y.phi - m.xc[i] * y.theta;
  const double vb = y.vz + m.yc[i] * y.p - m.xc[i] * y.q;
  dn_damper_input end = in0;
  end.x = zb - y.zus[i] + m.xs[i];
  end.v = vb - y.vus[i];
  DamperState ds1;
  c.damper.advance(c.full, ds0, in0, end, ds1);
  ds1.store(ns + fc_corner(i, DN_FULLCAR_CORNER_DAMPER));
  for (int k = 0; k < DN_DAMPER_STATE_SIZE; ++k) check += ds1.s[k];
  return plausible_corner(zb - y.zus[i], y.zus[i] - z_r, vb - y.vus[i]);
}

// RK4's stage point y + c k (one copy for the three stages).
DN_FC_OUTLINE inline FcMotion axpy(const FcMotion& y, double c, const FcMotion& k) noexcept {
  FcMotion o;
  const double* a = vec(y);
  const double* b = vec(k);
  double* w = vec(o);
  for (int j = 0; j < kFcMotion; ++j) w[j] = a[j] + c * b[j];
  return o;
}

// Everything at the step start: controls, steering, first evaluation, report.
struct FcStart {
  double u[kCorners], F[kCorners], delta, cos_delta;
  dn_damper_input in[kCorners];  // the dampers' inputs at the step start
  FcFree f;
  FcAccel acc;
  int status;
};

// fc_start's report (out != nullptr): out of the step's hot code.
DN_FC_OUTLINE inline void fc_report(const FullCarModel& m, const FcMotion& y, const FcStart& r,
                                    const uint32_t* mask, dn_fullcar_out* out) noexcept {
  const dn_damper_input* di = r.in;
  {
    double arel[kCorners];
    relative_accel(m, r.acc, arel);
    for (int i = 0; i < kCorners; ++i) {
      out->force[i] = r.F[i];
      out->u[i] = r.u[i];
      out->x[i] = di[i].x;
      out->v[i] = di[i].v;
      out->a[i] = di[i].a;
      out->acc_s[i] = arel[i] + r.acc.aus[i];
      out->acc_us[i] = r.acc.aus[i];
      out->tyre_load[i] = r.f.load[i];
      out->tyre_fy[i] = r.f.fy[i];
      out->clamped_mask[i] = mask[i];
    }
    out->acc_z = r.acc.az;
    out->acc_phi = r.acc.aphi;
    out->acc_theta = r.acc.atheta;
    out->a_y = r.f.a_y;
    out->steer = r.delta;
    out->slip_f = r.f.alpha_f;
    out->slip_r = r.f.alpha_r;
    out->beta = m.p.speed > 0 ? std::atan(y.vy / m.p.speed) : 0.0;
  }
}

DN_FC_OUTLINE inline FcStart fc_start(const FullCarModel& m, const double* s, const dn_fullcar_input& in,
                        dn_fullcar_out* out, int64_t* n_evals) noexcept {
  FcStart r;
  const FcMotion y = motion_of(s);
  r.delta = steer_for_step(m, s, in.steer);
  double zr[kCorners], vr[kCorners], fl[kCorners], temp[kCorners];
#pragma GCC unroll 1
  for (int i = 0; i < kCorners; ++i) {  // rolled: one copy of the control law
    zr[i] = s[fc_corner(i, FCC_z_r)];
    vr[i] = s[fc_corner(i, FCC_v_r)];
    fl[i] = s[fc_corner(i, FCC_f_last)];
    temp[i] = s[fc_corner(i, FCC_temperature)];
    const double vb = y.vz + m.yc[i] * y.p - m.xc[i] * y.q;
    r.u[i] = m.corner[i].command(vb, y.vus[i], in.u[i], s[fc_corner(i, FCC_u_cmd)]);
  }
  r.cos_delta = std::cos(r.delta);
  r.f = free_forces(m, y, zr, vr, r.delta, r.cos_delta);
  dn_damper_input* di = r.in;
  corner_inputs(m, y, r.f, fl, r.u, temp, s[FC_t], 0, di);
#pragma GCC unroll 1
  for (int i = 0; i < kCorners; ++i) Damper::fill(corner_damper_state(s, i), di[i]);
  double feat[kCorners * DN_MAX_INPUTS];
  uint32_t mask[kCorners] = {};
  r.status = evaluate_corners(m, di, fl, r.F, out ? feat : nullptr, mask, n_evals);
  double dF[kCorners];
  for (int i = 0; i < kCorners; ++i) dF[i] = r.F[i] - m.fs[i];
  r.acc = accelerations(m, y, r.f, dF);
  double sum = r.acc.az + r.acc.aphi + r.acc.atheta + r.f.a_y + r.f.dr;
#pragma GCC unroll 1
  for (int i = 0; i < kCorners; ++i) sum += r.acc.aus[i] + di[i].a + di[i].x + di[i].v + r.f.fy[i];
  if (r.status >= 0 && !std::isfinite(sum)) r.status = DN_E_DIVERGED;
  if (out) fc_report(m, y, r, mask, out);
  return r;
}

inline bool finite_input(const FullCarModel& m, const dn_fullcar_input& in, bool road) noexcept {
#pragma GCC unroll 1
  for (int i = 0; i < kCorners; ++i) {
    if (road && (!std::isfinite(in.z_r[i]) || !std::isfinite(in.v_r[i]))) return false;
    if (m.corner[i].ctrl.kind == DN_CTRL_EXTERNAL && !std::isfinite(in.u[i])) return false;
  }
  return m.p.steer_mode == DN_STEER_DRIVER || std::isfinite(in.steer);
}

}  // namespace detail

// [RT] Reset to rest (see dn_fullcar_reset).
inline void reset(const FullCarModel& m, FullCarData& d) noexcept {
  for (double& x : d.s) x = 0.0;
  for (int i = 0; i < kCorners; ++i) {
    const Corner& c = m.corner[i];
    const double u0 = c.command_at_rest();
    d.s[fc_corner(i, FCC_u_cmd)] = u0;
    d.s[fc_corner(i, FCC_f_last)] = m.fs[i];
    d.s[fc_corner(i, FCC_temperature)] = m.p.temperature;
    c.rest_state(m.xs[i], u0).store(d.s + fc_corner(i, DN_FULLCAR_CORNER_DAMPER));
  }
}

// [RT] What step() would report, without advancing.
DN_REALTIME inline int forward(const FullCarModel& m, const FullCarData& d,
                               const dn_fullcar_input& in, dn_fullcar_out* out) noexcept {
  if (!detail::finite_input(m, in, false)) return DN_E_NONFINITE_INPUT;
  int64_t n = 0;
  return detail::fc_start(m, d.s, in, out, &n).status;
}

// [RT] One step (see the file comment and dn_fullcar_step).
DN_REALTIME inline int step(const FullCarModel& m, FullCarData& d, const dn_fullcar_input& in,
                            dn_fullcar_out* out) noexcept {
  using namespace detail;
  if (!finite_input(m, in, true)) return DN_E_NONFINITE_INPUT;
  const double* s = d.s;
  const double h = m.p.dt;
  const FcStart r = fc_start(m, s, in, out, &d.n_evals);
  int status = r.status;
  if (status < 0) return status;

  const double t0 = s[FC_t];
  const FcMotion y0 = motion_of(s);
  double temp[kCorners];
  double zr0[kCorners], vr0[kCorners], zrm[kCorners], vrm[kCorners];
  double f_last[kCorners];
  DamperState ds0[kCorners];
#pragma GCC unroll 1
  for (int i = 0; i < kCorners; ++i) {  // rolled: one copy of the mid-step road
    temp[i] = s[fc_corner(i, FCC_temperature)];
    zr0[i] = s[fc_corner(i, FCC_z_r)];
    vr0[i] = s[fc_corner(i, FCC_v_r)];
    // road at mid-step: cubic Hermite of (zr0, vr0) -> (zr1, vr1), as the quarter car
    zrm[i] = 0.5 * (zr0[i] + in.z_r[i]) + 0.125 * h * (vr0[i] - in.v_r[i]);
    vrm[i] = 1.5 * (in.z_r[i] - zr0[i]) / h - 0.25 * (vr0[i] + in.v_r[i]);
    ds0[i] = corner_damper_state(s, i);
    f_last[i] = r.F[i];
  }
  const bool per_stage = m.p.damper_eval == DN_EVAL_PER_STAGE;
  const Heading hd{y0.psi, std::sin(y0.psi), std::cos(y0.psi)};
  // The derivative at a stage point: dampers evaluated (per_stage) or held (per_step).
  auto stage_deriv = [&](const FcMotion& y, const double* zr, const double* vr, double t,
                         int stage) noexcept DN_FC_OUTLINE_LAMBDA -> FcMotion {
    const FcFree f = free_forces(m, y, zr, vr, r.delta, r.cos_delta, per_stage ? nullptr : &r.f);
    double F[kCorners];
    if (per_stage) {
      const int st = stage_dampers(m, y, f, f_last, r.u, r.in, temp, t, stage, ds0, F, &d.n_evals);
      if (st < 0) status = st;
      else if (status >= 0) status |= st;
      for (int i = 0; i < kCorners; ++i) f_last[i] = F[i];
    } else {
      for (int i = 0; i < kCorners; ++i) F[i] = r.F[i];
    }
    double dF[kCorners];
    for (int i = 0; i < kCorners; ++i) dF[i] = F[i] - m.fs[i];
    return derivative(m, y, f, accelerations(m, y, f, dF), hd);
  };
  const FcMotion k1 = derivative(m, y0, r.f, r.acc, hd);
  const FcMotion y1 = axpy(y0, 0.5 * h, k1);
  const FcMotion k2 = stage_deriv(y1, zrm, vrm, t0 + 0.5 * h, 1);
  const FcMotion y2 = axpy(y0, 0.5 * h, k2);
  const FcMotion k3 = stage_deriv(y2, zrm, vrm, t0 + 0.5 * h, 2);
  const FcMotion y3 = axpy(y0, h, k3);
  const FcMotion k4 = stage_deriv(y3, in.z_r, in.v_r, t0 + h, 3);
  if (status < 0) return status;
  FcMotion y;
  {
    const double h6 = h / 6.0;
    const double *a = vec(y0), *b1 = vec(k1), *b2 = vec(k2), *b3 = vec(k3), *b4 = vec(k4);
    double* w = vec(y);
#pragma GCC unroll 1
    for (int j = 0; j < kFcMotion; ++j) w[j] = a[j] + h6 * (b1[j] + 2 * b2[j] + 2 * b3[j] + b4[j]);
  }
  double ns[DN_FULLCAR_STATE_SIZE];
  for (int j = 0; j < DN_FULLCAR_STATE_SIZE; ++j) ns[j] = s[j];
  store_motion(y, ns);
  ns[FC_t] = t0 + h;
  ns[FC_steer] = r.delta;
  double check = 0.0;
#pragma GCC unroll 1
  for (int j = 0; j < kFcMotion; ++j) check += vec(y)[j];
  bool plausible = true;  // every corner called (each writes its part of ns)
  for (int i = 0; i < kCorners; ++i)
    if (!corner_end(m, i, y, in.z_r[i], in.v_r[i], r.u[i], f_last[i], r.in[i], ds0[i], ns, check))
      plausible = false;
  if (!std::isfinite(check)) return DN_E_DIVERGED;
  // a runaway: beyond any car (dampnet.h DN_PLAUSIBLE_LIST)
  if (!(std::fabs(y.phi) <= DN_PLAUSIBLE_ANGLE_RAD) || !(std::fabs(y.theta) <= DN_PLAUSIBLE_ANGLE_RAD))
    return DN_E_DIVERGED;
  if (!plausible) return DN_E_DIVERGED;
  for (int j = 0; j < DN_FULLCAR_STATE_SIZE; ++j) d.s[j] = ns[j];
  return status;
}

}  // namespace dampnet
