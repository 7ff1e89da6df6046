"""The parallel restarts' start-up and end, apart from their fits (issue 33, bench/LOG.md "1 V with
two restarts, the restarts' start-up, and where issue 33 ends").

`dampnet.train` on the thesis plan (2.25 V held out) with 2 restarts in 2 worker processes of a few
epochs each, so that what is not fitting shows: the call's wall time, the restart stage's, and each
restart's own fit and score. Run it in two checkouts (e.g. 8e5cdfd, before the samples went through a
file, and this one), interleaved, and compare the wall times:

  python bench/experiments/restart_startup.py [--runs 3] [--epochs 20]
"""

from __future__ import annotations

import argparse
import json
import time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--epochs", type=int, default=20)
    args = ap.parse_args()
    import dampnet
    from dampnet.rig import generate

    ds = generate("thesis", seed=0)
    for _ in range(args.runs):
        t0 = time.perf_counter()
        trained = dampnet.train(ds, seed=0, holdout_voltage=2.25, algorithm="auto", restarts=2, workers=2,
                                max_epochs=args.epochs)
        rs = trained.metrics["training"]["restarts"]
        print(json.dumps({"wall_s": round(time.perf_counter() - t0, 2), "restarts_s": rs["time_s"],
                          "fits_s": [r["time_s"] for r in rs["runs"]]}), flush=True)


if __name__ == "__main__":
    main()
