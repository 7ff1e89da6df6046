"""One simulation cell, on a worker: a damper model, a road, a speed, a controller and a quarter car
in, the run's ride metrics out.

The run is `dampnet.sim.quarter_car.runs.simulate` (the runtime's C++ loop through QuarterCar, as
`dampnet simulate`). Roads and controllers come from the registries `dampnet simulate` reads
(dampnet.recipes.roads, dampnet.recipes.control_laws): a controller is calibrated on the cell's
damper (passive = passive_high), then [simulation.controller] fields replace the calibrated ones.
"""

from __future__ import annotations

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
    """The cell's Road: shipped or loaded (a CSV profile), or built by name (dampnet.recipes.roads)
    with the cell's road_seed, road_length_m and speed as the road's seed, length_m and speed_m_s
    (those it fills: RoadKind.fills)."""
    from dampnet.recipes import roads
    from dampnet.sweep.inputs import InputRef

    if not isinstance(value, InputRef):
        return value
    return roads.parse(value.text).build(seed=params["road_seed"], length_m=params["road_length_m"],
                                         speed_m_s=params["speed"])


def vehicle(params: dict[str, Any]):
    from dampnet.sim.vehicle import Vehicle

    veh = Vehicle(**{k[8:]: v for k, v in params.items() if k.startswith("vehicle.") and v is not None})
    veh.validate()
    return veh


def controller(params: dict[str, Any], spec, veh):
    """The cell's Controller (dampnet.recipes.control_laws: calibrated on the damper), with the
    spec's [simulation.controller] fields on top (u_tau_s also the calibration's command filter)."""
    from dampnet.recipes import control_laws

    set_ = {k[11:]: v for k, v in params.items() if k.startswith("controller.") and v is not None}
    return control_laws.make(params["controller"], spec, veh, u_tau_s=set_.get("u_tau_s"), fields=set_)


def run(params: dict[str, Any], inputs: dict[str, Any]) -> dict[str, Any]:
    """{"metrics": ride metrics and f_static_n, "controller_settings": the law's fields, "law": its
    registered name (dampnet.recipes.control_laws; the runtime's kind is in its fields)}."""
    from dampnet.sim.quarter_car.runs import simulate

    spec = damper(params, inputs["model"])
    prof = road(params, inputs["road"])
    veh = vehicle(params)
    from dampnet.recipes import control_laws

    ctrl = controller(params, spec, veh)
    law = control_laws.get(params["controller"]).name
    res = simulate(spec, prof, params["speed"] if prof.kind == "spatial" else None, ctrl, veh, law=law)
    from dampnet.sweep.metrics import coverage_columns

    metrics = {**res["metrics"], "f_static_n": res["f_static_n"], **coverage_columns(res)}
    return {"metrics": metrics, "controller_settings": ctrl.to_dict(), "law": law}
