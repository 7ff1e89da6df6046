"""Effects added by hand on the real data sets (issue 53): what the catalogue could give beside what
the diagnosis loop names. Trains `dampnet train`'s default on bench/real_data.py's split, diagnoses
it on its training tests (for the effects' parameters), then trains with each given combination
added (as `dampnet train --add A --add B --diagnosis d.json`) and prints the held-out RMSE:

    python bench/experiments/real_additions.py                      # UTFSM, three combinations, ~7 min
    python bench/experiments/real_additions.py --data labcontrol --adds friction,gas_spring

Measured 2026-12-02 (bench/RESULTS.md, "Real dampers"), UTFSM, seed 0: + friction + gas_spring
38.0 N, + friction + compressibility 46.8 N, + friction + gas_spring + compressibility 35.5 N (the
loop, whose diagnosis names friction and thermal only: 47.6 N; the GRU 50.9 N). The diagnosis's
candidates are printed with their scores: on UTFSM gas_spring explains 3.7 % (z 8.7) after
friction (81.0 %) and thermal (5.5 %), under the 5 % minimum (dampnet.diagnosis.score.MIN_SCORE).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from real_data import SPLITS, split  # noqa: E402

DEFAULT_ADDS = ["friction,gas_spring", "friction,compressibility", "friction,gas_spring,compressibility"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default="utfsm", choices=sorted(SPLITS))
    ap.add_argument("--adds", nargs="+", default=DEFAULT_ADDS, help="comma-separated effect ids, one combination each")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    from dampnet.data import Dataset
    from dampnet.data.real import load_real
    from dampnet.diagnosis.run import diagnose
    from dampnet.recipes.loop import holdout_scores
    from dampnet.recipes.training import TrainingRequest, train

    ds = load_real(args.data)
    _, test = split(args.data, ds)
    req = TrainingRequest.of(algorithm="auto", restarts="auto", seed=args.seed,
                             holdout_tests=[t.test_id for t in test], holdout_voltage=None)
    first = train(ds, request=req, workers=1)
    print(f"{args.data} default: held-out RMSE {holdout_scores(first.model, first.split.holdout.tests, first.envelope)['rmse_n']:.1f} N",
          flush=True)
    d = diagnose(first.model, Dataset(tests=list(first.split.train.tests), source=ds.source, meta=dict(ds.meta)),
                 seed=args.seed)
    print(f"  its diagnosis names: {', '.join(d['finding']['effects']) or 'nothing'}", flush=True)
    for c in d["candidates"]:   # each candidate's score, given the effects accepted before it
        if c["testable"]:
            print(f"    {c['effect']}: {100 * c['score']:.1f} % of the residual's variance, z {c['z']:.1f}, "
                  f"{'significant' if c['significant'] else 'not significant'}"
                  + (f", scored after {', '.join(c['given'])}" if c["given"] else ""), flush=True)
    for combo in args.adds:
        add = tuple(e.strip() for e in combo.split(",") if e.strip())
        t0 = time.perf_counter()
        trained = train(ds, request=req.replace(add=add, diagnosis=d).check(), workers=1)
        rmse = holdout_scores(trained.model, trained.split.holdout.tests, trained.envelope)["rmse_n"]
        print(f"  + {' + '.join(add)}: held-out RMSE {rmse:.1f} N ({time.perf_counter() - t0:.0f} s)", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
