// FullCarModel (constant: parameters, the four Corners, the mobility, the driver's path) and
// FullCarData (mutable: the flat state). Part of fullcar.hpp.
#pragma once

#include "dampnet/fullcar/params.hpp"

namespace dampnet {

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
  bool any_force_law = false;  // some corner's law tracks a force (is_force_law): its inverse
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
    any_implicit = any_force_law = false;
    for (int i = 0; i < kCorners; ++i) {
      if (!dampers[i]) return DN_E_NULL;
      dn_controller c = ctrls ? ctrls[i] : default_controller(DN_CTRL_PASSIVE);
      if (!ctrls) c.u_passive = 0.0;
      xs[i] = i < 2 ? v.x_static_f : v.x_static_r;
      st = corner[i].init(*dampers[i], c, v.dt, v.accel_feature);
      if (st != DN_OK) return st;
      if (corner[i].implicit_a) any_implicit = true;
      if (is_force_law(c.kind)) any_force_law = true;
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

}  // namespace dampnet
