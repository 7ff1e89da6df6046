"""The model at rest on the real data sets (issue 53 item 3): the error where the damper stands
still (dampnet.evaluation.regions: |v| under 2 % of the test's peak, at most 5 mm/s, for 0.1 s or
longer) with the rest points' three targets (`dampnet train --rest-target`): none (no rest rows:
the training as it is without the thesis's rest points), zero (the thesis's 0 N) and estimated
(the damper's own force at rest fitted near v = 0: the default). The split is bench/real_data.py's
(SPLITS: held-out tests); everything else is `dampnet train`'s default. Prints, per data set,
target and seed: the held-out RMSE [N], the RMSE and bias [N] at rest, the share of time at rest
and the share outside the training envelope with the error there.

    python bench/experiments/at_rest.py                 # labcontrol and utfsm, seeds 0-2 (~30 min on 2 cores)
    python bench/experiments/at_rest.py --seeds 0 --data labcontrol

Measured 2026-12-02: bench/RESULTS.md, "Real dampers", the rest-target table.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from real_data import SPLITS, split  # noqa: E402

from dampnet.data.real import load_real  # noqa: E402
from dampnet.evaluation.report import evaluation  # noqa: E402
from dampnet.outputs import atomic_write_text  # noqa: E402
from dampnet.recipes.training import train  # noqa: E402

TARGETS = ("none", "zero", "estimated")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", nargs="+", default=["labcontrol", "utfsm"], choices=sorted(SPLITS))
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    ap.add_argument("--json", help="write every row here")
    args = ap.parse_args(argv)
    rows = []
    for name in args.data:
        ds = load_real(name)
        _, test = split(name, ds)
        for target in TARGETS:
            for seed in args.seeds:
                t0 = time.perf_counter()
                trained = train(ds, holdout_voltage=None, holdout_tests=[t.test_id for t in test],
                                rest_target=target, seed=seed, algorithm="auto", restarts="auto", workers=1)
                rep = evaluation(trained.model, test, envelope=trained.envelope)
                reg = rep["regions"]
                r, o = reg["at_rest"], reg["outside_envelope"]
                row = {"data": name, "rest_target": target, "seed": seed, "rmse_n": rep["overall"]["rmse_n"],
                       "at_rest": r, "note": reg["note"], "outside": o, "train_s": time.perf_counter() - t0,
                       "rest_force": trained.model.meta.get("rest_force")}
                rows.append(row)
                rest = (f"at rest {100 * r['share_time']:.1f} %: RMSE {r['rmse_n']:.1f} N, bias {r['bias_n']:+.1f} N "
                        f"(force changes {r['force_rms_n']:.1f} N within a test)" if r else reg["note"])
                print(f"{name:10s} {target:9s} seed {seed}: held-out RMSE {row['rmse_n']:.1f} N; {rest}; outside "
                      f"the envelope {100 * o['share_time']:.2f} % (RMSE {o['rmse_n'] or 0:.1f} N there); "
                      f"{row['train_s']:.0f} s", flush=True)
        for target in TARGETS:
            mine = [r for r in rows if r["data"] == name and r["rest_target"] == target]
            med = lambda key: float(np.median([key(r) for r in mine]))  # noqa: E731
            rest = (f"at rest RMSE {med(lambda r: r['at_rest']['rmse_n']):.1f} N, bias "
                    f"{med(lambda r: r['at_rest']['bias_n']):+.1f} N" if mine[0]["at_rest"] else mine[0]["note"])
            print(f"MEDIAN {name:10s} {target:9s}: held-out RMSE {med(lambda r: r['rmse_n']):.1f} N; {rest}")
    if args.json:
        atomic_write_text(args.json, json.dumps(rows, indent=1, default=float), overwrite=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
