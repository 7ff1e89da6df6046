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


def controller_fields(params: dict[str, Any]) -> dict[str, Any]:
    """The spec's [simulation.controller] fields set for this cell (u_tau_s among them: also the
    calibration's command filter)."""
    return {k[11:]: v for k, v in params.items() if k.startswith("controller.") and v is not None}


def run(params: dict[str, Any], inputs: dict[str, Any]) -> dict[str, Any]:
    """{"metrics": ride metrics and f_static_n, "controller_settings": the law's fields, "law": its
    registered name (dampnet.recipes.control_laws; the runtime's kind is in its fields)}: the run
    `dampnet simulate` makes (dampnet.recipes.quarter_car.run)."""
    from dampnet.recipes import quarter_car
    from dampnet.sweep.metrics import coverage_columns

    fields = controller_fields(params)
    res = quarter_car.run(damper(params, inputs["model"]), road(params, inputs["road"]), params["controller"],
                          speed_m_s=params["speed"], vehicle=vehicle(params), u_tau_s=fields.get("u_tau_s"),
                          fields=fields)
    metrics = {**res["metrics"], "f_static_n": res["f_static_n"], **coverage_columns(res)}
    return {"metrics": metrics, "controller_settings": res["controller"], "law": res["law"]}
