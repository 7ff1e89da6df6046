// The full car's equations of motion: the forces that do not depend on the dampers, the body and
// wheel accelerations for given damper forces, the RK4 vector's derivative, a 4x4 solve.
// Part of fullcar.hpp (its file comment gives the equations).
#pragma once

#include "dampnet/fullcar/model.hpp"

namespace dampnet {
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

}  // namespace detail
}  // namespace dampnet
