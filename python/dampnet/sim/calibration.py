"""Control laws calibrated on a damper: its damping levels, its equivalent linear damping,
the semi-active controllers: the calibrations the control-law registry (dampnet.recipes.control_laws)
builds every law with.

Damping levels (`damping_levels`): "low" and "high" damping are the controls giving the
least and the most damping. They are found, not assumed: the damper's force at 0.5 m/s
(rebound) and -0.5 m/s is evaluated at the ends of the control range and the end with the
larger summed |force| is "high". For the rig's damper that is 0 V (valve closed) = high,
5 V = low.

Continuous skyhook (`continuous_skyhook`). The runtime's law (skyhook_continuous) asks for
the damping c_des = c_sky v_s / v when v_s v > 0 (else the soft setting) and maps it
linearly onto the control, c_min -> u_soft, c_max -> u_hard. Its settings come from the
vehicle and the damper, not from a study's result:
  c_sky        = zeta_sky 2 sqrt(k_s m_s), zeta_sky = 1/sqrt(2): the skyhook-ideal body
                 transmissibility k_s / (m_s s^2 + c_sky s + k_s) then has no resonant peak
                 (4583 N s/m for Table 5's vehicle);
  c_min, c_max = the damper's equivalent linear damping at u_soft and u_hard: statistical
                 linearisation c_eq(u) = E[F v] / E[v^2] of its steady force for a Gaussian
                 damper velocity of RMS 0.2 m/s (the rig damper's velocity RMS on the thesis
                 rough road at the soft setting: 0.185 m/s at 10 m/s, 0.255 m/s at 20 m/s).
                 For the rig's damper 1662 N s/m at 5 V and 5534 N s/m at 0 V (c_eq is close
                 to linear in the voltage in between: 3709 N s/m at 2.5 V), so the linear map
                 is right. The controller defaults (500 and 4000 N s/m) put 2500 N s/m at about
                 2.1 V, where the rig damper gives about 4500 N s/m.

Continuous groundhook (`continuous_groundhook`), by the same principle. The runtime's law
(groundhook_continuous) asks for c_des = c_gnd (-v_us) / v when -v_us v > 0 (else the soft
setting), mapped onto the control by the same c_min -> u_soft, c_max -> u_hard:
  c_gnd        = zeta_gnd 2 sqrt((k_s + k_t) m_us), zeta_gnd = 1/sqrt(2): the groundhook-ideal
                 wheel (a damper from the wheel to the ground, the body held still at the wheel
                 hop) m_us s^2 + c_gnd s + k_s + k_t then has no resonant peak (4147 N s/m for
                 Table 5's vehicle; the runtime's default is 2500 N s/m whatever the damper);
  c_min, c_max = the damper's equivalent linear damping at u_soft and u_hard, as for skyhook.

Command filter. Both skyhook laws pass their control through a first-order low-pass of
SKYHOOK_COMMAND_TAU_S = 5 ms (the runtime's u_tau_s: a 32 Hz corner, 20 degrees of lag at the
11.7 Hz wheel hop), as a real semi-active controller smooths its command. Unfiltered, the laws
jump between controls (continuous skyhook from hard to soft each time v changes sign while
v_s does not), each jump is a step of damper force that jolts the body, and a model whose
force answers the acceleration spike of that step (the thesis's inputs include the
acceleration) turns it into an error: the road model was +2.7 / +3.8 % off the truth under
unfiltered continuous skyhook, -0.2 / +0.6 % with the filter (10 / 20 m/s).

The force-tracking laws (`force_tracking`) are unfiltered by default (FORCE_COMMAND_TAU_S = 0):
their command is the inverse of a demanded force, and the filter delays the force it sets. On the
default model's quarter car over the study's ISO roads the 5 ms filter leaves the tracked force
12-41 % RMS off a reachable demand, against 0.0-0.2 % unfiltered (bench/experiments/force_tracking.py),
and its Wk comfort was worse on every road and speed (bench/RESULTS.md, "Semi-active control
against the ideal").
A caller's u_tau_s still sets one.
"""

from __future__ import annotations

import math

import numpy as np

from dampnet.sim.dampers import DamperSpec, steady_forces
from dampnet.sim.vehicle import Controller, Vehicle

SKYHOOK_ZETA = 1.0 / math.sqrt(2.0)
GROUNDHOOK_ZETA = 1.0 / math.sqrt(2.0)
SKYHOOK_V_RMS_M_S = 0.2
# Command filter of the study's semi-active laws [s] (the runtime's u_tau_s; see the module
# docstring): a 32 Hz corner, 20 degrees of lag at the 11.7 Hz wheel hop, five 1 ms steps.
SKYHOOK_COMMAND_TAU_S = 0.005
#: the force-tracking laws' command filter [s] by default: none (see the module docstring)
FORCE_COMMAND_TAU_S = 0.0


def damping_levels(spec: DamperSpec, dt: float = 1e-3) -> dict:
    """{'low': u, 'high': u}: the ends of the control range giving the least / most damping."""
    lo, hi = spec.u_range
    score = {u: float(np.sum(np.abs(steady_forces(spec, [0.5, -0.5], u, dt)))) for u in (lo, hi)}
    high = lo if score[lo] >= score[hi] else hi
    low = hi if high == lo else lo
    return dict(low=float(low), high=float(high))


def equivalent_damping(spec: DamperSpec, u: float, v_rms: float = SKYHOOK_V_RMS_M_S, dt: float = 1e-3,
                       nodes: int = 24) -> float:
    """Equivalent linear damping [N s/m] of a damper at control u: E[F v] / E[v^2], v ~ N(0, v_rms^2).

    Statistical linearisation (Gauss-Hermite quadrature) of the steady force
    (dampers.steady_forces: the truth's after its lag) at x = 0, a = 0.
    """
    x, w = np.polynomial.hermite_e.hermegauss(nodes)
    w = w / w.sum()
    v = v_rms * x
    f = steady_forces(spec, v, u, dt)
    f = f - np.sum(w * f)
    return float(np.sum(w * f * v) / np.sum(w * v * v))


def damping_range(spec: DamperSpec, levels: dict, vehicle: Vehicle,
                  v_rms: float = SKYHOOK_V_RMS_M_S) -> tuple[float, float]:
    """(c_min, c_max) [N s/m] of the continuous laws: equivalent_damping at the low / high damping
    levels. A damper whose damping does not rise from low to high (a linear damper) keeps the
    Controller's defaults: the control does nothing to it anyway."""
    c_min = equivalent_damping(spec, levels["low"], v_rms, vehicle.dt)
    c_max = equivalent_damping(spec, levels["high"], v_rms, vehicle.dt)
    if not (math.isfinite(c_min) and math.isfinite(c_max) and c_max > c_min):
        return Controller.c_min, Controller.c_max
    return c_min, c_max


def skyhook_gain(veh: Vehicle, zeta: float = SKYHOOK_ZETA) -> float:
    """c_sky [N s/m] = zeta 2 sqrt(k_s m_s): the skyhook-ideal body without a resonant peak."""
    return zeta * 2.0 * math.sqrt(veh.k_s * veh.m_s)


def groundhook_gain(veh: Vehicle, zeta: float = GROUNDHOOK_ZETA) -> float:
    """c_gnd [N s/m] = zeta 2 sqrt((k_s + k_t) m_us): the groundhook-ideal wheel without a resonant peak."""
    return zeta * 2.0 * math.sqrt((veh.k_s + veh.k_t) * veh.m_us)


def continuous_skyhook(spec: DamperSpec, levels: dict | None = None, vehicle: Vehicle | None = None,
                       zeta_sky: float = SKYHOOK_ZETA, v_rms: float = SKYHOOK_V_RMS_M_S,
                       u_tau_s: float = SKYHOOK_COMMAND_TAU_S) -> Controller:
    """The continuous skyhook controller calibrated on a damper (see the module docstring).

    c_sky = zeta_sky 2 sqrt(k_s m_s); c_min / c_max = `damping_range`; u_tau_s the command
    filter's time constant [s] (0: none).
    """
    veh = vehicle or Vehicle()
    lv = levels or damping_levels(spec, veh.dt)
    c_min, c_max = damping_range(spec, lv, veh, v_rms)
    return semi_active("skyhook_continuous", lv, u_tau_s, c_sky=skyhook_gain(veh, zeta_sky), c_min=c_min, c_max=c_max)


def continuous_groundhook(spec: DamperSpec, levels: dict | None = None, vehicle: Vehicle | None = None,
                          zeta_gnd: float = GROUNDHOOK_ZETA, v_rms: float = SKYHOOK_V_RMS_M_S,
                          u_tau_s: float = SKYHOOK_COMMAND_TAU_S) -> Controller:
    """The continuous groundhook controller calibrated on a damper (see the module docstring).

    c_gnd = zeta_gnd 2 sqrt((k_s + k_t) m_us); c_min / c_max = `damping_range`; u_tau_s the
    command filter's time constant [s] (0: none).
    """
    veh = vehicle or Vehicle()
    lv = levels or damping_levels(spec, veh.dt)
    c_min, c_max = damping_range(spec, lv, veh, v_rms)
    return semi_active("groundhook_continuous", lv, u_tau_s,
                       c_gnd=groundhook_gain(veh, zeta_gnd), c_min=c_min, c_max=c_max)


def force_tracking(kind: str, spec: DamperSpec, levels: dict | None = None, vehicle: Vehicle | None = None,
                   u_tau_s: float = FORCE_COMMAND_TAU_S, alpha: float = 0.5) -> Controller:
    """A force-tracking law (skyhook_force, groundhook_force, hybrid_force, clipped_optimal: the
    demanded force [N] through the damper's inverse) calibrated on the vehicle: c_sky and c_gnd as
    the continuous laws' (no resonant peak of the ideal body / wheel), hybrid_force's skyhook share
    `alpha`, clipped_optimal's gains `lqr_gains`; the control limited to the damper's levels;
    unfiltered unless `u_tau_s` [s] is given (FORCE_COMMAND_TAU_S)."""
    veh = vehicle or Vehicle()
    lv = levels or damping_levels(spec, veh.dt)
    gains = {"c_sky": skyhook_gain(veh), "c_gnd": groundhook_gain(veh), "alpha": alpha}
    if kind == "clipped_optimal":
        gains.update(lqr_gains(veh))
    return semi_active(kind, lv, u_tau_s, **gains)


#: clipped_optimal's LQR weights: J = integral of (a_s / A_REF)^2 + (travel / TRAVEL_REF)^2 +
#: (k_t tyre deflection / TYRE_LOAD_REF)^2 + (F / FORCE_REF)^2 dt. Body acceleration counts most
#: (comfort); 0.1 m/s^2 of it weighs as 5 cm of travel, as 1 kN of dynamic tyre load, and as 20 kN
#: of force (the force weight only keeps R > 0; the clipping to the damper is the real limit).
LQR_REFS = {"a_ref": 0.1, "travel_ref": 0.05, "tyre_load_ref": 1000.0, "force_ref": 20000.0}


def lqr_design(vehicle: Vehicle | None = None, refs: dict | None = None):
    """(A, B, Q, R, N) of the linear quarter car for clipped_optimal's LQR: state x = [travel
    z_s - z_us [m], v_s [m/s], tyre deflection z_us - z_r [m], v_us [m/s]], input the damper force
    F [N] (positive resisting extension: m_s a_s = -k_s travel - F), the road rate a disturbance;
    cost x'Qx + 2 x'N F + R F^2 (LQR_REFS, a_s = C x + D F giving the cross term)."""
    veh = vehicle or Vehicle()
    r = {**LQR_REFS, **(refs or {})}
    ms, mus, ks, kt, ct = veh.m_s, veh.m_us, veh.k_s, veh.k_t, veh.c_t
    A = np.array([[0, 1, 0, -1], [-ks / ms, 0, 0, 0], [0, 0, 0, 1], [ks / mus, 0, -kt / mus, -ct / mus]], float)
    B = np.array([[0.0], [-1 / ms], [0.0], [1 / mus]])
    C = np.array([[-ks / ms, 0, 0, 0]]) / r["a_ref"]
    D = -1 / ms / r["a_ref"]
    Q = C.T @ C + np.diag([1 / r["travel_ref"] ** 2, 0, (kt / r["tyre_load_ref"]) ** 2, 0])
    N = C.T * D
    R = np.array([[D * D + 1 / r["force_ref"] ** 2]])
    return A, B, Q, R, N


def lqr_gains(vehicle: Vehicle | None = None, refs: dict | None = None) -> dict:
    """clipped_optimal's gains {k_travel [N/m], k_vs [N s/m], k_tyre [N/m], k_vus [N s/m]}: the
    optimal state feedback F = -K x of `lqr_design` (scipy's continuous Riccati solver), F_d = k . x."""
    from scipy.linalg import solve_continuous_are

    A, B, Q, R, N = lqr_design(vehicle, refs)
    P = solve_continuous_are(A, B, Q, R, s=N)
    K = np.linalg.solve(R, B.T @ P + N.T)[0]
    return dict(zip(("k_travel", "k_vs", "k_tyre", "k_vus"), (-K).tolist()))


def semi_active(kind: str, levels: dict, u_tau_s: float = SKYHOOK_COMMAND_TAU_S, **law) -> Controller:
    """A control law (kind: a `_core.CONTROLLER_KINDS` name) between a damper's own low and high
    damping settings (`damping_levels`), limited to them, with the command filter; `law`: its
    other settings (c_sky, c_min, ...). A wrong name raises LoopError listing the valid ones."""
    ctrl = Controller(kind=kind, u_soft=levels["low"], u_hard=levels["high"], u_min=min(levels.values()),
                      u_max=max(levels.values()), u_tau_s=u_tau_s, **law)
    ctrl.validate()
    return ctrl
