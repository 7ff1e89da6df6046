"""Which restart score predicts the kept model's held-out error (issue 18; the choice in
dampnet/training/restarts.py).

On the 5-frequency x 8-voltage plan with issue 18's settings (every 4th sample, 120 LM epochs,
2.25 V held out), for base seeds 0-9 x restarts 0..R-1 (the seeds dampnet.training.restarts
derives): the full fit's held-out NRMSE and interpolation score, and for every interior training
level (0.5, 1, 1.5, 3, 4 V) a fit without that level: its NRMSE on the level (the LOLO score)
and on the hold-out. Prints the Spearman rank correlation of each score with the held-out NRMSE
of the model it would keep, and the held-out spread (max/min over the 10 base seeds) of the model
each rule keeps from the first N restarts, beside the oracle (the best held-out NRMSE among them).

  python bench/experiments/restarts_score_study.py [--restarts 8] [--json FILE]

Cost: 10 x R x 6 fits of ~4 s each, on 2 processes (R = 8: about 30 min on 2 idle cores).
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from restarts_seed_spread import SPARSE_PLAN  # noqa: E402  (run from bench/experiments or with it on the path)

TRAIN = {"decimate": 4, "max_epochs": 120}
_STATE = {}


def _init():
    import torch

    from dampnet.rig import generate
    from dampnet.training.pipeline import prepare_training

    torch.set_num_threads(1)
    ds = generate(SPARSE_PLAN, seed=1)
    prep = prepare_training(ds, **TRAIN)
    _STATE.update(prep=prep)


def _holdout(model, split) -> float:
    from dampnet.evaluation.metrics import evaluate_predictions
    from dampnet.predict import predict_force

    tests = split.holdout.tests
    return float(evaluate_predictions(tests, [predict_force(model, t) for t in tests])["overall"]["nrmse"])


def _job(s: int, k: int, level: float | None) -> dict:
    from dampnet.predict import predict_force
    from dampnet.training.metrics import nrmse
    from dampnet.training.pipeline import fit_prepared
    from dampnet.training.restarts import interpolation_score, restart_seeds

    prep = _STATE["prep"]
    seed = restart_seeds(s, k + 1)[k]
    if level is None:
        model, _ = fit_prepared(prep, seed, threads=1)
        return {"s": s, "k": k, "level": None, "hold": _holdout(model, prep.split),
                "interp": interpolation_score(model, prep)["score"]}
    held = np.isclose(prep.level, level, atol=1e-6)
    model, _ = fit_prepared(prep, seed, rows=~held, threads=1)
    return {"s": s, "k": k, "level": level, "lolo": nrmse(predict_force(model, prep.X[held]), prep.force[held]),
            "hold": _holdout(model, prep.split)}


def _spearman(a, b) -> float:
    ra, rb = np.argsort(np.argsort(a)), np.argsort(np.argsort(b))
    return float(np.corrcoef(ra, rb)[0, 1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--restarts", type=int, default=8)
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    from dampnet.training.restarts import training_levels

    _init()
    levels = training_levels(_STATE["prep"])[1:-1]
    jobs = [(s, k, lv) for k in range(args.restarts) for s in range(args.seeds) for lv in [None, *levels]]
    t0 = time.time()
    with ProcessPoolExecutor(args.workers, initializer=_init) as ex:
        rows = list(ex.map(_job, *zip(*jobs)))
    full = {(r["s"], r["k"]): r for r in rows if r["level"] is None}
    lolo = {(r["s"], r["k"], r["level"]): r for r in rows if r["level"] is not None}
    keys = sorted(full)
    hold = [full[c]["hold"] for c in keys]
    ns = sorted({n for n in (4, 6, args.restarts) if n <= args.restarts})
    print(f"{len(rows)} fits in {time.time() - t0:.0f} s, load average {os.getloadavg()[0]:.1f}\n")
    print("| score | Spearman with the kept model's hold-out | " + " | ".join(
        f"kept of {n}: max/min (max)" for n in ns) + " |")
    print("|---|---|" + "---|" * len(ns))

    def rule(name, score, kept_hold):
        rho = _spearman([score(c) for c in keys], [kept_hold(c) for c in keys])
        cells = []
        for n in ns:
            picked = [kept_hold(min([(s, k) for k in range(n)], key=score)) for s in range(args.seeds)]
            cells.append(f"{max(picked) / min(picked):.2f} ({max(picked):.4f})")
        print(f"| {name} | {rho:.2f} | " + " | ".join(cells) + " |")

    rule("oracle (the best hold-out)", lambda c: full[c]["hold"], lambda c: full[c]["hold"])
    rule("interpolation (default)", lambda c: full[c]["interp"], lambda c: full[c]["hold"])
    for n_lv in (1, 2, len(levels)):
        for lvs in itertools.combinations(levels, n_lv):
            if n_lv == 2 and lvs != (levels[0], levels[-1]) and lvs != (1.5, 3.0):
                continue
            name = "LOLO " + ",".join(f"{x:g}" for x in lvs) + " V, full fit kept"
            rule(name, lambda c, lvs=lvs: np.mean([lolo[(*c, lv)]["lolo"] for lv in lvs]), lambda c: full[c]["hold"])
    for lv in levels:
        rule(f"LOLO {lv:g} V, the LOLO fit kept", lambda c, lv=lv: lolo[(*c, lv)]["lolo"],
             lambda c, lv=lv: lolo[(*c, lv)]["hold"])
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f)


if __name__ == "__main__":
    main()
