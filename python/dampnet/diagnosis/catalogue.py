"""The catalogue of candidate physical effects: the one place to add your own.

A candidate says which inputs it needs, why it matters physically, what it
looks like in the residual, and how to test it: `columns(ctx, theta)` returns,
per test, regressors [rows, q] built from the physics (not from the residual),
for a value `theta` of its one nonlinear parameter (a time constant, a
pre-sliding length; None if it has none) chosen on a `grid`. The scorer
(`dampnet.diagnosis.score`) fits them to the residual on some tests, scores them
on the others, and compares the score with a null. `parameters(ctx, theta, fit)`
turns the fitted effect into numbers worth knowing; `additions(params, control)`
says what `dampnet train --add ID` adds to the model.

To add your own candidate:

    from dampnet.diagnosis.catalogue import Candidate, register_candidate
    register_candidate(Candidate(id="my_effect", title=..., needs=..., physics=...,
                                 signature=..., columns=my_columns, ...))

The built-in ids are fixed: gas_spring, thermal, valve_lag, friction, compressibility.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from dampnet.features import dahl_state, first_order_lag


@dataclass
class Candidate:
    id: str
    title: str
    needs: str                      # the inputs it needs, in words
    physics: str                    # the physical explanation
    signature: str                  # what it looks like in the residual
    columns: Callable               # (ctx, theta) -> list of [rows, q] arrays, one per test
    grid: Callable = lambda ctx: [None]          # ctx -> values of the nonlinear parameter
    testable: Callable = lambda ctx: (True, "")  # ctx -> (ok, note)
    parameters: Callable | None = None           # (ctx, theta, fit) -> {name: value}
    add: Callable | None = None                  # (params, control) -> additions dict
    evidence: Callable | None = None             # (params, loc) -> sentence
    theta_name: str | None = None                # name and unit of theta, e.g. "tau_s"
    extra: dict = field(default_factory=dict)


CANDIDATES: dict[str, Candidate] = {}


def register_candidate(c: Candidate) -> Candidate:
    """Add (or replace) a candidate effect in the catalogue."""
    CANDIDATES[c.id] = c
    return c


# -- helpers ---------------------------------------------------------------------

def _scale(arrs, q=99.5) -> tuple[float, float]:
    a = np.concatenate([np.asarray(x) for x in arrs if x is not None])
    lo, hi = np.percentile(a, [100 - q, q])
    c, h = 0.5 * (lo + hi), 0.5 * (hi - lo)
    return float(c), float(h if h > 0 else 1.0)


def _vel_norm(ctx):
    v = ctx.at_rows("velocity")
    s = max(float(np.max(np.abs(np.concatenate(v)))), 1e-12)
    return [x / s for x in v], s


def _control_name_in_model(ctx) -> str | None:
    for f in ctx.model.features:
        if f in ("voltage", "current"):
            return f
    return None


def _log_grid(lo, hi, n):
    return list(np.exp(np.linspace(np.log(lo), np.log(hi), n)))


def _min_dt(ctx) -> float:
    return min(td.test.dt for td in ctx.tests)


# -- gas_spring: position-dependent force ----------------------------------------------

def _x_frame(ctx):
    if "x_frame" not in ctx.notes:
        ctx.notes["x_frame"] = _scale(ctx.at_rows("displacement"))
    return ctx.notes["x_frame"]


def gas_columns_of(x, c, h):
    """Legendre polynomials 1-5 of the normalised position and squared end-of-travel hinges."""
    z = np.clip((np.asarray(x) - c) / h, -1.5, 1.5)
    p = [z, 0.5 * (3 * z**2 - 1), 0.5 * (5 * z**3 - 3 * z), (35 * z**4 - 30 * z**2 + 3) / 8,
         (63 * z**5 - 70 * z**3 + 15 * z) / 8]
    ends = [np.maximum(z - k, 0.0) ** 2 for k in (0.5, 0.7, 0.85)] + \
           [np.maximum(-z - k, 0.0) ** 2 for k in (0.5, 0.7, 0.85)]
    return np.stack(p + ends, axis=-1)


def _gas_columns(ctx, theta):
    c, h = _x_frame(ctx)
    return [gas_columns_of(x, c, h) for x in ctx.at_rows("displacement")]


def _gas_testable(ctx):
    if any(x is None for x in ctx.at_rows("displacement")):
        return False, "no displacement channel"
    return True, ""


def _gas_parameters(ctx, theta, fit):
    c, h = _x_frame(ctx)
    b = fit["beta"]
    g = lambda x: gas_columns_of(np.atleast_1d(x), c, h) @ b  # noqa: E731
    dx = 0.1 * h
    k = float((g(c + dx) - g(c - dx))[0] / (2 * dx))
    return {"stiffness_mid_n_per_mm": k / 1000.0,
            "force_at_full_extension_n": float((g(c + h) - g(c))[0]),
            "force_at_full_compression_n": float((g(c - h) - g(c))[0])}


def _gas_evidence(p, loc):
    return (f"the residual follows position, not velocity: a spring of {p['stiffness_mid_n_per_mm']:.3g} N/mm "
            f"at mid-stroke, {p['force_at_full_compression_n']:+.0f} N at full compression and "
            f"{p['force_at_full_extension_n']:+.0f} N at full extension relative to mid-stroke "
            "(see 'residual against displacement' and the residual restoring-force surface: "
            "bands across the velocity axis)")


register_candidate(Candidate(
    id="gas_spring", title="position-dependent force (gas spring, top-out, bump stops)",
    needs="displacement",
    physics="The gas charge behind the floating piston is compressed polytropically as the rod enters "
            "(p V^n = const), so the force grows with position; elastomer bump stops and top-out "
            "springs add steep forces near the ends of travel. None of it depends on velocity.",
    signature="residual a smooth, mostly increasing function of displacement, the same in rebound and "
              "compression; steepening near the ends of travel; horizontal bands in the "
              "displacement-velocity plane",
    columns=_gas_columns, testable=_gas_testable, parameters=_gas_parameters,
    add=lambda p, control: {"features": ["displacement"], "terms": [], "feature_params": {},
                            "how": "feature",
                            "why": "displacement as an MLP input: the network learns a gas spring of any "
                                   "polytropic shape and end-of-travel stops together; a cubic "
                                   "position_poly term cannot follow a bump stop's sharp onset"},
    evidence=_gas_evidence))


# -- thermal ---------------------------------------------------------------------------------

def _thermal_source(ctx):
    """(per-test temperature-like arrays at rows, label): the temperature, or a proxy."""
    temps = ctx.at_rows("temperature")
    if all(t is not None for t in temps):
        return temps, "temperature"
    # proxy: the energy dissipated since the start of the test (the oil heats by it)
    out = []
    for td in ctx.tests:
        p = np.abs(td.pred * td.test.channels["velocity"])
        e = np.concatenate(([0.0], np.cumsum(0.5 * (p[1:] + p[:-1]) * np.diff(td.test.time))))
        e = e[td.rows] / 1000.0
        out.append(e - np.mean(e))  # within-test drift only: the proxy says nothing between tests
    return out, "proxy: energy dissipated since the start of the test [kJ]"


def _thermal_columns(ctx, theta):
    temps, label = _thermal_source(ctx)
    ctx.notes["thermal_source"] = label
    c, h = _scale(temps, 100)
    zv, _ = _vel_norm(ctx)
    preds = ctx.pred_rows()
    fs = max(float(np.std(np.concatenate(preds))), 1e-9)
    out = []
    for t, v, f in zip(temps, zv, preds):
        tt = (t - c) / h
        fn = f / fs
        out.append(np.stack([tt, tt * fn, tt * v, tt * np.tanh(v / 0.05), tt * tt * fn, tt * np.abs(v) * v],
                            axis=1))
    return out


def _thermal_parameters(ctx, theta, fit):
    temps, label = _thermal_source(ctx)
    g = np.concatenate(fit["effect_rows"])
    t = np.concatenate(temps)
    f = np.concatenate(ctx.pred_rows())
    w = (t - np.mean(t)) * (f - np.mean(f))
    kappa = float(np.sum(g * w) / max(np.sum(w * w), 1e-30))
    unit = "percent_per_k" if label == "temperature" else "percent_per_kj"
    return {f"force_change_{unit}": 100.0 * kappa, "source": label,
            "temperature_range_c": [float(np.min(t)), float(np.max(t))] if label == "temperature" else None}


def _thermal_evidence(p, loc):
    key = [k for k in p if k.startswith("force_change")][0]
    unit = "%/K" if key.endswith("per_k") else "%/kJ dissipated"
    src = "" if p["source"] == "temperature" else f" ({p['source']})"
    return (f"the residual scales with the force and with temperature{src}: the force changes by "
            f"{p[key]:+.3g} {unit}; hot tests are over-predicted, cold ones under-predicted "
            "(see 'residual against temperature' and the per-test heat map)")


def _thermal_testable(ctx):
    temps = ctx.at_rows("temperature")
    if all(t is not None for t in temps):
        span = float(np.ptp(np.concatenate(temps)))
        if span < 0.5:
            return False, f"the temperature varies by only {span:.2f} K: viscosity changes cannot be seen"
        return True, ""
    return True, ("no temperature channel: tested with a proxy, the energy dissipated since the start "
                  "of each test (heating within a test only; between-test temperature differences cannot be tested)")


register_candidate(Candidate(
    id="thermal", title="oil viscosity changing with temperature",
    needs="temperature channel (else a proxy: energy dissipated within the test)",
    physics="Damper oil loses about half its viscosity per 20 K; the laminar (viscous) part of the "
            "pressure drop, so the damping force, falls as the oil warms, between tests and as a "
            "test heats it.",
    signature="residual proportional to force (or velocity) times the temperature's deviation; "
              "its sign flips between hot and cold tests; drifts within a long test",
    columns=_thermal_columns, testable=_thermal_testable, parameters=_thermal_parameters,
    add=lambda p, control: {"features": ["temperature"], "terms": [], "feature_params": {},
                            "how": "feature",
                            "why": "temperature as an MLP input: the viscosity law (Andrade, Walther) "
                                   "and which part of the force it scales are learned from the data"},
    evidence=_thermal_evidence))


# -- valve_lag ------------------------------------------------------------------------

def _control_rows(ctx):
    return ctx.at_rows(ctx.control_name)


def _valve_grid(ctx):
    return _log_grid(max(2 * _min_dt(ctx), 0.001), 1.0, 13)


def _valve_columns(ctx, theta):
    name = ctx.control_name
    model_ctrl = _control_name_in_model(ctx)
    lagged = {f: f for f in ctx.model.features if f in (name, name + "_lag")}
    zv, _ = _vel_norm(ctx)
    u_all = ctx.at_rows(name)
    c, h = _scale(u_all, 100)
    out = []
    for i, td in enumerate(ctx.tests):
        u = td.test.channels[name]
        ul = first_order_lag(u, td.test.dt, theta)
        d = ((ul - u) / h)[td.rows]
        v = zv[i]
        cols = [d, d * v, d * np.tanh(v / 0.05), d * np.abs(v)]
        if lagged:
            rep = {}
            for f in lagged:
                col = td.X[:, ctx.model.features.index(f)]
                rep[f] = first_order_lag(col, td.test.dt, theta) if f != model_ctrl else ul
            cols.insert(0, ctx.predict(i, rep) - td.pred[td.rows])
        out.append(np.stack(cols, axis=1))
    return out


def _valve_testable(ctx):
    name = ctx.control_name
    spans = [float(np.ptp(td.test.channels[name])) for td in ctx.tests if name in td.test.channels]
    allu = np.concatenate([td.test.channels[name] for td in ctx.tests])
    rng = float(np.ptp(allu)) or 1.0
    if not spans or max(spans) < 0.02 * rng:
        return False, (f"the {name} is constant within every test: a lag of the control's response "
                       "cannot be seen (it needs tests that step or sweep the control)")
    return True, ""


def _valve_evidence(p, loc):
    return (f"right after control steps the measured force approaches its new level over about "
            f"{1000 * p['tau_s']:.3g} ms (first-order lag) while the model jumps at once; the error's sign "
            "follows the direction of motion (see 'residual around control steps' and "
            "'residual against velocity' in the report)")


register_candidate(Candidate(
    id="valve_lag", title="control dynamics: valve or coil lag",
    needs="the control channel's history (control steps or sweeps within tests)",
    physics="A solenoid valve's spool or an MR coil's field (inductance, eddy currents) follows the "
            "command with a time constant of milliseconds to tens of milliseconds, so after a step the "
            "force keeps the old damping for a while.",
    signature="errors concentrated just after control steps, decaying with the lag's time constant; the "
              "sign of the error flips with the direction of motion (an interaction of the control's "
              "history and velocity, invisible to a plain correlation with the control)",
    columns=_valve_columns, grid=_valve_grid, testable=_valve_testable, theta_name="tau_s",
    parameters=lambda ctx, theta, fit: {"tau_s": float(theta)},
    add=lambda p, control: {"features": [f"{control}_lag"], "terms": [],
                            "feature_params": {"control_lag_tau_s": float(p.get("tau_s", 0.02))},
                            "how": "feature",
                            "why": f"the {control} after a first-order lag (estimated time constant) as an "
                                   "extra MLP input: the network maps the valve's actual state to force; "
                                   "the runtime carries one filter state"},
    evidence=_valve_evidence))


# -- friction -----------------------------------------------------------------------

def _friction_grid(ctx):
    return [2e-5, 5e-5, 1e-4, 2e-4, 5e-4, 1e-3, 2e-3]


def _friction_columns(ctx, theta):
    ctl = _control_name_in_model(ctx)
    out = []
    u_all = ctx.at_rows(ctx.control_name) if ctl else None
    if ctl:
        c, h = _scale(u_all, 100)
    for i, td in enumerate(ctx.tests):
        z = dahl_state(td.test.channels["velocity"], td.test.dt, theta)[td.rows]
        cols = [z]
        if ctl:
            cols.append(z * (u_all[i] - c) / h)
        out.append(np.stack(cols, axis=1))
    return out


def _friction_parameters(ctx, theta, fit):
    return {"presliding_length_mm": 1000.0 * float(theta), "friction_force_n": float(fit["beta"][0])}


register_candidate(Candidate(
    id="friction", title="seal friction and stick-slip near zero velocity",
    needs="velocity history (the travel since the last reversal)",
    physics="Rod seals, the piston band and the wiper stick at velocity reversals: the friction force "
            "does not switch with the sign of velocity but builds up over a pre-sliding travel and "
            "may break away with a peak (Dahl, LuGre). A friction that is a function of velocity alone "
            "(Coulomb, Stribeck) is already within reach of a velocity-input model and is not credited here.",
    signature="errors at velocity reversals that depend on the travel since the reversal; hysteresis "
              "loops in force-displacement near the ends of travel",
    columns=_friction_columns, grid=_friction_grid, theta_name="presliding_m",
    parameters=_friction_parameters,
    add=lambda p, control: {"features": ["friction_state"], "terms": [],
                            "feature_params": {"friction_presliding_m":
                                               float(p.get("presliding_length_mm", 0.2)) / 1000.0},
                            "how": "feature",
                            "why": "the Dahl friction state as an MLP input: the network scales it and "
                                   "combines it with velocity; the runtime carries one state"},
    evidence=lambda p, loc: (f"just after velocity reversals the force builds up over about "
                             f"{p['presliding_length_mm']:.3g} mm of travel ({p['friction_force_n']:.3g} N) "
                             "instead of switching with the sign of velocity (see 'near zero velocity')")))


# -- compressibility --------------------------------------------------------------------

def _comp_grid(ctx):
    return _log_grid(max(_min_dt(ctx), 0.0005), 0.1, 10)


def _comp_columns(ctx, theta):
    zv, vs = _vel_norm(ctx)
    ctl = _control_name_in_model(ctx)
    out = []
    for i, td in enumerate(ctx.tests):
        v = td.test.channels["velocity"]
        vl = first_order_lag(v, td.test.dt, theta)
        rep = {"velocity": vl}
        if "acceleration" in ctx.model.features:
            a = td.X[:, ctx.model.features.index("acceleration")]
            rep["acceleration"] = first_order_lag(a, td.test.dt, theta)
        d = ((vl - v) / vs)[td.rows]
        cols = [ctx.predict(i, rep) - td.pred[td.rows], d, d * np.tanh(zv[i] / 0.05)]
        if ctl:
            u = td.test.channels[ctl][td.rows]
            cols.append(d * u / max(float(np.max(np.abs(u))), 1e-12))
        out.append(np.stack(cols, axis=1))
    return out


def _comp_parameters(ctx, theta, fit):
    """tau_s: the physical time constant, the lag of the velocity at which a smooth function of
    (lagged velocity, acceleration, control) fits the measured force best (estimate.lag_with_spread,
    cached: the same for every fold); residual_lag_s: the extra lag the residual test found beyond
    the model's own acceleration input (small when the acceleration already carries most of it)."""
    from dampnet.diagnosis.estimate import lag_with_spread

    if "compressibility_tau" not in ctx.notes:
        ctx.notes["compressibility_tau"] = lag_with_spread([td.test for td in ctx.tests], "velocity")
    tau, spread = ctx.notes["compressibility_tau"]
    return {"tau_s": tau, "residual_lag_s": float(theta), "_uncertainty": {"tau_s": spread}}


register_candidate(Candidate(
    id="compressibility", title="force lagging velocity (oil compressibility, gas entrainment)",
    needs="velocity history",
    physics="The chamber pressure builds through the oil's effective bulk modulus (lowered by entrained "
            "gas and tube compliance), so the force lags the velocity by a time constant V/beta * dp/dQ; "
            "an acceleration input explains a small, linear lag, not a large or nonlinear one.",
    signature="force-velocity loops open into hysteresis that grows with frequency; residual "
              "proportional to the model's force evaluated on a lagged velocity minus its force now",
    columns=_comp_columns, grid=_comp_grid, theta_name="residual_lag_s",
    testable=lambda ctx: (("velocity" in ctx.model.features),
                          "" if "velocity" in ctx.model.features else "the model has no velocity input"),
    parameters=_comp_parameters,
    add=lambda p, control: {"features": ["velocity_lag"], "terms": [],
                            "feature_params": {"velocity_lag_tau_s": float(p.get("tau_s", 0.002))},
                            "how": "feature",
                            "why": "the velocity after a first-order lag as an extra MLP input: the network "
                                   "learns how much of the force follows the lagged flow"},
    evidence=lambda p, loc: (f"the force follows a velocity lagged by about {1000 * p['tau_s']:.3g} ms, "
                             "more than the acceleration input explains: the measured force-velocity "
                             "loops are wider than the predicted ones, most at high frequency")))


# -- what --add adds ------------------------------------------------------------------------

def additions(effect_id: str, params: dict[str, Any] | None = None, control: str = "voltage",
              dataset=None) -> dict[str, Any]:
    """What `dampnet train --add EFFECT` adds: {"features", "terms", "feature_params", "how", "why"}.

    `params` are the diagnosis's estimates (e.g. {"tau_s": 0.013} for valve_lag); without them
    and with a `dataset`, lag time constants are estimated from the data
    (`dampnet.diagnosis.estimate.estimate_parameters`); otherwise defaults are used.
    """
    if effect_id not in CANDIDATES:
        raise ValueError(f"unknown effect {effect_id!r}: expected one of {', '.join(sorted(CANDIDATES))}")
    c = CANDIDATES[effect_id]
    if c.add is None:
        raise ValueError(f"effect {effect_id!r} has no recipe for adding it to a model")
    if dataset is not None and dataset.tests:
        control = dataset.tests[0].control_name
        if not params:
            from dampnet.diagnosis.estimate import estimate_parameters

            params = estimate_parameters(effect_id, dataset)
    return c.add(params or {}, control)
