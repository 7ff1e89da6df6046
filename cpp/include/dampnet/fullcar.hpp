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
//
// The parts, by role (each includes the one before): fullcar/params.hpp (layout, defaults,
// validation, geometry), fullcar/model.hpp (FullCarModel, FullCarData), fullcar/dynamics.hpp (the
// equations of motion), fullcar/corners.hpp (the damper evaluations), fullcar/driver.hpp (the
// steering), fullcar/step.hpp (the step).
#pragma once

#include "dampnet/fullcar/step.hpp"
