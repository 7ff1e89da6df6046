"""The quarter-car loop in Python: the TEST ORACLE of the runtime's loop, used by tests only.

Nothing in the package runs it (every run goes through `dampnet.sim.quarter_car.loop.QuarterCar`, the
runtime's C++ loop); tests/python compare the runtime with it, so the two must agree to
rounding. It integrates exactly the runtime's equations (cpp/include/dampnet/loop.hpp,
thesis eq. 13-14) with the runtime's scheme for one damper evaluation per step
(DN_INT_RK4 with DN_EVAL_PER_STEP, `vehicle.LOOP_SCHEME`):

    m_s  a_s  = -k_s (z_s - z_us) - (F - f_static)
    m_us a_us =  k_s (z_s - z_us) + (F - f_static) - k_t (z_us - z_r) - c_t (v_us - v_r)

* the control u is computed by `control_law` (the Python mirror of `control_law` in
  loop.hpp: passive, skyhook/groundhook on-off and continuous) from the state at the step
  start and held over the step;
* the damper is evaluated at the step start, with x = z_s - z_us +
  x_static, v = v_s - v_us and the relative acceleration a = a_s - a_us.
  a and F are coupled (a = a_free - k (F(a) - f_static), k = 1/m_s + 1/m_us).
  For a neural damper that reads "acceleration", with
  Vehicle.accel_feature = "implicit" (default), the coupling is solved by
  `solve_acceleration`, the runtime's algorithm (dn_accel_feature in
  dampnet.h: Newton/secant from the explicit value, bisection in a bracket, at
  most ACCEL_MAX_EVALS evaluations, same tolerance); with "explicit", and for every
  other damper, a comes from the equations of motion with the force of the
  previous evaluation (f_last; the explicit scheme). ("linear" is not mirrored here.)
  Its force F is held over the step - a stateful damper (the truth damper's
  compressibility lag, LuGre friction) is therefore stepped exactly once per
  dt, as its `step(dt, ...)` requires;
* classical RK4 on (z_s, v_s, z_us, v_us) with the road at mid-step the cubic
  Hermite interpolant of (z_r, v_r) at the step's ends;
* every reported quantity is at the step's start time (like dn_loop_out).

A damper here is any object with `force(x, v, a, u, dt) -> F [N]` and `reset()` (and, with
derived-feature states, `advance(x, v, u, dt)`, called once at each step start);
`reference_damper(spec)` gives the Python damper of a `dampnet.sim.dampers.DamperSpec`.
"""

from __future__ import annotations

import math

import numpy as np

from dampnet import _core, features
from dampnet.reference import forward_of
from dampnet.sim.limits import PLAUSIBLE
from dampnet.sim.vehicle import Controller, LoopError, Vehicle
from dampnet.terms import terms_force

ACCEL_MAX_EVALS = _core.DN_ACCEL_MAX_EVALS

# ---- dampers (Python side) ---------------------------------------------------------------------

class LinearDamper:
    def __init__(self, c: float):
        self.c = float(c)

    def reset(self) -> None:
        pass

    def force(self, x, v, a, u, dt) -> float:
        return self.c * v


class TruthLoopDamper:
    """The rig's truth damper (dampnet.rig.truth.TruthDamper), stepped once per loop step."""

    def __init__(self, params=None, effects=(), temperature: float | None = None):
        from dampnet.rig.truth import TruthDamper

        self.damper = TruthDamper(params, effects)
        self.temperature = temperature

    def reset(self) -> None:
        self.damper.reset()

    def force(self, x, v, a, u, dt) -> float:
        return self.damper.step(dt, x, v, u, self.temperature)

    def force_at_rest(self, u: float, dt: float) -> float:
        from dampnet.rig.truth import TruthDamper

        return TruthDamper(self.damper.params, [e.name for e in self.damper.effects]).step(dt, 0.0, 0.0, u)


class TableLoopDamper:
    """A lookup table (dampnet.evaluation.lookup.LookupTable): force(v, u), bilinear, clamped."""

    def __init__(self, table):
        self.table = table

    def reset(self) -> None:
        pass

    def force(self, x, v, a, u, dt) -> float:
        return float(self.table.force(v, u))


class NeuralLoopDamper:
    """An MlpModel (with its physics terms) on the loop's kinematics.

    Each feature is fed from the dn_damper_input field the feature registry names
    (dampnet.features: x, v, a, u, temperature, and the derived features' states);
    temperature is constant, `temperature_c` (the runtime's default vehicle temperature).
    The damper's states are the runtime's block, by name (dampnet.h DN_DAMPER_STATE_LIST via
    dampnet.features.damper_states: every one, as the runtime keeps them, each moving by its
    dynamics when the model sets its parameter, else by the dynamics' default: a lag follows
    its source, a Dahl state stays), plus the states of Python-only derived features. They
    advance by `advance(x, v, u, dt)`, which the loop calls once at each step start, with the
    runtime's exact updates (damper_state.hpp: a lag of the control held over the previous
    step, a lag of a motion quantity as a ramp, the Dahl state by the net travel), so that
    this loop and the runtime's per-step loop give the same trajectories; `states` gives them
    (after an `advance`). `force` may be called any number of times in between (the implicit
    acceleration solve) and, before any `advance`, sees the steady state of its own inputs.
    The network is dampnet.reference's numpy forward (the kernel's function).
    """

    #: the loop quantities a feature may read directly (dn_damper_input fields)
    LOOP_INPUTS = ("x", "v", "a", "u", "temperature")
    #: the quantities a derived state may follow (known at the step start, before the damper)
    STATE_SOURCES = ("x", "v", "u")

    def __init__(self, model, temperature_c: float = 20.0):
        # states by dn_damper_input field: the runtime's block (parameter None: not set by the
        # model, the dynamics' default), then the model's derived features (voltage_lag and
        # current_lag share the runtime's control lag)
        fp = model.feature_params
        self._states: dict[str, tuple[features.State, float | None]] = {
            field: (state, float(fp[param]) if param in fp else None)
            for field, (state, param) in features.damper_states().items()}
        for name in model.features:
            try:
                f = features.feature(name)
            except KeyError as e:
                raise LoopError(f"the Python loop cannot feed feature {name!r}: {e.args[0]}") from None
            if f.state is None:
                if f.field not in self.LOOP_INPUTS:
                    raise LoopError(f"the Python loop cannot feed feature {name!r} (field {f.field!r})")
                continue
            if f.state.loop_input not in self.STATE_SOURCES:
                raise LoopError(f"the Python loop cannot feed feature {name!r}: its state follows "
                                f"{f.state.loop_input!r}, which is not known at the step start")
            value = float(model.feature_params.get(f.param, 0.0))
            if not value > 0:
                raise LoopError(f"feature {name!r} needs feature_params[{f.param!r}] > 0")
            self._states[f.field] = (f.state, value)
        self.model = model
        self.temperature_c = float(temperature_c)
        self._fields = [features.feature(name).field for name in model.features]
        self._forward = forward_of(model)
        self.reset()

    def reset(self) -> None:
        self._state: dict[str, float] | None = None  # states after the last advance(), by field
        self._prev: dict[str, float] | None = None   # loop quantities of the previous step start

    def forward(self, x: np.ndarray) -> np.ndarray:
        """MLP force [N] for inputs x [..., n_inputs] in feature units (no terms)."""
        return self._forward(x)

    def advance(self, x: float, v: float, u: float, dt: float) -> None:
        """The derived states at this step start (displacement x [m], velocity v [m/s], control u).

        As the runtime (loop.hpp, damper_state.hpp): the first step is the state at rest (lags
        equal their input, the Dahl state 0); then each state takes its exact update over the
        step (dampnet.features.Lag.step, Dahl.step), or without its parameter its default
        (Lag.off, Dahl.off).
        """
        q = {"x": x, "v": v, "u": u}
        if self._state is None or self._prev is None:
            self._state = {k: s.first(q) for k, (s, _) in self._states.items()}
        else:
            y, q0 = self._state, self._prev
            self._state = {k: s.step(y[k], q0, q, dt, p) if p is not None else s.off(y[k], q0, q)
                           for k, (s, p) in self._states.items()}
        self._prev = q

    @property
    def states(self) -> dict[str, float]:
        """The damper's states at the last `advance` by name, the runtime's block in its order
        (_core.DAMPER_STATES: the loop's state columns of those names); {} before any."""
        if self._state is None:
            return {}
        return {k: self._state[k] for k in _core.DAMPER_STATES}

    def force(self, x, v, a, u, dt) -> float:
        """Force [N] (MLP plus terms) at the derived features' current states."""
        q = {"x": x, "v": v, "a": a, "u": u, "temperature": self.temperature_c}
        if self._state is None:
            q.update({k: s.steady(q) for k, (s, _) in self._states.items()})
        else:
            q.update(self._state)
        f = float(self._forward(np.array([q[k] for k in self._fields], dtype=np.float64)))
        if self.model.terms:
            f += float(terms_force(self.model.terms, np.array(x), np.array(v), u=np.array(u)))
        return f

    @property
    def acceleration_input(self) -> int | None:
        """Index of the "acceleration" input, or None."""
        f = self.model.features
        return f.index("acceleration") if "acceleration" in f else None


def control_law(ctrl: Controller, v_s: float, v_us: float) -> float:
    """The control [V] of a controller at sprung / unsprung velocities v_s, v_us [m/s]: the
    Python mirror of loop.hpp's control_law (before the command filter)."""
    v = v_s - v_us
    k = ctrl.kind
    if k == "passive":
        return min(max(ctrl.u_passive, ctrl.u_min), ctrl.u_max)
    d = 0.0
    if k == "skyhook_onoff":
        d = 1.0 if v_s * v > 0 else 0.0
    elif k == "groundhook_onoff":
        d = 1.0 if -v_us * v > 0 else 0.0
    elif k == "skyhook_continuous":
        if v_s * v > 0:
            d = min(max((ctrl.c_sky * v_s / v - ctrl.c_min) / (ctrl.c_max - ctrl.c_min), 0.0), 1.0)
    elif k == "groundhook_continuous":
        if -v_us * v > 0:
            d = min(max((-ctrl.c_gnd * v_us / v - ctrl.c_min) / (ctrl.c_max - ctrl.c_min), 0.0), 1.0)
    else:
        raise LoopError(f"the reference loop does not mirror the control law {k!r}")
    u = ctrl.u_soft + d * (ctrl.u_hard - ctrl.u_soft)
    return min(max(u, ctrl.u_min), ctrl.u_max)


def reference_damper(spec):
    """The Python damper of a DamperSpec (dampnet.sim.dampers) for this loop."""
    if spec.kind == "truth":
        return TruthLoopDamper(effects=spec.obj or ())
    if spec.kind in ("neural", "hybrid"):
        return NeuralLoopDamper(spec.obj)
    if spec.kind == "lookup":
        return TableLoopDamper(spec.obj)
    if spec.kind == "linear":
        return LinearDamper(spec.obj)
    raise LoopError(f"no Python form of a {spec.kind!r} damper")


def solve_acceleration(force_of_a, a_explicit: float, f_last: float, k: float, f_static: float,
                       a_lo: float, a_hi: float, f_eps: float = 1e-12, slope: float = 0.0):
    """Solve g(a) = a - a_free + k (F(a) - f_static) = 0: the runtime's implicit acceleration feature.

    The same equation, start, safeguards and tolerance as dampnet::detail::evaluate
    (loop.hpp), which takes its slope analytically from the MLP; this Python
    reference estimates it (below), so the two converge to the same root within the
    tolerance through different iterates. Start at the
    explicit value a_explicit (from f_last); slope 1 where a is outside
    [a_lo, a_hi] (the MLP clamps it), else the given slope when positive, else
    a forward difference of 1e-4 (a_hi - a_lo) toward the root; then Newton
    with the latest secant slope (the fixed-point step a - g when the slope is
    below 1e-3), bisection when a step leaves a bracket [g < 0, g > 0]; at most
    ACCEL_MAX_EVALS evaluations; converged when |g| <= 1e-7 (1 + |a_free|) +
    k f_eps (1 + |F|). Returns (a, F, converged, evaluations, slope); not
    converged: the evaluated point with the smallest |g|.
    """
    a_free = a_explicit + k * (f_last - f_static)
    evals = 0

    def ev(a):
        nonlocal evals
        evals += 1
        f = float(force_of_a(a))
        return (a, f, a - a_free + k * (f - f_static))

    def conv(r):
        return abs(r[2]) <= 1e-7 * (1.0 + abs(a_free)) + k * f_eps * (1.0 + abs(r[1]))

    lo = hi = None
    cur = best = ev(a_explicit)

    def note(r):
        nonlocal lo, hi, best
        if r[2] < 0:
            lo = r
        elif r[2] > 0:
            hi = r
        if abs(r[2]) < abs(best[2]):
            best = r

    note(cur)
    done = conv(cur)
    s = slope if (slope > 0 and math.isfinite(slope)) else 0.0
    if not (a_lo <= cur[0] <= a_hi):
        s = 1.0
    if not done and not s > 0:
        h = 1e-4 * (a_hi - a_lo if a_hi > a_lo else 1.0)
        prev = cur
        cur = ev(cur[0] - (h if cur[2] > 0 else -h))
        s = (cur[2] - prev[2]) / (cur[0] - prev[0])
        note(cur)
        done = conv(cur)
        if abs(prev[2]) < abs(cur[2]):
            prev, cur = cur, prev
    while not done and evals < ACCEL_MAX_EVALS:
        an = cur[0] - cur[2] / s if (s > 1e-3 and math.isfinite(s)) else cur[0] - cur[2]
        if lo is not None and hi is not None:
            b0, b1 = min(lo[0], hi[0]), max(lo[0], hi[0])
            if not (b0 < an < b1):
                an = 0.5 * (lo[0] + hi[0])
        if not math.isfinite(an) or an == cur[0]:
            break
        nxt = ev(an)
        if not math.isfinite(nxt[2]):
            break
        s = (nxt[2] - cur[2]) / (nxt[0] - cur[0])
        cur = nxt
        note(cur)
        done = conv(cur)
    r = cur if done else best
    return r[0], r[1], done, evals, s


# ---- the loop ----------------------------------------------------------------------------------

_BOUNDS = {k: v for k, (v, _doc) in PLAUSIBLE.items()}


def implausible(travel: float, wheel_road: float, damper_speed: float) -> str | None:
    """Which of the runtime's physical bounds (dampnet.h DN_PLAUSIBLE_LIST) a corner's new state
    leaves, in words, or None: the runtime's plausible_corner (loop.hpp)."""
    for name, value, key in (("suspension travel", travel, "DN_PLAUSIBLE_TRAVEL_M"),
                             ("wheel to road", wheel_road, "DN_PLAUSIBLE_WHEEL_ROAD_M"),
                             ("damper velocity", damper_speed, "DN_PLAUSIBLE_DAMPER_SPEED_M_S")):
        if not abs(value) <= _BOUNDS[key]:
            return f"{name} {value:.4g} beyond {_BOUNDS[key]:g} ({key})"
    return None


def run(damper, z_r, v_r, vehicle: Vehicle | None = None, controller: Controller | None = None) -> dict:
    """Run the loop over road samples z_r [m], v_r [m/s] at t = k dt; arrays at each step's start.

    Returns t, z_s, v_s, z_us, v_us, z_r, acc_s, acc_us, force, u, x, v, a (n = len(z_r) - 1
    steps; the last road sample is the end of the last step); with the implicit acceleration
    feature also accel_evals and accel_converged per step; with a damper that keeps the
    runtime's damper states (NeuralLoopDamper.states) each of them by its name (u_lag, ...:
    _core.DAMPER_STATES, the runtime loop's state columns of the same names).
    """
    veh = vehicle or Vehicle()
    ctrl = controller or Controller()
    veh.validate()
    ctrl.validate()
    if veh.accel_feature not in ("implicit", "explicit"):
        raise LoopError(f"the reference loop mirrors accel_feature 'implicit' and 'explicit', not {veh.accel_feature!r}")
    z_r = np.asarray(z_r, dtype=np.float64)
    v_r = np.asarray(v_r, dtype=np.float64)
    if z_r.ndim != 1 or z_r.shape != v_r.shape:
        raise LoopError("road displacement and rate must be 1-D arrays of equal length")
    if z_r.size < 2:
        raise LoopError("the road must cover at least one time step (2 samples)")
    bad = np.flatnonzero(~(np.isfinite(z_r) & np.isfinite(v_r)))
    if bad.size:
        raise LoopError(f"road sample {bad[0]} is not finite")
    h = veh.dt
    ms, mus, ks, kt, ct = veh.m_s, veh.m_us, veh.k_s, veh.k_t, veh.c_t
    damper.reset()
    u0 = control_law(ctrl, 0.0, 0.0)
    # Command filter (the runtime's u_tau_s): the law's control through a first-order
    # low-pass, sampled at the step start and held; it starts settled at the control at rest.
    cmd_keep = math.exp(-veh.dt / ctrl.u_tau_s) if ctrl.u_tau_s > 0 else 0.0
    u_cmd = u0
    if veh.f_static is None:
        rest = getattr(damper, "force_at_rest", None)
        f_static = float(rest(u0, h)) if rest else float(damper.force(veh.x_static, 0.0, 0.0, u0, h))
        damper.reset()
    else:
        f_static = float(veh.f_static)
    n = z_r.size - 1
    out = {k: np.empty(n) for k in ("t", "z_s", "v_s", "z_us", "v_us", "z_r", "acc_s", "acc_us",
                                     "force", "u", "x", "v", "a")}
    zs = vs = zus = vus = 0.0
    f_last = f_static
    inv_ms, inv_mus = 1.0 / ms, 1.0 / mus
    ia = getattr(damper, "acceleration_input", None) if veh.accel_feature == "implicit" else None
    advance = getattr(damper, "advance", None)  # derived-feature states, once per step
    if advance is not None and hasattr(damper, "states"):
        out.update({name: np.empty(n) for name in _core.DAMPER_STATES})
    if ia is not None:
        a_lo, a_hi = float(damper.model.sat_lo[ia]), float(damper.model.sat_hi[ia])
        out["accel_evals"] = np.ones(n, dtype=np.int64)
        out["accel_converged"] = np.ones(n, dtype=bool)

    def accel(zs, vs, zus, vus, zr, vr, f):
        fs = ks * (zs - zus)
        fa = f - f_static
        return (-fs - fa) * inv_ms, (fs + fa - kt * (zus - zr) - ct * (vus - vr)) * inv_mus

    for k in range(n):
        zr0, vr0, zr1, vr1 = z_r[k], v_r[k], z_r[k + 1], v_r[k + 1]
        u = control_law(ctrl, vs, vus)
        if cmd_keep > 0.0:
            u += (u_cmd - u) * cmd_keep
        u_cmd = u
        as_l, aus_l = accel(zs, vs, zus, vus, zr0, vr0, f_last)
        x, v, a = zs - zus + veh.x_static, vs - vus, as_l - aus_l
        if advance is not None:
            advance(x, v, u, h)
            for name, value in damper.states.items():
                out[name][k] = value
        if ia is not None:
            a, f, ok, ne, _ = solve_acceleration(lambda aa: damper.force(x, v, aa, u, h), a, f_last,
                                                 inv_ms + inv_mus, f_static, a_lo, a_hi)
            out["accel_evals"][k] = ne
            out["accel_converged"][k] = ok
        else:
            f = float(damper.force(x, v, a, u, h))
        if not math.isfinite(f):
            raise LoopError(f"damper force is not finite at t = {k * h:.6g} s (x={x:.4g}, v={v:.4g}, u={u:.4g})")
        k1s, k1u = accel(zs, vs, zus, vus, zr0, vr0, f)
        zrm = 0.5 * (zr0 + zr1) + 0.125 * h * (vr0 - vr1)
        vrm = 1.5 * (zr1 - zr0) / h - 0.25 * (vr0 + vr1)
        b1 = (zs + 0.5 * h * vs, vs + 0.5 * h * k1s, zus + 0.5 * h * vus, vus + 0.5 * h * k1u)
        k2s, k2u = accel(*b1, zrm, vrm, f)
        b2 = (zs + 0.5 * h * b1[1], vs + 0.5 * h * k2s, zus + 0.5 * h * b1[3], vus + 0.5 * h * k2u)
        k3s, k3u = accel(*b2, zrm, vrm, f)
        b3 = (zs + h * b2[1], vs + h * k3s, zus + h * b2[3], vus + h * k3u)
        k4s, k4u = accel(*b3, zr1, vr1, f)
        row = (k * h, zs, vs, zus, vus, zr0, k1s, k1u, f, u, x, v, a)
        for key, val in zip(out, row):
            out[key][k] = val
        h6 = h / 6.0
        zs, vs, zus, vus = (zs + h6 * (vs + 2 * b1[1] + 2 * b2[1] + b3[1]),
                            vs + h6 * (k1s + 2 * k2s + 2 * k3s + k4s),
                            zus + h6 * (vus + 2 * b1[3] + 2 * b2[3] + b3[3]),
                            vus + h6 * (k1u + 2 * k2u + 2 * k3u + k4u))
        f_last = f
        if not (math.isfinite(zs) and math.isfinite(vs) and math.isfinite(zus) and math.isfinite(vus)):
            raise LoopError(f"the loop diverged at t = {(k + 1) * h:.6g} s (reduce dt?)")
        beyond = implausible(zs - zus, zus - zr1, vs - vus)
        if beyond:
            raise LoopError(f"the loop left physical plausibility at t = {(k + 1) * h:.6g} s: {beyond} "
                            "(the runtime's DN_E_DIVERGED)")
    out["f_static"] = f_static
    return out
