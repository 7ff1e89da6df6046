"""The derived acceleration on the real data sets: neither records an acceleration, so the model's
acceleration input is derived from the velocity (dampnet.data.derivative). This trains `dampnet
train`'s default on bench/real_data.py's split with the acceleration derived each way and prints the
held-out RMSE and the error at rest:

    python bench/experiments/real_acceleration.py                       # every way, seed 0, ~15 min on 2 cores
    python bench/experiments/real_acceleration.py --data labcontrol --ways content 40 --seeds 0 1 2

Ways: content = each test's own cut-off (8x the frequency below which 90 % of its velocity's power
lies, 1-40 Hz; the default since issue 53), 40/20/10/5 = a fixed zero-phase cut-off [Hz] (at most
a quarter of the rate: 25 Hz at Labcontrol's 100 Hz), ma = the thesis's 20 ms moving average.

Measured 2026-12-02 (bench/RESULTS.md, "Real dampers"), held-out RMSE [N], seeds 0 / 1 / 2 (median):
  labcontrol (100 Hz, sines up to 1.2 Hz): each test's 37.4 / 44.0 / 35.5 (37.4); fixed 40 Hz
      47.9 / 43.5 / 41.5 (43.5); 10 Hz 37.1 / 40.6 / 37.6 (37.6); moving average 40.2 / 39.3 /
      40.5 (40.2); seed 0 only: 20 Hz 41.4, 5 Hz 37.0
  utfsm (200 Hz to 1 kHz, sines 0.1 to 5 Hz): each test's 55.9 / 50.2 / 53.7 (53.7); fixed 40 Hz
      57.1 / 55.7 / 53.7 (55.7); 10 Hz 56.3 / 53.2 / 56.0 (56.0); moving average 53.4 / 53.7 / 54.9
      (53.7); seed 0 only: 20 Hz 58.0
Each test's own cut-off is the best or equal best median on both (a fixed 10 Hz suits Labcontrol's
slow sines, not UTFSM's 5 Hz ones), and on the rig it halves the acceleration's error.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from real_data import SPLITS, split  # noqa: E402

from dampnet.data import derivative  # noqa: E402
from dampnet.data.real import load_real  # noqa: E402
from dampnet.evaluation.report import evaluation  # noqa: E402
from dampnet.recipes.training import train  # noqa: E402

#: each way of deriving the acceleration: name -> (label, the zero-phase cut-off [Hz]: a number, or
#: "content" for each test's own (the default), the moving-average window [s] or None)
WAYS = {"content": ("zero-phase, each test's cut-off (the default)", "content", None),
        "40": ("zero-phase 40 Hz", 40.0, None), "20": ("zero-phase 20 Hz", 20.0, None),
        "10": ("zero-phase 10 Hz", 10.0, None), "5": ("zero-phase 5 Hz", 5.0, None),
        "ma": ("moving average 20 ms", None, 0.02)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", nargs="+", default=["labcontrol", "utfsm"], choices=sorted(SPLITS))
    ap.add_argument("--ways", nargs="+", default=list(WAYS), choices=list(WAYS))
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    args = ap.parse_args(argv)
    default_cutoff, default_factor = derivative.ACCELERATION_CUTOFF_HZ, derivative.CONTENT_FACTOR
    for name, seed, way in ((n, s, w) for n in args.data for s in args.seeds for w in args.ways):
        label, cutoff_hz, window = WAYS[way]
        if cutoff_hz != "content":      # a fixed cut-off (or none, for the moving average)
            derivative.ACCELERATION_CUTOFF_HZ, derivative.CONTENT_FACTOR = cutoff_hz or default_cutoff, None
        try:
            ds = load_real(name)
            _, test = split(name, ds)
            t0 = time.perf_counter()
            trained = train(ds, holdout_voltage=None, holdout_tests=[t.test_id for t in test], seed=seed,
                            algorithm="auto", restarts="auto", workers=1, acceleration_window=window)
            rep = evaluation(trained.model, test, envelope=trained.envelope)
        finally:
            derivative.ACCELERATION_CUTOFF_HZ, derivative.CONTENT_FACTOR = default_cutoff, default_factor
        rest = rep["regions"]["at_rest"]
        print(f"{name:10s} seed {seed} {label:45s}: held-out RMSE {rep['overall']['rmse_n']:.1f} N, at rest "
              + (f"{rest['rmse_n']:.1f} N" if rest else "not measured") + f" ({time.perf_counter() - t0:.0f} s)",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
