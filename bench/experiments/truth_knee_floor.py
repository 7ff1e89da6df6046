"""What is left between the thesis plan's held-out error and the noise floor: the valves' knees or the
seal friction? (issue 33, bench/LOG.md "1 V with two restarts, the restarts' start-up, and where
issue 33 ends".)

The rig's thesis plan is generated again with its truth damper changed, one `dampnet.train` per seed
(the default training, restarts=1, so the truth and not the selection is measured), 2.25 V held out,
and the held-out RMSE over the load cell's noise RMS printed, overall and per frequency:

  as is        the rig's truth (dampnet.rig.truth.TruthParams())
  no knee      the shim stacks open from zero pressure (crack pressures 0): the same digressive
               curve at speed, without the blow-off knee's kink in force against velocity
  no friction  no seal friction (its 40 N step within +-2 mm/s gone)

  python bench/experiments/truth_knee_floor.py [--seeds 0,1,2] [--variants "as is,no knee"]

One JSON line per (seed, variant) on stdout. About 2-4 minutes per training on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace


def variants() -> dict:
    from dampnet.rig.truth import TruthParams

    p0 = TruthParams()
    return {"as is": p0,
            "no knee": replace(p0, crack_pressure_rebound_pa=0.0, crack_pressure_compression_pa=0.0),
            "no friction": replace(p0, seal_friction_n=0.0)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="0,1", help="comma-separated training seeds")
    ap.add_argument("--variants", default="as is,no knee,no friction", help="comma-separated, of the above")
    args = ap.parse_args()
    import dampnet
    from dampnet.rig import generate

    known = variants()
    chosen = [v.strip() for v in args.variants.split(",")]
    unknown = [v for v in chosen if v not in known]
    if unknown:
        raise SystemExit(f"--variants: unknown {unknown}; known: {', '.join(known)}")
    for seed in (int(s) for s in args.seeds.split(",")):
        for name in chosen:
            ds = generate("thesis", seed=0, params=known[name])
            t0 = time.perf_counter()
            trained = dampnet.train(ds, seed=seed, holdout_voltage=2.25, algorithm="auto", restarts=1)
            hv = trained.metrics["noise_floor"]["holdout_vs_floor"]
            print(json.dumps({"variant": name, "seed": seed, "nrmse": round(trained.metrics["holdout"]["overall"]["nrmse"], 5),
                              "floor_ratio": round(hv["ratio"], 3),
                              "per_frequency": {f"{r['frequency_hz']:g}": round(r["ratio"], 2) for r in hv["per_frequency"]},
                              "time_s": round(time.perf_counter() - t0, 1)}), flush=True)


if __name__ == "__main__":
    main()
