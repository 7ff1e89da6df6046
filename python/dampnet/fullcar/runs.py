"""One full-vehicle test for one damper model: the same damper spec (dampnet.sim.dampers) at all
four corners, passive at its low or high damping setting or under on-off skyhook per corner,
through the runtime's FullCar, with the test's metrics."""

from __future__ import annotations

import numpy as np

from dampnet import _core
from dampnet.fullcar.maneuvers import Maneuver
from dampnet.fullcar.metrics import metrics_of
from dampnet.fullcar.params import RUN_SCHEME, check, defaults
from dampnet.sim.calibration import damping_levels, semi_active
from dampnet.sim.dampers import DamperSpec, force_at_rest, runtime_damper
from dampnet.sim.vehicle import Controller, LoopError, Vehicle

#: the damping settings of a run: passive at the damper's low / high setting, or skyhook
DAMPING = ("low", "high", "skyhook")


def controller_for(spec: DamperSpec, damping: str, levels: dict | None = None) -> Controller:
    """Every corner's controller: passive at the low / high setting, or on-off skyhook between
    them with the quarter car's command filter."""
    if damping not in DAMPING:
        raise LoopError(f"damping must be one of {', '.join(DAMPING)}, got {damping!r}")
    lv = levels or damping_levels(spec)
    if damping == "skyhook":
        return semi_active("skyhook_onoff", lv)
    ctrl = Controller(kind="passive", u_passive=lv[damping], u_min=min(lv.values()), u_max=max(lv.values()))
    ctrl.validate()
    return ctrl


def run(spec: DamperSpec, man: Maneuver, damping: str = "low", params: dict | None = None) -> dict:
    """{'arrays': FullCar.simulate's arrays, 'metrics': ..., 'params', 'controller', ...}.

    params: full-car fields over the defaults (speed, dt and the steering mode come from the
    maneuver; damper_eval per_step as every Python-side run, RUN_SCHEME)."""
    ctrl = controller_for(spec, damping)
    u_rest = ctrl.u_soft if ctrl.kind != "passive" else ctrl.u_passive
    veh = Vehicle()
    veh.dt = man.dt
    f_static = force_at_rest(spec, u_rest, veh)
    p = {**defaults(), **RUN_SCHEME, **(params or {})}
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
    return dict(arrays=res, metrics=metrics_of(res, man, p), params=p, controller=ctrl.to_dict(),
                damper=spec.name, damping=damping, test=man.name, f_static_n=f_static,
                maneuver=man.meta)
