"""One full-vehicle cell, on a worker: a damper model at all four corners, a test (bounce sine
sweep, ISO 3888-1 double lane change, rough road), a damping setting and the full car's
parameters in, the test's metrics out.

The run is `dampnet.sim.full_car.runs.run` (the runtime's FullCar, as `dampnet vehicle`): the same
damper spec at every corner, passive at its low or high damping setting or on-off skyhook per
corner, its force at rest as the static force; [fullcar.vehicle] fields over the runtime's
defaults. The test is built as `dampnet vehicle` builds it (dampnet.recipes.maneuvers) at the
cell's dt, with the cell's settings (its entry's: speed [km/h], bsst mode and sweep, road
(dampnet.recipes.roads) and seed, ...); the road test's rear wheels follow the front ones by the cell's
wheelbase (a + b).
"""

from __future__ import annotations

from typing import Any

from dampnet.sweep.metrics import WHEELS, coverage_columns


def vehicle(params: dict[str, Any]) -> dict[str, Any]:
    """The cell's [fullcar.vehicle] fields (those set; the runtime's defaults for the others)."""
    return {k[8:]: v for k, v in params.items() if k.startswith("vehicle.") and v is not None}


def maneuver(params: dict[str, Any], inputs: dict[str, Any] | None = None):
    """The cell's test (a dampnet.sim.full_car.maneuvers.Maneuver, built by dampnet.recipes.maneuvers);
    a CSV road is the cell's input as the worker read it (its content checked against the key's)."""
    from dampnet.recipes import maneuvers
    from dampnet.sim.roads import Road

    m = maneuvers.get(params["test"])
    settings = {k: params[k] for k in m.defaults}
    road = (inputs or {}).get("road")
    if "road" in settings and isinstance(road, Road):
        settings["road"] = road
    return maneuvers.build(m.name, params["dt"], settings, vehicle(params))


def flat_metrics(metrics: dict[str, Any]) -> dict[str, Any]:
    """fullcar's metrics as table cells: a per-wheel list as one column per wheel (name_fl_n, ...)."""
    out: dict[str, Any] = {}
    for k, v in metrics.items():
        if isinstance(v, (list, tuple)):
            stem, unit = k.rsplit("_", 1)
            out.update({f"{stem}_{w}_{unit}": x for w, x in zip(WHEELS, v)})
        else:
            out[k] = v
    return out


def run(params: dict[str, Any], inputs: dict[str, Any]) -> dict[str, Any]:
    """{"metrics": the test's metrics, f_static_n and duration_s, "controller_settings": the law's fields,
    "law": its registered name (dampnet.recipes.control_laws.VEHICLE_DAMPING of the cell's damping)}."""
    from dampnet.recipes.maneuvers import run as run_test
    from dampnet.sweep.sim_cell import damper

    spec = damper(params, inputs["model"])
    man = maneuver(params, inputs)
    res = run_test(spec, man, params["damping"], vehicle(params))
    metrics = {**flat_metrics(res["metrics"]), "f_static_n": res["f_static_n"],
               "duration_s": man.road.shape[0] * man.dt, **coverage_columns(res)}
    return {"metrics": metrics, "controller_settings": res["controller"], "law": res["law"]}
