"""One simulation cell, on a worker: a damper model, a road, a speed, a controller and a quarter car
in, the run's ride metrics out.

The run is `dampnet.sim.quarter_car.runs.simulate` (the runtime's C++ loop through QuarterCar, as
`dampnet simulate`). Controllers are calibrated on the cell's damper as `dampnet simulate`
calibrates them: passive_low / passive_high (passive = high) at the damper's own low / high
damping control (`damping_levels`), the on-off laws between them with the study's 5 ms
command filter, skyhook_continuous with c_sky, c_min, c_max from the vehicle and the damper
(`continuous_skyhook`). [simulation.controller] fields then replace the calibrated ones.
"""

from __future__ import annotations

import dataclasses
from typing import Any


def damper(params: dict[str, Any], value: Any):
    """The cell's DamperSpec: shipped or loaded (a file), or built from its name."""
    from dampnet.sweep.inputs import InputRef

    if not isinstance(value, InputRef):
        return value
    from dampnet.sim.dampers import load_spec

    if value.text == "default":
        from dampnet.modeldir import default_model_path
        from dampnet.sweep.hashing import file_digest
        from dampnet.sweep.inputs import InputChanged

        path = default_model_path()
        if file_digest(path) != value.digest:
            raise InputChanged(f"{path}: this worker's default model differs from the client's "
                               "(another dampnet version?)")
        return load_spec(str(path))
    return load_spec(value.text)


def road(params: dict[str, Any], value: Any):
    """The cell's Road: shipped or loaded (a CSV profile), or built from its name and seed."""
    from dampnet.sim import roads
    from dampnet.sweep.inputs import InputRef

    if not isinstance(value, InputRef):
        return value
    name = value.text.lower()
    if name == "impulse":
        return roads.impulse()
    if name == "bump":
        return roads.bump()
    if name == "sweep":
        return roads.sine_sweep()
    if name == "rough":
        return roads.thesis_rough_road(seed=params["road_seed"])
    return roads.iso8608(value.text[4:].upper(), length_m=params["road_length_m"], seed=params["road_seed"])


def vehicle(params: dict[str, Any]):
    from dampnet.sim.vehicle import Vehicle

    veh = Vehicle(**{k[8:]: v for k, v in params.items() if k.startswith("vehicle.") and v is not None})
    veh.validate()
    return veh


def controller(params: dict[str, Any], spec, veh):
    """The cell's Controller, calibrated on the damper, with the spec's fields on top."""
    from dampnet.sim.calibration import SKYHOOK_COMMAND_TAU_S, continuous_skyhook, damping_levels, semi_active
    from dampnet.sim.vehicle import Controller

    set_ = {k[11:]: v for k, v in params.items() if k.startswith("controller.") and v is not None}
    tau = set_.get("u_tau_s", SKYHOOK_COMMAND_TAU_S)
    levels = damping_levels(spec, veh.dt)
    name = params["controller"]
    if name.startswith("passive"):
        ctrl = Controller(kind="passive", u_passive=levels["low" if name == "passive_low" else "high"])
    elif name == "skyhook_continuous":
        ctrl = continuous_skyhook(spec, levels, veh, u_tau_s=tau)
    else:
        ctrl = semi_active(name, levels, tau)
    ctrl = dataclasses.replace(ctrl, **set_)
    ctrl.validate()
    return ctrl


def run(params: dict[str, Any], inputs: dict[str, Any]) -> dict[str, Any]:
    """{"metrics": ride metrics and f_static_n, "controller_settings": the law's fields}."""
    from dampnet.sim.quarter_car.runs import simulate

    spec = damper(params, inputs["model"])
    prof = road(params, inputs["road"])
    veh = vehicle(params)
    ctrl = controller(params, spec, veh)
    res = simulate(spec, prof, params["speed"] if prof.kind == "spatial" else None, ctrl, veh)
    from dampnet.sweep.metrics import coverage_columns

    metrics = {**res["metrics"], "f_static_n": res["f_static_n"], **coverage_columns(res)}
    return {"metrics": metrics, "controller_settings": ctrl.to_dict()}
