"""Held-out NRMSE over training seeds 0-9, without and with restarts (issue 18, robust training).

For each configuration, trains `dampnet.train` (train_dataset) once per seed (restarts=1: the
training as it always was) and with restarts (the kept model of N restarts, scored by
interpolation or by leave-one-level-out), evaluates the 2.25 V hold-out tests and records the
wall time of each training call. Prints a markdown table (max/min is the issue's spread figure)
and writes the per-seed numbers as JSON.

Configurations (data: the virtual rig, no hidden effect unless stated):
  quick         the rig's quick plan (3 Hz x 0/2.25/5 V: two training levels), `dampnet train`'s defaults
  sparse-issue  the 5-frequency x 8-voltage plan at 1 kHz (tests/python/test_diagnose_hidden.py's, data
                seed 1) with issue 18's settings: every 4th sample, at most 120 LM epochs
  sparse        the same plan with `dampnet train`'s defaults (about 200 Hz, up to 1000 epochs, early stop)
  demo-quick    the demo's --quick plan (4 Hz x 8 V), 150 epochs as the demo trains it

Usage (2 worker processes, one torch thread each; restarts=1 runs with one thread as well):

  python bench/experiments/restarts_seed_spread.py [CONFIG ...] [--restarts 6] [--lolo] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

import numpy as np

SPARSE_PLAN = {"name": "sparse-5x8", "frequencies_hz": [0.25, 0.5, 1.0, 2.0, 3.0], "amplitudes_m": [0.0254],
               "voltages_v": [0.0, 0.5, 1.0, 1.5, 2.25, 3.0, 4.0, 5.0], "sample_rate_hz": 1000.0,
               "samples": 2000, "min_cycles": 2}


def configs():
    from dampnet.demo.run import QUICK_PLAN

    return {
        "quick": ("quick", 0, {}),
        "sparse-issue": (SPARSE_PLAN, 1, {"decimate": 4, "max_epochs": 120}),
        "sparse": (SPARSE_PLAN, 1, {}),
        "demo-quick": (QUICK_PLAN, 0, {"max_epochs": 150}),
    }


def holdout_nrmse(model, split) -> float:
    from dampnet.evaluation.metrics import evaluate_predictions
    from dampnet.predict import predict_force

    tests = split.holdout.tests
    return float(evaluate_predictions(tests, [predict_force(model, t) for t in tests])["overall"]["nrmse"])


def run(name: str, restarts: int, lolo: bool, workers: int) -> dict:
    from dampnet.data import DataError
    from dampnet.rig import generate
    from dampnet.training.pipeline import train_dataset

    plan, data_seed, kw = configs()[name]
    ds = generate(plan, seed=data_seed)
    variants = [("restarts=1", {"restarts": 1, "threads": 1}),
                (f"restarts={restarts}", {"restarts": restarts, "workers": workers})]
    if lolo:
        variants.append((f"restarts={restarts} lolo", {"restarts": restarts, "workers": workers,
                                                       "restart_score": "lolo"}))
    out = {"config": name, "train": kw, "variants": {}}
    for label, extra in variants:
        rows = []
        for seed in range(10):
            t0 = time.perf_counter()
            try:
                model, info, split = train_dataset(ds, seed=seed, **kw, **extra)
            except DataError as e:  # e.g. LOLO on two training levels
                print(f"{name:12s} {label:18s}: not applicable ({e})", flush=True)
                break
            dt = time.perf_counter() - t0
            r = {"seed": seed, "holdout_nrmse": holdout_nrmse(model, split), "time_s": dt}
            if "restarts" in model.meta:
                r["kept_seed"] = model.meta["restarts"]["kept_seed"]
            rows.append(r)
            print(f"{name:12s} {label:18s} seed {seed}: hold-out NRMSE {r['holdout_nrmse']:.4f} in {dt:.1f} s",
                  flush=True)
        if not rows:
            continue
        h = np.array([r["holdout_nrmse"] for r in rows])
        t = np.array([r["time_s"] for r in rows])
        out["variants"][label] = {"rows": rows, "min": h.min(), "median": float(np.median(h)), "max": h.max(),
                                  "max_over_min": h.max() / h.min(), "time_median_s": float(np.median(t))}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("configs", nargs="*", default=["quick", "sparse-issue", "sparse", "demo-quick"])
    ap.add_argument("--restarts", type=int, default=6)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--lolo", action="store_true", help="also the leave-one-level-out score")
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    import torch

    torch.set_num_threads(1)
    t0 = time.time()
    results = [run(c, args.restarts, args.lolo, args.workers) for c in args.configs]
    print(f"\n{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime(t0))}, {platform.machine()}, {os.cpu_count()} cores, "
          f"torch {torch.__version__}, load average {os.getloadavg()[0]:.1f} at the end\n")
    print("| config | training | hold-out NRMSE min / median / max | max/min | time per training, median [s] |")
    print("|---|---|---|---|---|")
    for r in results:
        for label, v in r["variants"].items():
            print(f"| {r['config']} | {label} | {v['min']:.4f} / {v['median']:.4f} / {v['max']:.4f} | "
                  f"{v['max_over_min']:.2f} | {v['time_median_s']:.1f} |")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1, default=float)


if __name__ == "__main__":
    main()
