"""One quarter-car run by names: what `dampnet simulate` and a sweep's [simulation] cell run.

    run(spec, road, law, speed_m_s=..., vehicle=None, u_tau_s=None, damping="high", u=None, fields=None)

The damper is a spec (dampnet.sim.dampers.load_spec), the road a Road (dampnet.recipes.roads
builds it from its name), the law a name of the control-law registry, built and calibrated on
the damper and the vehicle by the registry (dampnet.recipes.control_laws.make; `fields`:
Controller fields set over the calibrated ones); the run is dampnet.sim.quarter_car.runs.simulate
(the runtime's loop), and it records the law's registered name.
"""

from __future__ import annotations

from typing import Any, Mapping

from dampnet.recipes import control_laws
from dampnet.sim.vehicle import Vehicle


def run(spec, road, law: str, *, speed_m_s: float = 10.0, vehicle: Vehicle | None = None,
        u_tau_s: float | None = None, damping: str = "high", u: float | None = None,
        fields: Mapping[str, Any] | None = None) -> dict:
    """simulate's result (arrays, metrics, coverage, ...) of `spec` over `road` (a distance
    profile at speed_m_s [m/s]; a time profile as it is) under control law `law`."""
    from dampnet.sim.quarter_car.runs import simulate

    veh = vehicle or Vehicle()
    veh.validate()
    ctrl = control_laws.make(law, spec, veh, u_tau_s=u_tau_s, damping=damping, u=u, fields=fields)
    return simulate(spec, road, speed_m_s if road.kind == "spatial" else None, ctrl, veh,
                    law=control_laws.get(law).name)
