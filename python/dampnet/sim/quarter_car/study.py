"""The thesis's chapter 5 study (Tables 6 and 7, skyhook), as a dict with stable keys.

For each damper spec (`dampnet.sim.dampers`; and the truth damper, when known), every run
through the runtime's loop (`dampnet.sim.quarter_car.runs.simulate`, RK4 with one damper evaluation per
step, the same dt for all, so the models are compared like for like):
  impulse      - raised-cosine pulse (50 mm, 50 ms), passive at low and high damping
  sine_sweep   - bounce sine sweep 0.5-20 Hz (5 mm, 0.1 octave/s), low and high, with transmissibility
  rough_road   - thesis rough road (RMS 16 mm, 184 m) at 10 and 20 m/s, low and high
  skyhook      - on the rough road at 10 and 20 m/s: each law of SKYHOOK_LAWS between the damper's
                 own low and high settings (cases "<v>_<law>": "10_skyhook_onoff",
                 "10_skyhook_continuous", the runtime's law names) against passive at the same
                 damper's low and high settings ("<v>_passive_low", "<v>_passive_high")
and `errors`: per model and case, (model - truth) / truth of every metric; for each neural or
hybrid model, `coverage` (section -> case -> model: dampnet.envelope.coverage's result, the run against
the model's training envelope) and `extrapolated` (model -> {any, runs, extrapolated: the
"section case" runs whose verdict is extrapolated}). The damping
levels and the controllers' calibration: `dampnet.sim.calibration`. Tables and plots of a
result: `dampnet.sim.quarter_car.report`, `dampnet.sim.plots`.

Every controller is built and calibrated by the control-law registry
(dampnet.recipes.control_laws.make, passed in as `laws`: this layer does not import it): passive
low / high are its passive_low / passive_high, the semi-active laws its laws of the same names.
Each law's gains (c_sky, c_gnd, c_min, c_max) are the registry's calibration on the truth damper
when known (else on the first model), used for every model between that model's own low and high
settings, so the models are compared under the same control; they are recorded under
`settings.skyhook`, and every case's law by its registered name under `settings.laws`.

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
from typing import Any, Callable

import numpy as np

from dampnet.sim.calibration import SKYHOOK_V_RMS_M_S, SKYHOOK_ZETA, damping_levels
from dampnet.sim.dampers import DamperSpec
from dampnet.sim.roads import Road, impulse, sine_sweep, thesis_rough_road
from dampnet.sim.quarter_car.runs import simulate
from dampnet.sim.vehicle import Controller, Vehicle

# /2: the on-off skyhook case is "<v>_skyhook_onoff" (was "<v>_skyhook"), settings.backends is gone
SCHEMA = "dampnet.sim.quarter_car.study/2"
SPEEDS = (10.0, 20.0)
#: the semi-active laws of the skyhook section, by their names in the control-law registry
SKYHOOK_LAWS = ("skyhook_onoff", "skyhook_continuous")
#: the passive laws of the impulse, sine-sweep and rough-road sections (case level -> law)
PASSIVE_LAWS = {"low": "passive_low", "high": "passive_high"}
#: a law's gains, calibrated once on the reference damper and used for every model
GAINS = ("c_sky", "c_gnd", "c_min", "c_max")
# Metrics compared with the truth (relative error) in `errors`.
ERROR_METRICS = ("acc_rms_m_s2", "acc_wk_rms_m_s2", "disp_peak_to_rms", "travel_rms_m", "tyre_load_rms_n")


def _rel(a: float, b: float) -> float:
    return float((a - b) / b) if b != 0 and math.isfinite(a) and math.isfinite(b) else float("nan")


def run_study(specs: list[DamperSpec], truth: DamperSpec | None = None, dt: float = 1e-3,
              speeds=SPEEDS, seed: int = 0, sweep: Road | None = None, pulse: Road | None = None,
              rough: Road | None = None, keep_runs: bool = False, progress=None, *,
              laws: Callable[..., Controller]) -> dict:
    """The chapter 5 study; see the module docstring. Returns a JSON-ready dict (arrays only if keep_runs).

    laws: the control-law registry's make (dampnet.recipes.control_laws.make): laws(name, spec,
    vehicle, fields=...) -> the Controller of law `name` calibrated on `spec`."""
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
                                             laws=dict(PASSIVE_LAWS, **{law: law for law in SKYHOOK_LAWS}),
                                             roads={k: r.meta for k, r in roads.items()}),
                               impulse={}, sine_sweep={}, rough_road={}, skyhook={}, errors={},
                               coverage={}, extrapolated={})
    runs: dict[str, Any] = {}
    ref = truth or all_specs[0]
    calibrated = {law: laws(law, ref, veh) for law in SKYHOOK_LAWS}
    gains = {law: {k: getattr(c, k) for k in GAINS} for law, c in calibrated.items()}
    sky_c = calibrated["skyhook_continuous"]
    res["settings"]["skyhook"] = dict(
        onoff={s.name: dict(u_soft=levels[s.name]["low"], u_hard=levels[s.name]["high"],
                            u_tau_s=calibrated["skyhook_onoff"].u_tau_s) for s in all_specs},
        continuous=dict(sky_c.to_dict(), calibrated_on=ref.name, zeta_sky=SKYHOOK_ZETA,
                        v_rms_m_s=SKYHOOK_V_RMS_M_S))

    def go(section, case, spec, road, speed, ctrl, law):
        if progress:
            progress(f"{section} {case} {spec.name}")
        r = simulate(spec, road, speed, ctrl, veh, law=law)
        res[section].setdefault(case, {})[spec.name] = r["metrics"]
        if "coverage" in r:
            res["coverage"].setdefault(section, {}).setdefault(case, {})[spec.name] = r["coverage"]
            ex = res["extrapolated"].setdefault(spec.name, dict(any=False, runs=0, extrapolated=[]))
            ex["runs"] += 1
            if r["coverage"]["extrapolated"]:
                ex["any"] = True
                ex["extrapolated"].append(f"{section} {case}")
        if keep_runs:
            runs.setdefault(section, {}).setdefault(case, {})[spec.name] = r
        return r

    for spec in all_specs:
        for level, law in PASSIVE_LAWS.items():
            passive = laws(law, spec, veh)
            go("impulse", level, spec, roads["impulse"], None, passive, law)
            go("sine_sweep", level, spec, roads["sine_sweep"], None, passive, law)
            for v in speeds:
                go("rough_road", f"{v:g}_{level}", spec, roads["rough_road"], v, passive, law)
        semi = {law: laws(law, spec, veh, fields=gains[law]) for law in SKYHOOK_LAWS}
        for v in speeds:
            for law in SKYHOOK_LAWS:
                go("skyhook", f"{v:g}_{law}", spec, roads["rough_road"], v, semi[law], law)
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
        res["_specs"] = {s.name: s for s in all_specs}
    return res


#: the file beside study.json holding the neural models' per-step damper inputs (dampnet plan-tests)
INPUTS_FILE = "inputs.npz"


def neural_inputs(res: dict) -> dict[str, np.ndarray]:
    """Each neural or hybrid model's damper inputs of every run of a study kept with keep_runs:
    {"<section>__<case>__<model>__features": [n, n_inputs] in the model's feature units,
    "...__t": [n] time [s], "models": "<model>=<model_id>" per model}; {} without kept runs."""
    runs, specs = res.get("_runs"), res.get("_specs", {})
    if not runs:
        return {}
    out: dict[str, np.ndarray] = {}
    names = set()
    for section, cases in runs.items():
        for case, by_model in cases.items():
            for name, r in by_model.items():
                spec = specs.get(name)
                if spec is None or spec.kind not in ("neural", "hybrid") or "features" not in r["arrays"]:
                    continue
                key = f"{section}__{case}__{name}"
                out[key + "__features"] = np.asarray(r["arrays"]["features"], dtype=np.float64)
                out[key + "__t"] = np.asarray(r["arrays"]["t"], dtype=np.float64)
                names.add(name)
    if out:
        out["models"] = np.array([f"{n}={specs[n].obj.model_id()}" for n in sorted(names)])
    return out
