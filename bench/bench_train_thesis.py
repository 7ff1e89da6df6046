"""LM (and the other algorithms) on the full thesis plan: time to final accuracy, per decimation.

The rig's default data (thesis plan: 180 tests, 12 frequencies 0.25-3 Hz x 15 voltages,
2.45 M samples at 5 kHz, no extra effects, seed 0); all 2.25 V tests held out; the
training tests decimated by each factor; LM with dampnet's defaults (3-30-1, tanh,
70/15/15 split, early stopping, rest points). Reports, per factor: training
samples, LM time (algorithm only) and time to the best-validation epoch (the weights
returned: "final accuracy"), wall time including data preparation, epochs, NRMSE on
fit()'s random test subset and on the held-out tests, and the noise floor in the same
(range) definition. With --algorithms, the thesis's Table 3 for dampnet at one factor.

    python bench/bench_train_thesis.py [--decimate 10,25,50] [--algorithms lm,br,scg,adam]
                                       [--no-write]

Appends (replaces) its own section of bench/RESULTS.md.
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import time
from pathlib import Path

import torch

from dampnet.data import add_acceleration
from dampnet.rig import generate
from dampnet.training import nrmse, torch_forward
from dampnet.features import feature_matrix
from dampnet.training.pipeline import noise_floors, train_dataset

RESULTS = Path(__file__).resolve().parent / "RESULTS.md"
BEGIN, END = "<!-- bench_train_thesis: begin -->", "<!-- bench_train_thesis: end -->"


def one(ds, algorithm: str, factor: int, seed: int) -> dict:
    t0 = time.perf_counter()
    model, info, split = train_dataset(ds, algorithm=algorithm, decimate=factor, seed=seed)
    wall = time.perf_counter() - t0
    # the float64 torch reference (equal to the C++ kernel to 1e-12; tests/python/test_evaluate_runtime.py)
    pred = torch_forward(model, feature_matrix(split.holdout.tests, model.features))
    best = info.history[info.best_epoch]["time_s"] if info.best_epoch < len(info.history) else info.time_s
    return {"algorithm": algorithm, "decimate": factor, "n_train": info.n_train, "time_s": info.time_s,
            "time_best_s": best, "wall_s": wall, "epochs": info.epochs, "best_epoch": info.best_epoch,
            "test": info.metrics["test"], "holdout": nrmse(pred, split.holdout.concat("force")),
            "threads": model.meta.get("threads"), "stop": info.stop_reason}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--decimate", default="10,25,50")
    ap.add_argument("--algorithms", default="", help="also run these at --table-decimate (Table 3)")
    ap.add_argument("--table-decimate", type=int, default=25)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args()

    t0 = time.perf_counter()
    ds = generate("thesis", seed=args.seed)
    add_acceleration(ds)
    t_data = time.perf_counter() - t0
    n = sum(len(t) for t in ds.tests)
    held = [t for t in ds.tests if t.control_nominal == 2.25]
    floor = noise_floors(ds.subset(held))
    print(f"thesis plan: {len(ds.tests)} tests, {n} samples, generated + acceleration in {t_data:.1f} s; "
          f"noise floor on the hold-out: NRMSE {floor['nrmse_range']:.5f} (range), "
          f"{floor['nrmse_std']:.5f} (std)", flush=True)
    rows = []
    for f in [int(s) for s in args.decimate.split(",") if s.strip()]:
        r = one(ds, "lm", f, args.seed)
        rows.append(r)
        print(r, flush=True)
    table = []
    for a in [s.strip() for s in args.algorithms.split(",") if s.strip()]:
        r = one(ds, a, args.table_decimate, args.seed)
        table.append(r)
        print(r, flush=True)

    load = os.getloadavg()[0]
    lines = [BEGIN, "## Training on the thesis plan (bench/bench_train_thesis.py)", "",
             f"Measured {time.strftime('%Y-%m-%d')} on {platform.machine()}, {os.cpu_count()} cores "
             f"(1-min load average {load:.1f} at the end), torch {torch.__version__}, seed {args.seed}. "
             f"Data: rig thesis plan, no effects, {len(ds.tests)} tests, {n} samples at 5 kHz; "
             f"{len(held)} tests at 2.25 V held out. LM, 3-30-1 tanh, 70/15/15, early stopping (max_fail 6).",
             "", "| decimate | train samples | LM time [s] | to best epoch [s] | wall incl. prep [s] | epochs (best) "
             "| NRMSE test subset | NRMSE hold-out |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['decimate']} | {r['n_train']} | {r['time_s']:.1f} | {r['time_best_s']:.1f} | "
                     f"{r['wall_s']:.1f} | {r['epochs']} ({r['best_epoch']}) | {r['test']:.5f} | {r['holdout']:.5f} |")
    lines += ["", f"Noise floor of the hold-out data (load-cell noise alone), same definition as NRMSE "
              f"(RMSE / force range): {floor['nrmse_range']:.5f} (in the rig's std definition "
              f"{floor['nrmse_std']:.5f}). The thesis's LM: 0.0339 in 106 min.", ""]
    if table:
        lines += [f"Table 3 for dampnet (decimate {args.table_decimate}, same split and seed):", "",
                  "| algorithm | NRMSE test subset | NRMSE hold-out | time [s] | epochs | stop |",
                  "|---|---|---|---|---|---|"]
        for r in table:
            lines.append(f"| {r['algorithm']} | {r['test']:.5f} | {r['holdout']:.5f} | {r['time_s']:.1f} | "
                         f"{r['epochs']} | {r['stop']} |")
        lines.append("")
    lines.append(END)
    section = "\n".join(lines)
    print(section)
    if not args.no_write:
        text = RESULTS.read_text() if RESULTS.exists() else "# Benchmark results\n"
        if BEGIN in text and END in text:
            text = re.sub(re.escape(BEGIN) + ".*?" + re.escape(END), lambda _: section, text, flags=re.S)
        else:
            text = text.rstrip("\n") + "\n\n" + section + "\n"
        RESULTS.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
