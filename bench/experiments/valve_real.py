"""The valve term on the real dampers (issue 54 item 2: "no worse than today on the real datasets").

For each real data set, bench/real_data.py's split, `dampnet train`'s default (algorithm and
restarts "auto") trained the two ways valve "auto" compares (valve "off" and "on": bit for bit
its two variants), each one's validation NRMSE and held-out RMSE [N], and which "auto" keeps
(dampnet.training.valve_choice.keep_hybrid on the validation errors, as it does).

  python bench/experiments/valve_real.py [--datasets utfsm,labcontrol] [--seed 0]
  python bench/experiments/valve_real.py --loop     # bench/real_data.py's dampnet rows only: the loop
                                                    # (dampnet.recipes.loop.run_loop) from the default

One JSON line per data set on stdout. About 2-6 minutes per data set on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--datasets", default="utfsm,labcontrol")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--loop", action="store_true", help="the diagnosis loop's rows of bench/real_data.py")
    args = ap.parse_args()
    from dampnet.predict import predict_force
    from dampnet.recipes.training import TrainingRequest, train
    from dampnet.training.valve_choice import keep_hybrid, validation_nrmse
    from real_data import BUDGETS, load, run_dampnet, scores, split

    for name in args.datasets.split(","):
        ds = load(name, quick=False)
        train_tests, test = split(name, ds)
        if args.loop:
            rows = run_dampnet(ds, train_tests, test, BUDGETS["full"]["dampnet"], BUDGETS["full"]["steps"],
                               seed=args.seed, log=lambda s: print(s, file=sys.stderr, flush=True))
            for r in rows:
                print(json.dumps({"dataset": name, "model": r["model"], "holdout_rmse_n": round(r["rmse_n"], 2),
                                  "at_rest": r.get("at_rest"), "diagnosis": (r.get("diagnosis") or {}).get("named"),
                                  "train_s": round(r["train_s"], 1)}, default=str), flush=True)
            continue
        row = {"dataset": name}
        for valve in ("off", "on"):
            req = TrainingRequest.of(algorithm="auto", restarts="auto", seed=args.seed, valve=valve,
                                     holdout_tests=[t.test_id for t in test], holdout_voltage=None)
            t0 = time.perf_counter()
            tr = train(ds, request=req, workers=1)
            held = tr.split.holdout.tests
            sc = scores(held, [predict_force(tr.model, t) for t in held])
            row[valve] = {"val_nrmse": round(validation_nrmse(tr.model, tr.info), 6),
                          "holdout_rmse_n": round(sc["rmse_n"], 2), "algorithm": tr.model.meta.get("algorithm"),
                          "time_s": round(time.perf_counter() - t0, 1),
                          **({"valve_params": [round(p, 5) for p in tr.model.terms[0]["params"]]}
                             if valve == "on" else {})}
        row["auto_keeps"] = "hybrid" if keep_hybrid(row["off"]["val_nrmse"], row["on"]["val_nrmse"]) else "network"
        print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
