"""The diagnosis's candidate effects: how to test each effect of the catalogue (dampnet.effects).

The effect's identity (id, title, physics) and what a model needs to capture it (what
`dampnet train --add ID` adds) are the effect catalogue's, dampnet.effects. A candidate,
keyed by the catalogue's id, says which inputs it needs, what the effect
looks like in the residual, and how to test it: `columns(ctx, theta)` returns,
per test, regressors [rows, q] built from the physics (not from the residual),
for a value `theta` of its one nonlinear parameter (a time constant, a
pre-sliding length; None if it has none) chosen on a `grid`. The scorer
(`dampnet.diagnosis.score`) fits them to the residual on some tests, scores them
on the others, and compares the score with a null. `parameters(ctx, theta, fit)`
turns the fitted effect into numbers worth knowing (the ones the catalogue's recipe reads,
e.g. tau_s, set the added feature's parameter).

To add your own candidate, register its identity in the catalogue first:

    from dampnet.effects import EffectInfo, register_effect
    from dampnet.diagnosis.catalogue import Candidate, register_candidate
    register_effect(EffectInfo(id="my_effect", title=..., physics=..., rig="absent",
                               diagnosed_by="my_effect", adds=...))
    register_candidate(Candidate(id="my_effect", needs=..., signature=..., columns=my_columns, ...))

The built-in ids are fixed: gas_spring, thermal, valve_lag, friction, compressibility,
mr_hysteresis (the rig's bump_stop is diagnosed as gas_spring).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from dampnet.effects import CATALOGUE, EffectInfo
from dampnet.features import dahl_state, first_order_lag, lags_of


@dataclass
class Candidate:
    id: str                         # an id of the effect catalogue (dampnet.effects)
    needs: str                      # the inputs it needs, in words
    signature: str                  # what it looks like in the residual
    columns: Callable               # (ctx, theta) -> list of [rows, q] arrays, one per test
    grid: Callable = lambda ctx: [None]          # ctx -> values of the nonlinear parameter
    testable: Callable = lambda ctx: (True, "")  # ctx -> (ok, note)
    parameters: Callable | None = None           # (ctx, theta, fit) -> {name: value}
    evidence: Callable | None = None             # (params, loc) -> sentence
    theta_name: str | None = None                # name and unit of theta, e.g. "tau_s"
    extra: dict = field(default_factory=dict)

    @property
    def info(self) -> EffectInfo:
        """The effect's catalogue entry: id, title, physics, what a model needs to capture it."""
        return CATALOGUE[self.id]

    @property
    def title(self) -> str:
        return self.info.title

    @property
    def physics(self) -> str:
        return self.info.physics


CANDIDATES: dict[str, Candidate] = {}


def register_candidate(c: Candidate) -> Candidate:
    """Add (or replace) the candidate of an effect of the catalogue (dampnet.effects) that
    names it as `diagnosed_by`; ValueError otherwise."""
    info = CATALOGUE.get(c.id)
    if info is None or info.diagnosed_by != c.id:
        raise ValueError(f"diagnosis candidate {c.id!r}: register the effect in the catalogue first "
                         "(dampnet.effects.register_effect with diagnosed_by=its id); catalogue ids: "
                         f"{', '.join(sorted(CATALOGUE))}")
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
    id="gas_spring",
    needs="displacement",
    signature="residual a smooth, mostly increasing function of displacement, the same in rebound and "
              "compression; steepening near the ends of travel; horizontal bands in the "
              "displacement-velocity plane",
    columns=_gas_columns, testable=_gas_testable, parameters=_gas_parameters,
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
    id="thermal",
    needs="temperature channel (else a proxy: energy dissipated within the test)",
    signature="residual proportional to force (or velocity) times the temperature's deviation; "
              "its sign flips between hot and cold tests; drifts within a long test",
    columns=_thermal_columns, testable=_thermal_testable, parameters=_thermal_parameters,
    evidence=_thermal_evidence))


# -- valve_lag ------------------------------------------------------------------------

def _control_rows(ctx):
    return ctx.at_rows(ctx.control_name)


def _valve_grid(ctx):
    return _log_grid(max(2 * _min_dt(ctx), 0.001), 1.0, 13)


def _valve_columns(ctx, theta):
    name = ctx.control_name
    model_ctrl = _control_name_in_model(ctx)
    lagged = {f: f for f in ctx.model.features if f == name or f in lags_of(name)}
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
    id="valve_lag",
    needs="the control channel's history (control steps or sweeps within tests)",
    signature="errors concentrated just after control steps, decaying with the lag's time constant; the "
              "sign of the error flips with the direction of motion (an interaction of the control's "
              "history and velocity, invisible to a plain correlation with the control)",
    columns=_valve_columns, grid=_valve_grid, testable=_valve_testable, theta_name="tau_s",
    parameters=lambda ctx, theta, fit: {"tau_s": float(theta)},
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
    id="friction",
    needs="velocity history (the travel since the last reversal)",
    signature="errors at velocity reversals that depend on the travel since the reversal; hysteresis "
              "loops in force-displacement near the ends of travel",
    columns=_friction_columns, grid=_friction_grid, theta_name="presliding_m",
    parameters=_friction_parameters,
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
    id="compressibility",
    needs="velocity history",
    signature="force-velocity loops open into hysteresis that grows with frequency; residual "
              "proportional to the model's force evaluated on a lagged velocity minus its force now",
    columns=_comp_columns, grid=_comp_grid, theta_name="residual_lag_s",
    testable=lambda ctx: (("velocity" in ctx.model.features),
                          "" if "velocity" in ctx.model.features else "the model has no velocity input"),
    parameters=_comp_parameters,
    evidence=lambda p, loc: (f"the force follows a velocity lagged by about {1000 * p['tau_s']:.3g} ms, "
                             "more than the acceleration input explains: the measured force-velocity "
                             "loops are wider than the predicted ones, most at high frequency")))


# -- mr_hysteresis: a position-and-direction force that grows with the control ------------------

#: the candidate is testable only when a loop the same at every control keeps at most this share of
#: what the control-independent columns would explain (mean(u)^2 / mean(u^2), u = control / max|control|):
#: with a control nearly constant across the data a control-scaled loop and a rubber mount's
#: control-independent one cannot be told apart
MR_CONTROL_SPREAD_MAX = 0.75
MR_DEGREES = 3  # Legendre P1..P3 of the position (P0 times the direction is friction's and the baseline's)


def _mr_control(ctx):
    """(per-test control at rows, normalised by the data's max |control|, the max, the control's name)."""
    u = ctx.at_rows(ctx.control_name)
    if any(x is None for x in u):
        return None, 0.0, ctx.control_name
    us = float(np.max(np.abs(np.concatenate(u))))
    return [x / us for x in u] if us > 0 else None, us, ctx.control_name


def mr_columns_of(x, zv, u, c, h):
    """Legendre P1..P3 of the normalised position times the direction of motion tanh(v / 0.05 v_max)
    times the normalised control: a loop between extension and compression strokes that grows with it."""
    return gas_columns_of(x, c, h)[:, :MR_DEGREES] * (np.tanh(zv / 0.05) * u)[:, None]


def _mr_columns(ctx, theta):
    c, h = _x_frame(ctx)
    zv, _ = _vel_norm(ctx)
    u, _, _ = _mr_control(ctx)
    return [mr_columns_of(x, z, ui, c, h) for x, z, ui in zip(ctx.at_rows("displacement"), zv, u)]


def _mr_testable(ctx):
    if any(x is None for x in ctx.at_rows("displacement")):
        return False, "no displacement channel"
    u, us, name = _mr_control(ctx)
    if u is None:
        return False, f"no {name} channel, or it is zero throughout"
    a = np.concatenate(u)
    kept = float(np.mean(a) ** 2 / max(np.mean(a * a), 1e-30))
    if kept > MR_CONTROL_SPREAD_MAX:
        return False, (f"the {name} varies too little across the data (a loop the same at every {name} would keep "
                       f"{100 * kept:.0f} % of its score): a control-scaled hysteresis cannot be told from a "
                       "control-independent one (a rubber mount's); it needs tests at low and high control")
    return True, ""


def _mr_parameters(ctx, theta, fit):
    c, h = _x_frame(ctx)
    _, us, name = _mr_control(ctx)
    z = np.linspace(-1.0, 1.0, 201)
    half = gas_columns_of(c + h * z, c, h)[:, :MR_DEGREES] @ np.asarray(fit["beta"])
    k = int(np.argmax(np.abs(half)))
    return {"loop_half_height_at_max_control_n": float(abs(half[k])),
            "loop_half_height_mid_stroke_n": float(abs(half[100])),
            "peak_at_position_mm": 1000.0 * float(c + h * z[k]),
            "max_control": us, "control": name}


def _mr_evidence(p, loc):
    return (f"the residual depends on position and on the direction of motion, and grows with the {p['control']}: "
            f"between extension and compression strokes the force differs by up to "
            f"2 x {p['loop_half_height_at_max_control_n']:.3g} N at the highest {p['control']} "
            f"({p['max_control']:.3g}; 2 x {p['loop_half_height_mid_stroke_n']:.3g} N at mid-stroke), in proportion "
            f"to the {p['control']} (see the residual's force-displacement loop: wider at high control)")


register_candidate(Candidate(
    id="mr_hysteresis",
    needs="displacement and a control channel that varies between tests",
    signature="a loop in the residual's force-displacement plane (a force that depends on position and on "
              "the direction of motion) whose height grows with the control; a loop the same at every "
              "control (a rubber mount) is not it",
    columns=_mr_columns, testable=_mr_testable, parameters=_mr_parameters, evidence=_mr_evidence))
