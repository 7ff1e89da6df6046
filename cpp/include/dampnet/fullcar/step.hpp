// One full-car step: the step start, the RK4 stages with their damper evaluations, each corner's
// end; reset, forward and step. Part of fullcar.hpp.
#pragma once

#include "dampnet/fullcar/driver.hpp"

namespace dampnet {
namespace detail {


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

// The corners whose law tracks a force: the damper's inverse of the demand at the step start's
// input (its states filled), after the command filter; out of the hot step (a cold call). With
// the coupling solved (DN_ACCEL_IMPLICIT) the inverse reads the acceleration the step solves to
// when every tracking corner gives its demand and the others their last force, as the quarter car
// does (detail::force_law_start): a = a(f_last) - K (F - f_last).
DN_FC_COLD inline void force_law_commands(const FullCarModel& m, const FcMotion& y, const FcFree& f,
                                          const double* zr, const double* s, dn_damper_input* di, double* u,
                                          int64_t* n_evals) noexcept {
  double demand[kCorners] = {}, moved[kCorners] = {};  // moved: F - f_last where a demand is given
#pragma GCC unroll 1
  for (int i = 0; i < kCorners; ++i) {
    const Corner& c = m.corner[i];
    if (!is_force_law(c.ctrl.kind)) continue;
    demand[i] = force_demand(c.ctrl, f.vb[i], y.vus[i], f.dfl[i], y.zus[i] - zr[i]);
    if (demand[i] != 0) moved[i] = m.fs[i] + demand[i] - s[fc_corner(i, FCC_f_last)];
  }
#pragma GCC unroll 1
  for (int i = 0; i < kCorners; ++i) {
    const Corner& c = m.corner[i];
    if (!is_force_law(c.ctrl.kind)) continue;
    const double a_explicit = di[i].a;
    if (c.implicit_a && !c.linear_a)
      for (int j = 0; j < kCorners; ++j) di[i].a -= m.K[i][j] * moved[j];
    u[i] = c.command_force(di[i], m.fs[i], demand[i], s[fc_corner(i, FCC_u_cmd)], n_evals);
    di[i].a = a_explicit;  // (the step's evaluation starts from the explicit value)
    di[i].u = u[i];
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
  if (m.any_force_law) force_law_commands(m, y, r.f, zr, s, di, r.u, n_evals);
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
