"""The cost of the force-tracking laws (issue 55, item 4): the HIL quarter car's step (the default model
as a float neural damper, HIL_VEHICLE: per-step evaluation, the linearised acceleration coupling, RK4,
dt 1 ms) with each law of the registry, timed in interleaved rounds against on-off skyhook (HIL_LAW).

Each round runs every law once over the same road (a 10 s two-tone road, 10,000 steps, in C++:
QuarterCar.simulate, the GIL released); a law's time per step is its run's time / steps. Reported:
median and p90 over the rounds [ns/step], the median of the per-round ratios to skyhook_onoff, and the
damper evaluations per step (the inverse's two limits and its Newton steps). Before any timing, every
law's run is checked on hard inputs (dampnet.latency.harness.hard_inputs: steps, chirps, a kerb): all
statuses OK and the outputs finite.

    python bench/force_laws.py                 # 15 rounds, about 2 s
    python bench/force_laws.py --rounds 5 --json out.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

LAWS = ("skyhook_onoff", "skyhook_continuous", "skyhook_force", "groundhook_force", "hybrid_force", "clipped_optimal")


def cars(model):
    from dampnet.latency.harness import HIL_VEHICLE
    from dampnet.recipes.control_laws import model_controller
    from dampnet.sim.quarter_car.loop import QuarterCar, damper_from_model

    damper = damper_from_model(model, single=True)
    return {law: QuarterCar(damper, dict(HIL_VEHICLE, dt=1e-3),
                            model_controller(law, model, HIL_VEHICLE["accel_feature"], 0.0).core_dict())
            for law in LAWS}


def check_hard_inputs(by_law) -> None:
    from dampnet.latency.harness import hard_inputs

    for law, car in by_law.items():
        for name, (z, zd) in hard_inputs(1e-3).items():
            r = car.simulate(z, zd)
            ok = np.all(r["status"] >= 0) and all(np.all(np.isfinite(r[k])) for k in ("force", "control", "acc_s"))
            if not ok:
                raise SystemExit(f"{law} on the hard input {name}: a failed status or a non-finite output")


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=15)
    ap.add_argument("--json", default=None, help="write the numbers here")
    args = ap.parse_args(argv)
    from dampnet.modeldir import default_model

    by_law = cars(default_model())
    check_hard_inputs(by_law)
    t = np.arange(10_000) * 1e-3
    z = 0.015 * (1 - np.cos(2 * np.pi * 1.2 * t)) + 0.002 * (1 - np.cos(2 * np.pi * 6.0 * t))
    zd = 0.015 * 2 * np.pi * 1.2 * np.sin(2 * np.pi * 1.2 * t) + 0.002 * 2 * np.pi * 6.0 * np.sin(2 * np.pi * 6.0 * t)
    ns = {law: [] for law in LAWS}
    evals = {}
    for _ in range(args.rounds):
        for law, car in by_law.items():
            before = car.loop.damper_evals
            t0 = time.perf_counter_ns()
            car.simulate(z, zd)
            ns[law].append((time.perf_counter_ns() - t0) / t.size)
            evals[law] = (car.loop.damper_evals - before) / (t.size - 1)   # n samples: n - 1 steps
    base = np.array(ns["skyhook_onoff"])
    out = {}
    print(f"{'law':20s} {'median ns/step':>15s} {'p90':>8s} {'ratio to skyhook_onoff':>23s} {'evaluations/step':>17s}")
    for law in LAWS:
        a = np.array(ns[law])
        out[law] = {"median_ns": float(np.median(a)), "p90_ns": float(np.percentile(a, 90)),
                    "ratio_median": float(np.median(a / base)), "evals_per_step": evals[law]}
        e = evals[law]
        print(f"{law:20s} {out[law]['median_ns']:15.0f} {out[law]['p90_ns']:8.0f} {out[law]['ratio_median']:23.2f} "
              f"{e:17.2f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"rounds": args.rounds, "laws": out}, f, indent=1)
    return out


if __name__ == "__main__":
    main()
