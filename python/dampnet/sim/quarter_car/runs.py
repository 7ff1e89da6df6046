"""One quarter-car run of a damper spec over a road, with its ride metrics.

The run goes through `dampnet.sim.quarter_car.loop.QuarterCar` (the runtime's C++ loop) with the
Vehicle's loop scheme (RK4, one damper evaluation per step: `vehicle.LOOP_SCHEME`), so the
models of a study are compared like for like and the rig's truth damper (a callback) is
stepped once per step.
"""

from __future__ import annotations

import numpy as np

from dampnet.envelope.coverage import coverage, quarter_car_inputs
from dampnet.sim.dampers import DamperSpec, force_at_rest, runtime_damper
from dampnet.sim.quarter_car.loop import QuarterCar, columns
from dampnet.sim.ride import ride_metrics, transmissibility
from dampnet.sim.roads import Road
from dampnet.sim.vehicle import Controller, Vehicle


def loop_arrays(spec: DamperSpec, z_r, v_r, vehicle: Vehicle, controller: Controller) -> tuple[dict, float]:
    """Run road samples z_r [m], v_r [m/s] at t = k dt -> (arrays, f_static [N]).

    arrays: `loop.columns` of the run, one row per step at the step's start (n = len(z_r) - 1:
    the last road sample is the end of the last step). f_static: the vehicle's, or (None)
    the damper's force at rest with the controller's control at rest.
    """
    damper = runtime_damper(spec)
    f_static = vehicle.f_static
    if f_static is None:
        at_rest = QuarterCar(damper.damper, vehicle.core_dict(), controller.core_dict())
        u0 = float(at_rest.model.control(np.zeros(1), np.zeros(1))[0])
        f_static = force_at_rest(spec, u0, vehicle)
    car = QuarterCar(damper.damper, vehicle.core_dict(f_static), controller.core_dict())
    damper.reset()
    res = car.simulate(np.ascontiguousarray(z_r, dtype=np.float64), np.ascontiguousarray(v_r, dtype=np.float64))
    n = res["state"].shape[0] - 1    # the last report is at the road's end (no step after it)
    return {k: np.array(a[:n]) for k, a in columns(res).items()}, float(f_static)


def spec_coverage(spec: DamperSpec, arrays: dict) -> dict | None:
    """The coverage (dampnet.envelope.coverage) of a quarter-car run of a neural or hybrid spec against
    its model's training envelope (spec.meta["envelope"], or its ranges only); None for others."""
    if spec.kind not in ("neural", "hybrid"):
        return None
    return coverage(spec.obj, quarter_car_inputs(spec.obj, arrays), spec.meta.get("envelope"), t=arrays["t"],
                    note=spec.meta.get("envelope_note"))


def simulate(spec: DamperSpec, road: Road, speed: float | None = None, controller: Controller | None = None,
             vehicle: Vehicle | None = None, transfer: bool | None = None, law: str | None = None) -> dict:
    """One run: {'arrays': {...}, 'metrics': {...}, 'transmissibility': {...} (sweeps), ...,
    'controller': its fields (the runtime's `kind` among them), 'law': `law`, the name of the
    control law that built it (dampnet.recipes.control_laws; None: a Controller given as is),
    'coverage': {...} (neural and hybrid dampers: dampnet.envelope.coverage, against the training envelope)}.

    A wrong vehicle or controller setting (an unknown law name among them) raises LoopError
    naming the field and the valid range or names.
    """
    veh = vehicle or Vehicle()
    ctrl = controller or Controller()
    veh.validate()
    ctrl.validate()
    s = road.sample(veh.dt, speed)
    arr, f_static = loop_arrays(spec, s.z, s.zdot, veh, ctrl)
    metrics = ride_metrics(arr["t"], arr["z_s"], arr["z_us"], arr["z_r"], arr["acc_s"], veh.k_t,
                           veh.m_s, veh.m_us)
    out = dict(arrays=arr, metrics=metrics, f_static_n=f_static, road=road.meta,
               speed_m_s=speed, controller=ctrl.to_dict(), law=law, vehicle=veh.to_dict(), damper=spec.name)
    cov = spec_coverage(spec, arr)
    if cov is not None:
        out["coverage"] = cov
    if transfer or (transfer is None and road.meta.get("input") == "sine_sweep"):
        f1 = road.meta.get("f1_hz", 20.0)
        tr = transmissibility(arr["z_r"], arr["z_s"], 1.0 / veh.dt, fmin=road.meta.get("f0_hz", 0.5),
                              fmax=f1)
        out["transmissibility"] = tr
        metrics["transmissibility_peak"] = float(np.max(tr["magnitude"]))
        metrics["transmissibility_peak_hz"] = float(tr["f_hz"][np.argmax(tr["magnitude"])])
    return out
