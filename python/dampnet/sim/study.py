"""Quarter-car runs and the thesis's chapter 5 study (Tables 6 and 7, skyhook), as dicts with stable keys.

A *damper spec* (`DamperSpec`) names a damper model and how to build it for a
loop: 'truth' (the rig's physical damper, `dampnet.rig.truth`),
'neural' / 'hybrid' (an `MlpModel`), 'lookup' (a `LookupTable`), 'linear'.

Backends. Runs go through the runtime's C++ loop (`dampnet._core.Loop`,
RK4 with one damper evaluation per step, `damper_eval="per_step"`) when it is
built; the rig's truth damper exists only in Python and enters that loop as a
callback damper (`_core.Damper.callback`), stepped once per loop step as its
`step(dt, ...)` requires. Without the runtime, `dampnet.sim.reference_loop` runs the
same equations with the same scheme (checked against the runtime in
tests/python/test_simulate.py). Every model in a study runs with one damper
evaluation per step at the same dt, so they are compared like for like; the
backend of each run is recorded under `settings.backends`.

Damping levels: "low" and "high" damping are the controls giving the least
and the most damping. They are found, not assumed: the damper's force at
0.5 m/s (rebound) and -0.5 m/s is evaluated at the ends of the control range
and the end with the larger summed |force| is "high". For the rig's damper
that is 0 V (valve closed) = high, 5 V = low.

Study (`run_study`): for each model (and the truth damper, when known)
  impulse      - raised-cosine pulse (50 mm, 50 ms), passive at low and high damping
  sine_sweep   - bounce sine sweep 0.5-20 Hz (5 mm, 0.1 octave/s), low and high, with transmissibility
  rough_road   - thesis rough road (RMS 16 mm, 184 m) at 10 and 20 m/s, low and high
  skyhook      - on the rough road at 10 and 20 m/s: on-off skyhook (u_soft = low, u_hard = high,
                 cases "<v>_skyhook") and continuous skyhook ("<v>_skyhook_continuous", settings
                 below) against passive at the same damper's low and high settings
and `errors`: per model and case, (model - truth) / truth of every metric.

Continuous skyhook (`continuous_skyhook`). The runtime's law (DN_CTRL_SKYHOOK_CONTINUOUS)
asks for the damping c_des = c_sky v_s / v when v_s v > 0 (else the soft setting) and
maps it linearly onto the control, c_min -> u_soft, c_max -> u_hard. Its settings come
from the vehicle and the damper, not from a study's result:
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

Command filter. Both skyhook laws pass their control through a first-order low-pass of
SKYHOOK_COMMAND_TAU_S = 5 ms (the runtime's u_tau_s: a 32 Hz corner, 20 degrees of lag at the
11.7 Hz wheel hop), as a real semi-active controller smooths its command. Unfiltered, the laws
jump between controls (continuous skyhook from hard to soft each time v changes sign while
v_s does not), each jump is a step of damper force that jolts the body, and a model whose
force answers the acceleration spike of that step (the thesis's inputs include the
acceleration) turns it into an error: the road model was +2.7 / +3.8 % off the truth under
unfiltered continuous skyhook, -0.2 / +0.6 % with the filter (10 / 20 m/s).

One controller is calibrated on the truth damper when known (else on the first model) and
used for every model, so the models are compared under the same control; it is recorded
under `settings.skyhook`.

What skyhook can do here (rig damper, thesis road, measured): 72-78 % of the sprung
acceleration variance at the soft setting lies above 1.5 Hz (42-48 % at 8-20 Hz, the wheel
hop), where any damping above the soft setting's costs comfort; the soft setting
(c_eq 1.5-1.8 kN s/m) is already above the best passive linear damping for acceleration RMS
(about 1 kN s/m: 0.453 vs 0.476 m/s^2 at 1.5 kN s/m, 10 m/s). A semi-active law can only add
damping, so against passive *low* the gain is small: filtered continuous skyhook 1.2 / 1.6 %
for the truth at 10 / 20 m/s (road seed 0; 0.8 / 0.9 % unfiltered), 1.7-2.5 % for the road
model (3 training seeds); an ideal force-tracking skyhook that inverts the truth damper's map
gets 1.6-2.2 %; acceleration-driven damping (ADD) and mixed SH-ADD on-off are worse than
passive low. Against passive *high* (0 V) continuous skyhook is 41-49 % lower; on-off skyhook
between the damper's own ends is 34 % / 26 % above passive low at 10 / 20 m/s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dampnet.sim.ride import ride_metrics, transmissibility
from dampnet.sim.reference_loop import (LinearDamper, NeuralLoopDamper, TableLoopDamper, TruthLoopDamper,
                                        run as py_run)
from dampnet.sim.vehicle import Controller, LoopError, Vehicle
from dampnet.sim.roads import Road, impulse, sine_sweep, thesis_rough_road

SCHEMA = "dampnet.sim.study/1"
SPEEDS = (10.0, 20.0)
# Metrics compared with the truth (relative error) in `errors`.
ERROR_METRICS = ("acc_rms_m_s2", "acc_wk_rms_m_s2", "disp_peak_to_rms", "travel_rms_m", "tyre_load_rms_n")


@dataclass
class DamperSpec:
    """A damper model for the loop: kind in truth/neural/hybrid/lookup/linear; obj the model."""

    name: str
    kind: str
    obj: Any = None
    u_range: tuple = (0.0, 5.0)
    meta: dict = field(default_factory=dict)

    def python_damper(self):
        if self.kind == "truth":
            return TruthLoopDamper(effects=self.obj or ())
        if self.kind in ("neural", "hybrid"):
            return NeuralLoopDamper(self.obj)
        if self.kind == "lookup":
            return TableLoopDamper(self.obj)
        if self.kind == "linear":
            return LinearDamper(self.obj)
        raise LoopError(f"no Python form of a {self.kind!r} damper")


def neural_spec(model, name: str = "neural") -> DamperSpec:
    u_range = (0.0, 5.0)
    for key in ("voltage", "current"):
        if key in model.features:
            i = model.features.index(key)
            u_range = (float(model.sat_lo[i]), float(model.sat_hi[i]))
    kind = "hybrid" if model.terms else "neural"
    return DamperSpec(name, kind, model, u_range, meta=dict(model_id=model.model_id()))


def lookup_spec(table, name: str = "lookup") -> DamperSpec:
    return DamperSpec(name, "lookup", table, (float(table.voltages[0]), float(table.voltages[-1])))


def truth_spec(effects=(), name: str = "truth") -> DamperSpec:
    return DamperSpec(name, "truth", list(effects), (0.0, 5.0), meta=dict(effects=list(effects)))


def steady_force(spec: DamperSpec, v: float, u: float, dt: float = 1e-3) -> float:
    """The damper's force [N] after 50 steps of dt at constant velocity v [m/s] and control u
    (past the truth damper's 2 ms lag), at x = 0, a = 0."""
    d = spec.python_damper()
    d.reset()
    f = 0.0
    for _ in range(50):
        f = d.force(0.0, float(v), 0.0, float(u), dt)
    return float(f)


def damping_levels(spec: DamperSpec, dt: float = 1e-3) -> dict:
    """{'low': u, 'high': u}: the ends of the control range giving the least / most damping."""
    lo, hi = spec.u_range
    score = {u: sum(abs(steady_force(spec, v, u, dt)) for v in (0.5, -0.5)) for u in (lo, hi)}
    high = lo if score[lo] >= score[hi] else hi
    low = hi if high == lo else lo
    return dict(low=float(low), high=float(high))


SKYHOOK_ZETA = 1.0 / math.sqrt(2.0)
SKYHOOK_V_RMS_M_S = 0.2
# Command filter of the study's semi-active laws [s] (the runtime's u_tau_s; see the module
# docstring): a 32 Hz corner, 20 degrees of lag at the 11.7 Hz wheel hop, five 1 ms steps.
SKYHOOK_COMMAND_TAU_S = 0.005


def equivalent_damping(spec: DamperSpec, u: float, v_rms: float = SKYHOOK_V_RMS_M_S, dt: float = 1e-3,
                       nodes: int = 24) -> float:
    """Equivalent linear damping [N s/m] of a damper at control u: E[F v] / E[v^2], v ~ N(0, v_rms^2).

    Statistical linearisation (Gauss-Hermite quadrature) of the steady force, each velocity
    held for 50 steps (past the truth damper's 2 ms lag) at x = 0, a = 0.
    """
    x, w = np.polynomial.hermite_e.hermegauss(nodes)
    w = w / w.sum()
    v = v_rms * x
    f = np.array([steady_force(spec, vi, u, dt) for vi in v])
    f = f - np.sum(w * f)
    return float(np.sum(w * f * v) / np.sum(w * v * v))


def continuous_skyhook(spec: DamperSpec, levels: dict | None = None, vehicle: Vehicle | None = None,
                       zeta_sky: float = SKYHOOK_ZETA, v_rms: float = SKYHOOK_V_RMS_M_S,
                       u_tau_s: float = SKYHOOK_COMMAND_TAU_S) -> Controller:
    """The continuous skyhook controller calibrated on a damper (see the module docstring).

    c_sky = zeta_sky 2 sqrt(k_s m_s); c_min / c_max = equivalent_damping at the low / high
    damping levels; u_tau_s the command filter's time constant [s] (0: none). A damper whose
    damping does not rise from low to high (a linear damper) keeps the Controller's default
    c_min / c_max: the control does nothing to it anyway.
    """
    veh = vehicle or Vehicle()
    lv = levels or damping_levels(spec, veh.dt)
    c_min = equivalent_damping(spec, lv["low"], v_rms, veh.dt)
    c_max = equivalent_damping(spec, lv["high"], v_rms, veh.dt)
    if not (math.isfinite(c_min) and math.isfinite(c_max) and c_max > c_min):
        c_min, c_max = Controller.c_min, Controller.c_max
    return semi_active("skyhook_continuous", lv, u_tau_s, c_sky=zeta_sky * 2.0 * math.sqrt(veh.k_s * veh.m_s),
                       c_min=c_min, c_max=c_max)


def semi_active(kind: str, levels: dict, u_tau_s: float = SKYHOOK_COMMAND_TAU_S, **law) -> Controller:
    """A control law between a damper's own low and high damping settings (`damping_levels`),
    limited to them, with the command filter; `law`: its other settings (c_sky, c_min, ...)."""
    return Controller(kind=kind, u_soft=levels["low"], u_hard=levels["high"], u_min=min(levels.values()),
                      u_max=max(levels.values()), u_tau_s=u_tau_s, **law)


def core_loop_available() -> bool:
    """True when the runtime's C++ loop (dampnet._core.Loop) is built."""
    try:
        from dampnet import _core
    except ImportError:
        return False
    return all(hasattr(_core, n) for n in ("Loop", "LoopModel", "Damper"))


_CORE_LAWS = {"passive": "passive", "skyhook": "skyhook_onoff", "skyhook_continuous": "skyhook_continuous",
              "groundhook": "groundhook_onoff", "groundhook_continuous": "groundhook_continuous"}


def core_damper(spec: DamperSpec):
    """The runtime's damper (dampnet._core.Damper) for a spec; for the truth, (callback damper, its TruthLoopDamper)."""
    from dampnet import _core

    if spec.kind == "linear":
        return _core.Damper.linear(float(spec.obj))
    if spec.kind == "lookup":
        t = spec.obj
        return _core.Damper.table(t.velocities, t.voltages, np.ascontiguousarray(t.forces))
    if spec.kind in ("neural", "hybrid"):
        m = spec.obj
        d = _core.Damper.neural(m.core(), list(m.features), dict(m.feature_params))
        for term in m.terms:
            d.add_term(term["kind"], np.asarray(term["params"], dtype=np.float64))
        return d
    if spec.kind == "truth":
        truth = spec.python_damper()

        def fn(inp):   # called once per step (damper_eval per_step)
            return truth.force(inp.x, inp.v, inp.a, inp.u, inp.dt)

        return _core.Damper.callback(fn), truth
    raise LoopError(f"no runtime form of a {spec.kind!r} damper")


def _core_run(spec: DamperSpec, z_r, v_r, vehicle: Vehicle, controller: Controller) -> dict:
    """Run in the runtime's C++ loop (RK4, one damper evaluation per step); arrays as pyloop.run."""
    from dampnet import _core

    damper = core_damper(spec)
    truth = None
    if spec.kind == "truth":
        damper, truth = damper
    u0 = controller.law(0.0, 0.0)
    if vehicle.f_static is None:
        f_static = float(spec.python_damper().force_at_rest(u0, vehicle.dt)) if spec.kind == "truth" else \
            float(damper.forces(np.array([vehicle.x_static]), np.zeros(1), np.zeros(1), np.array([u0]),
                                np.array([u0]), np.array([20.0]), v_lag=np.zeros(1),
                                z_fric=np.zeros(1))[0][0])  # at rest, as the loop's reset
    else:
        f_static = float(vehicle.f_static)
    veh = dict(m_s=vehicle.m_s, m_us=vehicle.m_us, k_s=vehicle.k_s, k_t=vehicle.k_t, c_t=vehicle.c_t,
               dt=vehicle.dt, x_static=vehicle.x_static, f_static=f_static, integrator="rk4",
               damper_eval="per_step", accel_feature=vehicle.accel_feature)
    ctrl = {k: v for k, v in controller.to_dict().items() if k != "kind"}
    ctrl["kind"] = _CORE_LAWS[controller.kind]
    loop = _core.Loop(_core.LoopModel(damper, veh, ctrl))
    if truth is not None:
        truth.reset()
    r = loop.simulate(np.ascontiguousarray(z_r, dtype=np.float64), np.ascontiguousarray(v_r, dtype=np.float64))
    st = r["state"]
    names = list(_core.STATE_NAMES)
    n = st.shape[0] - 1          # the last report is at the road's end (no step): drop, as pyloop
    out = dict(t=st[:n, names.index("t")], z_s=st[:n, names.index("z_s")], v_s=st[:n, names.index("v_s")],
               z_us=st[:n, names.index("z_us")], v_us=st[:n, names.index("v_us")],
               z_r=st[:n, names.index("z_r")], acc_s=r["acc_s"][:n], acc_us=r["acc_us"][:n],
               force=r["force"][:n], u=r["control"][:n], x=r["x"][:n], v=r["v"][:n], a=r["a"][:n])
    out = {k: np.array(v) for k, v in out.items()}
    out["f_static"] = f_static
    return out


def simulate(spec: DamperSpec, road: Road, speed: float | None = None, controller: Controller | None = None,
             vehicle: Vehicle | None = None, backend: str = "auto", transfer: bool | None = None) -> dict:
    """One run: {'arrays': {...}, 'metrics': {...}, 'transmissibility': {...} (sweeps), 'backend': str}."""
    veh = vehicle or Vehicle()
    ctrl = controller or Controller()
    veh.validate()
    ctrl.validate()
    s = road.sample(veh.dt, speed)
    if backend not in ("auto", "core", "python"):
        raise ValueError(f"backend must be auto, core or python, got {backend!r}")
    use_core = backend == "core" or (backend == "auto" and core_loop_available())
    if use_core:
        arr = _core_run(spec, s.z, s.zdot, veh, ctrl)
        used = "core"
    else:
        arr = py_run(spec.python_damper(), s.z, s.zdot, veh, ctrl)
        used = "python"
    f_static = arr.pop("f_static", None)
    metrics = ride_metrics(arr["t"], arr["z_s"], arr["z_us"], arr["z_r"], arr["acc_s"], veh.k_t,
                           veh.m_s, veh.m_us)
    out = dict(arrays=arr, metrics=metrics, backend=used, f_static_n=f_static, road=road.meta,
               speed_m_s=speed, controller=ctrl.to_dict(), vehicle=veh.to_dict(), damper=spec.name)
    if transfer or (transfer is None and road.meta.get("input") == "sine_sweep"):
        f1 = road.meta.get("f1_hz", 20.0)
        tr = transmissibility(arr["z_r"], arr["z_s"], 1.0 / veh.dt, fmin=road.meta.get("f0_hz", 0.5),
                              fmax=f1)
        out["transmissibility"] = tr
        metrics["transmissibility_peak"] = float(np.max(tr["magnitude"]))
        metrics["transmissibility_peak_hz"] = float(tr["f_hz"][np.argmax(tr["magnitude"])])
    return out


def _rel(a: float, b: float) -> float:
    return float((a - b) / b) if b != 0 and math.isfinite(a) and math.isfinite(b) else float("nan")


def run_study(specs: list[DamperSpec], truth: DamperSpec | None = None, dt: float = 1e-3,
              speeds=SPEEDS, seed: int = 0, sweep: Road | None = None, pulse: Road | None = None,
              rough: Road | None = None, keep_runs: bool = False, progress=None) -> dict:
    """The chapter 5 study; see the module docstring. Returns a JSON-ready dict (arrays only if keep_runs)."""
    all_specs = list(specs) + ([truth] if truth is not None else [])
    names = [s.name for s in all_specs]
    if len(set(names)) != len(names):
        raise ValueError(f"damper names must be unique, got {names}")
    veh = Vehicle(dt=dt)
    roads = dict(impulse=pulse or impulse(), sine_sweep=sweep or sine_sweep(),
                 rough_road=rough or thesis_rough_road(seed=seed))
    levels = {s.name: damping_levels(s, dt) for s in all_specs}
    res: dict[str, Any] = dict(schema=SCHEMA, models=names, truth=truth.name if truth else None,
                               settings=dict(dt_s=dt, vehicle=veh.to_dict(), speeds_m_s=list(speeds),
                                             damping_levels=levels,
                                             roads={k: r.meta for k, r in roads.items()},
                                             backends={}),
                               impulse={}, sine_sweep={}, rough_road={}, skyhook={}, errors={})
    runs: dict[str, Any] = {}
    ref = truth or all_specs[0]
    sky_c = continuous_skyhook(ref, levels[ref.name], veh)
    res["settings"]["skyhook"] = dict(
        onoff={s.name: dict(u_soft=levels[s.name]["low"], u_hard=levels[s.name]["high"],
                            u_tau_s=sky_c.u_tau_s) for s in all_specs},
        continuous=dict(sky_c.to_dict(), calibrated_on=ref.name, zeta_sky=SKYHOOK_ZETA,
                        v_rms_m_s=SKYHOOK_V_RMS_M_S))

    def go(section, case, spec, road, speed, ctrl):
        if progress:
            progress(f"{section} {case} {spec.name}")
        r = simulate(spec, road, speed, ctrl, veh)
        res[section].setdefault(case, {})[spec.name] = r["metrics"]
        res["settings"]["backends"][spec.name] = r["backend"]
        if keep_runs:
            runs.setdefault(section, {}).setdefault(case, {})[spec.name] = r
        return r

    for spec in all_specs:
        lv = levels[spec.name]
        for level in ("low", "high"):
            passive = Controller(kind="passive", u_passive=lv[level])
            go("impulse", level, spec, roads["impulse"], None, passive)
            go("sine_sweep", level, spec, roads["sine_sweep"], None, passive)
            for v in speeds:
                go("rough_road", f"{v:g}_{level}", spec, roads["rough_road"], v, passive)
        for v in speeds:
            sky = semi_active("skyhook", lv, sky_c.u_tau_s)
            go("skyhook", f"{v:g}_skyhook", spec, roads["rough_road"], v, sky)
            cont = semi_active("skyhook_continuous", lv, sky_c.u_tau_s, c_sky=sky_c.c_sky, c_min=sky_c.c_min,
                               c_max=sky_c.c_max)
            go("skyhook", f"{v:g}_skyhook_continuous", spec, roads["rough_road"], v, cont)
            res["skyhook"].setdefault(f"{v:g}_passive_low", {})[spec.name] = \
                res["rough_road"][f"{v:g}_low"][spec.name]
            res["skyhook"].setdefault(f"{v:g}_passive_high", {})[spec.name] = \
                res["rough_road"][f"{v:g}_high"][spec.name]
    if truth is not None:
        for section in ("impulse", "sine_sweep", "rough_road", "skyhook"):
            for case, by_model in res[section].items():
                ref = by_model[truth.name]
                for spec in specs:
                    res["errors"].setdefault(section, {}).setdefault(case, {})[spec.name] = {
                        k: _rel(by_model[spec.name][k], ref[k]) for k in ERROR_METRICS}
    if keep_runs:
        res["_runs"] = runs
    return res


def text_tables(res: dict) -> str:
    """Short text tables: Table 6 (sweep/impulse), Table 7 (rough road), skyhook, errors vs truth."""
    models = res["models"]
    lines = []

    def table(title, section, cases, metric, fmt="{:10.4f}"):
        lines.append(title)
        lines.append("  " + f"{'case':<22}" + "".join(f"{m:>12}" for m in models))
        for c in cases:
            row = res[section].get(c, {})
            lines.append("  " + f"{c:<22}" + "".join(
                f"{fmt.format(row[m][metric]) if m in row else '':>12}" for m in models))

    table("Table 6 - sine sweep: sprung acceleration RMS [m/s^2]", "sine_sweep", ("low", "high"), "acc_rms_m_s2")
    table("Table 6 - sine sweep: sprung displacement peak-to-RMS", "sine_sweep", ("low", "high"), "disp_peak_to_rms")
    table("Impulse: sprung acceleration RMS [m/s^2]", "impulse", ("low", "high"), "acc_rms_m_s2")
    table("Impulse: sprung displacement peak-to-RMS", "impulse", ("low", "high"), "disp_peak_to_rms")
    table("Table 7 - rough road: sprung acceleration RMS [m/s^2]", "rough_road", list(res["rough_road"]),
          "acc_rms_m_s2")
    table("Skyhook vs passive, rough road: sprung acceleration RMS [m/s^2]", "skyhook", list(res["skyhook"]),
          "acc_rms_m_s2")
    table("Skyhook vs passive, rough road: sprung displacement RMS [m]", "skyhook", list(res["skyhook"]),
          "disp_rms_m", fmt="{:10.5f}")
    sky = res["skyhook"]
    gains = [(f"{c[:-len(law)]}{law} vs {p}", c, c[:-len(law)] + p) for c in sky
             for law in ("skyhook", "skyhook_continuous") if c.endswith("_" + law)
             for p in ("passive_low", "passive_high") if c[:-len(law)] + p in sky]
    if gains:
        c = res["settings"]["skyhook"]["continuous"]
        lines.append(f"Skyhook against passive: change of sprung acceleration RMS, % (continuous: c_sky "
                     f"{c['c_sky']:.0f}, c_min {c['c_min']:.0f}, c_max {c['c_max']:.0f} N s/m; both laws: "
                     f"command filter {1e3 * c['u_tau_s']:g} ms)")
        lines.append("  " + f"{'case':<40}" + "".join(f"{m:>12}" for m in models))
        for label, c, p in gains:
            lines.append("  " + f"{label:<40}" + "".join(
                f"{100 * (sky[c][m]['acc_rms_m_s2'] / sky[p][m]['acc_rms_m_s2'] - 1):>11.2f}%"
                if m in sky[c] and m in sky[p] else f"{'':>12}" for m in models))
    if res.get("errors"):
        lines.append(f"Error of sprung acceleration RMS against the truth ({res['truth']}), %")
        others = [m for m in models if m != res["truth"]]
        lines.append("  " + f"{'case':<34}" + "".join(f"{m:>12}" for m in others))
        for section, cases in res["errors"].items():
            for c, by in cases.items():
                lines.append("  " + f"{section + ' ' + c:<34}" + "".join(
                    f"{100 * by[m]['acc_rms_m_s2']:>11.2f}%" for m in others))
    return "\n".join(lines)


def plot_run(run: dict, path, title: str = "") -> None:
    """Time histories of one run (road, sprung displacement, sprung acceleration, travel) as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    a = run["arrays"]
    fig, ax = plt.subplots(4, 1, figsize=(9, 8), sharex=True)
    ax[0].plot(a["t"], a["z_r"] * 1e3, lw=0.7)
    ax[0].set_ylabel("road [mm]")
    ax[1].plot(a["t"], a["z_s"] * 1e3, lw=0.7)
    ax[1].set_ylabel("sprung disp. [mm]")
    ax[2].plot(a["t"], a["acc_s"], lw=0.7)
    ax[2].set_ylabel("sprung acc. [m/s²]")
    ax[3].plot(a["t"], (a["z_s"] - a["z_us"]) * 1e3, lw=0.7)
    ax[3].set_ylabel("travel [mm]")
    ax[3].set_xlabel("time [s]")
    fig.suptitle(title or run.get("damper", ""))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_overlay(runs: dict, path, title: str, key: str = "acc_s", ylabel: str = "sprung acc. [m/s²]") -> None:
    """One channel of several runs (name -> run) on one axis, as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 3.5))
    for name, r in runs.items():
        ax.plot(r["arrays"]["t"], r["arrays"][key], lw=0.7, label=name)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_transmissibility(runs: dict, path, title: str = "Transmissibility z_s / z_r") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    for name, r in runs.items():
        tr = r["transmissibility"]
        ax.loglog(tr["f_hz"], tr["magnitude"], lw=0.8, label=name)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("|z_s / z_r|")
    ax.set_title(title)
    ax.grid(True, which="both", lw=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_plots(res: dict, out_dir) -> list:
    """Plots of a study run with keep_runs=True: overlays per case and transmissibility."""
    from pathlib import Path

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    runs = res.get("_runs", {})
    for section, cases in runs.items():
        for case, by_model in cases.items():
            p = out / f"{section}_{case}.png"
            plot_overlay(by_model, p, f"{section} {case}")
            written.append(p)
            if section == "sine_sweep":
                p = out / f"transmissibility_{case}.png"
                plot_transmissibility(by_model, p, f"Transmissibility, {case} damping")
                written.append(p)
    return written


def jsonable(res: dict) -> dict:
    """The study dict without arrays (for JSON)."""
    return {k: v for k, v in res.items() if not k.startswith("_")}
