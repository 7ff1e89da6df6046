"""The derived acceleration on the real data sets: neither records an acceleration, so the model's
acceleration input is derived from the velocity (dampnet.data.derivative). Since the zero-phase
derivative became the default (a Butterworth low-pass at ACCELERATION_CUTOFF_HZ = 40 Hz, at most a
quarter of the sample rate, then 4th-order differences), the default model on both real data sets
is worse than with the thesis's 20 ms moving average it replaced, although the rig measured the
zero-phase derivative better. This trains `dampnet train`'s default on bench/real_data.py's split
(seed 0) with the acceleration derived each way and prints the held-out RMSE and the error at rest:

    python bench/experiments/real_acceleration.py                 # both data sets, ~15 min on 2 cores
    python bench/experiments/real_acceleration.py --data labcontrol

Measured 2026-12-02 (bench/RESULTS.md, "Real dampers"), held-out RMSE [N]:
  labcontrol (100 Hz, sines up to 1.2 Hz): zero-phase 40 Hz (25 Hz: capped at a quarter of the
      rate) 47.9; 20 Hz 41.4; 10 Hz 37.1; 5 Hz 37.0; moving average 20 ms 40.2
  utfsm (1 kHz, sines up to 5 Hz): zero-phase 40 Hz 57.1; 20 Hz 58.0; 10 Hz 56.3; moving average
      20 ms 53.4 (5 Hz not run: a 5 Hz test's own motion would be cut)
No single cut-off is best on both: the default is left as it is, and this is the evidence for
whoever changes it.
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
