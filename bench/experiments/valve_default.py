"""Does a free valve term lower the default training's error inside the envelope? (issue 54 item 2)

The rig's thesis plan (rig seed 0), 2.25 V held out, `dampnet.train`'s default (algorithm 'auto',
restarts 1) with and without a free valve term (terms=[{"kind": "valve"}]: fitted first by
nonlinear least squares, the network trained on what it leaves). Prints per (seed, model) the
validation NRMSE (the rows the fit held back to stop on), the held-out NRMSE, the held-out RMSE over
the load cell's noise, its worst frequency, and the time.

  python bench/experiments/valve_default.py [--seeds 0,1,2] [--plan thesis]
  python bench/experiments/valve_default.py --command [--seeds 0,1,2]

--command trains as `dampnet train` does by default instead (algorithm, restarts and valve "auto":
dampnet.training.settings.command_defaults), one line per seed: the shippable model.

One JSON line per (seed, model) on stdout. About 2-4 minutes per training on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="0,1,2", help="comma-separated training seeds")
    ap.add_argument("--plan", default="thesis", help="rig plan (dampnet rig --plan)")
    ap.add_argument("--command", action="store_true", help="dampnet train's defaults (valve auto), one model a seed")
    args = ap.parse_args()
    import dampnet
    from dampnet.rig import generate
    from dampnet.training.settings import command_defaults

    ds = generate(args.plan, seed=0)
    for seed in (int(s) for s in args.seeds.split(",")):
        variants = ((("command", command_defaults()),) if args.command else
                    (("network", {"algorithm": "auto", "restarts": 1}),
                     ("hybrid", {"algorithm": "auto", "restarts": 1, "terms": [{"kind": "valve"}]})))
        for name, options in variants:
            t0 = time.perf_counter()
            trained = dampnet.train(ds, seed=seed, holdout_voltage=2.25, **options)
            m = trained.metrics
            hv = m.get("noise_floor", {}).get("holdout_vs_floor", {})
            per = {f"{r['frequency_hz']:g}": round(r["ratio"], 2) for r in hv.get("per_frequency", [])}
            print(json.dumps({"model": name, "seed": seed, "nrmse": m["training"]["nrmse"],
                              "holdout_nrmse": round(m["holdout"]["overall"]["nrmse"], 5),
                              "floor_ratio": round(hv.get("ratio", float("nan")), 3),
                              "worst_frequency_ratio": max(per.values()) if per else None, "per_frequency": per,
                              "algorithm": m["training"]["algorithm"], "epochs": m["training"]["epochs"],
                              "valve": trained.model.meta.get("valve"),
                              "restarts": (trained.model.meta.get("restarts") or {}).get("n", 1),
                              "time_s": round(time.perf_counter() - t0, 1)}), flush=True)


if __name__ == "__main__":
    main()
