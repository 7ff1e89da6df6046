// The road-wheel angle of a step: the preview driver (MacAdam) or the open-loop input, with
// the steering lag and rate limit. Part of fullcar.hpp.
#pragma once

#include "dampnet/fullcar/corners.hpp"

namespace dampnet {
namespace detail {


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

}  // namespace detail
}  // namespace dampnet
