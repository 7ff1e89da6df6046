"""One full-vehicle test for one damper model: the same damper spec (dampnet.sim.dampers) at all
four corners, passive at its low or high damping setting or under on-off skyhook per corner,
through the runtime's FullCar, with the test's metrics."""

from __future__ import annotations

from typing import Callable

import numpy as np

from dampnet import _core
from dampnet.sim.full_car.maneuvers import Maneuver
from dampnet.sim.full_car.params import RUN_SCHEME, TRUTH_SCHEME, check, defaults
from dampnet.sim.calibration import damping_levels, semi_active
from dampnet.sim.dampers import DamperSpec, force_at_rest, runtime_damper
from dampnet.sim.vehicle import Controller, LoopError, Vehicle

#: the damping settings of a run: passive at the damper's low / high setting, or skyhook
#: the corners, in the runtime's order (FullCarModel's dampers, the [n, 4] columns)
CORNERS = ("fl", "fr", "rl", "rr")


def run(spec: DamperSpec, man: Maneuver, damping: str = "low", params: dict | None = None, *,
        metrics: Callable[[dict, Maneuver, dict], dict], controller: Controller, law: str | None = None) -> dict:
    """{'arrays': FullCar.simulate's arrays, 'metrics': metrics(arrays, man, params), 'params',
    'controller', 'law', ..., 'coverage' (neural and hybrid dampers: `run_coverage`)}.

    metrics: the test's; controller: every corner's, for the setting named `damping`, built by
    the control law named `law` (dampnet.recipes: `recipes.maneuvers.run` passes all three).
    params: full-car fields over the defaults (speed, dt and the steering mode come from the
    maneuver; damper_eval per_stage, RUN_SCHEME, the truth damper per_step, TRUTH_SCHEME)."""
    ctrl = controller
    u_rest = ctrl.u_soft if ctrl.kind != "passive" else ctrl.u_passive
    veh = Vehicle()
    veh.dt = man.dt
    f_static = force_at_rest(spec, u_rest, veh)
    p = {**defaults(), **(TRUTH_SCHEME if spec.kind == "truth" else RUN_SCHEME), **(params or {})}
    p.update(speed=man.speed, dt=man.dt, steer_mode="driver" if man.path is not None else "open_loop",
             f_static_f=f_static, f_static_r=f_static)
    check(p)
    # a stateful truth damper: one per corner; the others are stateless, so one damper object
    # serves the four corners (a float neural one is then evaluated in one kernel pass)
    dampers = [runtime_damper(spec) for _ in range(4)] if spec.kind == "truth" else [runtime_damper(spec)] * 4
    for d in dampers:
        d.reset()
    px, py = man.path if man.path is not None else (None, None)
    model = _core.FullCarModel([d.damper for d in dampers], p, ctrl.core_dict(), px, py)
    res = _core.FullCar(model).simulate(man.road, man.road_rate,
                                        steer=None if man.path is not None else man.steer)
    res["t"] = np.arange(man.road.shape[0]) * man.dt
    res["road"] = man.road
    out = dict(arrays=res, metrics=metrics(res, man, p), params=p, controller=ctrl.to_dict(), law=law,
               damper=spec.name, damping=damping, test=man.name, f_static_n=f_static,
               maneuver=man.meta)
    cov = run_coverage(spec, res)
    if cov is not None:
        out["coverage"] = cov
        res["outside"] = outside_mask(spec, res)
    return out


def outside_mask(spec: DamperSpec, arrays: dict) -> np.ndarray:
    """[n] bool: at that step some corner's damper inputs were outside the neural model's
    training ranges or its joint envelope (dampnet.envelope.coverage's measure), for the plots."""
    from dampnet.envelope.coverage import fullcar_inputs

    env = spec.meta.get("envelope")
    m = spec.obj
    out = np.zeros(len(arrays["t"]), dtype=bool)
    for X in fullcar_inputs(m, arrays):
        bad = np.any((X < m.sat_lo) | (X > m.sat_hi) | ~np.isfinite(X), axis=1)
        if env is not None:
            bad |= env.far(X)   # nearest distance > threshold, the tree stopping at the threshold
        out |= bad
    return out


def man_dt(arrays: dict) -> float | None:
    t = np.asarray(arrays["t"])
    return float(t[1] - t[0]) if t.size > 1 else None


def run_coverage(spec: DamperSpec, arrays: dict) -> dict | None:
    """The coverage (dampnet.envelope.coverage) of a full-vehicle run of a neural or hybrid spec: the four
    corners' damper inputs together (one row per corner and step), and per corner the share of
    time outside the envelope; None for other dampers."""
    if spec.kind not in ("neural", "hybrid"):
        return None
    from dampnet.envelope.coverage import coverage, fullcar_inputs, outside_shares, step_durations

    env, note = spec.meta.get("envelope"), spec.meta.get("envelope_note")
    per = fullcar_inputs(spec.obj, arrays)
    t = np.asarray(arrays["t"])
    w = step_durations(len(t), t, man_dt(arrays))
    cov = coverage(spec.obj, np.concatenate(per), env, durations=np.tile(w, len(per)), note=note)
    cov["worst_excursion"]["corner"] = CORNERS[cov["worst_excursion"]["step"] // max(1, len(t))]
    cov["worst_excursion"]["step"] %= max(1, len(t))
    cov["worst_excursion"]["t_s"] = float(t[cov["worst_excursion"]["step"]]) if len(t) else None
    cov["corners"] = {c: outside_shares(spec.obj, X, env, t=t) for c, X in zip(CORNERS, per)}
    return cov
