"""How close can any choice among N restarts get to issue 18's spread goal (held-out max/min <= 1.5
over base seeds 0-9)? Fits 10 restarts per base seed (the seeds dampnet.training.restarts derives),
records each one's held-out NRMSE, interpolation score and validation/training NRMSE, then replays
selection rules for the first N restarts beside the oracle (the best held-out NRMSE among them:
no rule that cannot see the hold-out does better in spread unless by luck).

  python bench/experiments/restarts_selection_bound.py quick|sparse [--restarts 10] [--jsonl FILE]
  python bench/experiments/restarts_selection_bound.py --replay FILE

Cost: 10 x 10 fits; quick about 3 min, sparse (5 x 8 plan, issue 18's settings) about 8 min on 2 cores.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from restarts_seed_spread import SPARSE_PLAN, holdout_nrmse  # run from bench/experiments

CONFIGS = {"quick": ("quick", 0, {}), "sparse": (SPARSE_PLAN, 1, {"decimate": 4, "max_epochs": 120})}


def collect(name: str, n: int) -> list[dict]:
    from dampnet.rig import generate
    from dampnet.training import restarts as R
    from dampnet.training.pipeline import fit_prepared, prepare_training

    plan, data_seed, kw = CONFIGS[name]
    prep = prepare_training(generate(plan, seed=data_seed), **kw)
    rows = []
    for base in range(10):
        seeds = R.restart_seeds(base, n)
        res = R._run(prep, fit_prepared, [("full", s, None) for s in seeds], 2, lambda i, r: None)
        rows.append({"base": base, "seeds": seeds, "hold": [holdout_nrmse(r["model"], prep.split) for r in res],
                     "score": [r["score"] for r in res], "val": [r["info"].metrics.get("val") for r in res],
                     "train": [r["info"].metrics.get("train") for r in res]})
        print(json.dumps(rows[-1]), flush=True)
    return rows


def replay(rows: list[dict]) -> None:
    from scipy.stats import spearmanr

    print("| N | rule | kept hold-out NRMSE min / median / max | max/min |\n|---|---|---|---|")
    for n in (1, 4, 6, 8, 10):
        rules = {"interpolation score (dampnet)": "score", "validation NRMSE": "val", "oracle (sees the hold-out)": "hold"}
        for label, key in rules.items():
            kept = np.array([r["hold"][int(np.argmin(r[key][:n]))] for r in rows])
            print(f"| {n} | {label} | {kept.min():.4f} / {np.median(kept):.4f} / {kept.max():.4f} | "
                  f"{kept.max() / kept.min():.2f} |")
    h = np.concatenate([r["hold"] for r in rows])
    for key in ("score", "val"):
        print(f"Spearman({key}, hold-out NRMSE) over all fits: {spearmanr(np.concatenate([r[key] for r in rows]), h)[0]:.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("config", nargs="?", choices=sorted(CONFIGS))
    ap.add_argument("--restarts", type=int, default=10)
    ap.add_argument("--jsonl", default=None, help="write the per-fit records here")
    ap.add_argument("--replay", default=None, help="replay the rules on records written by --jsonl")
    args = ap.parse_args()
    if args.replay:
        rows = [json.loads(line) for line in open(args.replay)]
    else:
        if not args.config:
            ap.error("a config (quick or sparse) or --replay FILE")
        import torch

        torch.set_num_threads(1)
        rows = collect(args.config, args.restarts)
        if args.jsonl:
            with open(args.jsonl, "w") as f:
                f.writelines(json.dumps(r) + "\n" for r in rows)
    replay(rows)


if __name__ == "__main__":
    main()
