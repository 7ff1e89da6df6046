// The four corners' damper evaluations at one point (the explicit, batched, linear and Newton
// schemes of the acceleration feature), their inputs, and the flat state's motion. Part of
// fullcar.hpp.
#pragma once

#include "dampnet/fullcar/dynamics.hpp"

namespace dampnet {
namespace detail {


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

}  // namespace detail
}  // namespace dampnet
