"""How well the force-tracking laws track their demand on the quarter car, by acceleration scheme and
command filter (issue 55: the numbers behind FORCE_COMMAND_TAU_S = 0 and the linearised scheme's
tracking; not a product feature).

The default model (it reads the acceleration) on the study's ISO roads (dampnet.recipes.control_study:
classes B, C, D at 40, 80, 120 km/h, 200 m, seed 0), each law of FORCE_LAWS as the registry makes it,
and with the registry's 5 ms filter of the switching laws (SKYHOOK_COMMAND_TAU_S), under each of the
vehicle's acceleration schemes (implicit: the default; linear: the HIL's and the firmware's;
explicit). Printed: the tracking error where the demand is reachable, relative to the demand's RMS
(control_study.tracking), worst and best over the roads and speeds, per law.

    python bench/experiments/force_tracking.py

About 30 s on 2 cores.
"""

from __future__ import annotations

import dataclasses


def main() -> None:
    from dampnet.recipes import control_laws, roads
    from dampnet.recipes.control_study import FORCE_LAWS, ROAD_CLASSES, ROAD_LENGTH_M, SPEEDS_KMH, tracking
    from dampnet.sim.calibration import SKYHOOK_COMMAND_TAU_S
    from dampnet.sim.dampers import load_spec
    from dampnet.sim.quarter_car.runs import simulate
    from dampnet.sim.vehicle import Vehicle

    spec = load_spec("default")
    print("| scheme | filter | " + " | ".join(FORCE_LAWS) + " |")
    print("|---" * (2 + len(FORCE_LAWS)) + "|")
    for scheme in ("implicit", "linear", "explicit"):
        veh = Vehicle(accel_feature=scheme)
        for tau in (None, SKYHOOK_COMMAND_TAU_S):
            cells = []
            for law in FORCE_LAWS:
                ctrl = control_laws.make(law, spec, veh)
                if tau is not None:
                    ctrl = dataclasses.replace(ctrl, u_tau_s=tau)
                errs = []
                for c in ROAD_CLASSES:
                    for kmh in SPEEDS_KMH:
                        v = kmh / 3.6
                        road = roads.build(f"iso:class={c},length_m={ROAD_LENGTH_M:g}", seed=0, speed_m_s=v)
                        errs.append(tracking(spec, ctrl, simulate(spec, road, v, ctrl, veh, law=law))["tracking_rel"])
                cells.append(f"{100 * min(errs):.1f}-{100 * max(errs):.1f} %")
            label = "none (the registry's)" if tau is None else f"{1e3 * tau:g} ms"
            print(f"| {scheme} | {label} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
