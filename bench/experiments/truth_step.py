"""The truth damper's per-sample step (TruthDamper.step, Python floats) against its vectorised law
on a one-sample array (what the step ran per sample before: `_context` and `base_force` on
1-element arrays), and the full-vehicle study the demo runs with it.

  python bench/experiments/truth_step.py          # about 40 s on 2 cores

Prints the median over 5 repeats of 20,000 calls each [us per call], without effects and with
the gas spring, and the wall time of the demo's full-vehicle study (default model and truth
damper, bounce sweep at 1 oct/s and two lane changes, low, high and skyhook damping).
"""

from __future__ import annotations

import statistics
import time
import timeit

import numpy as np


def per_call_us(fn, n: int = 20_000, repeats: int = 5) -> float:
    return 1e6 * statistics.median(timeit.repeat(fn, number=n, repeat=repeats)) / n


def main() -> None:
    from dampnet.rig.truth import TruthDamper, TruthParams, _context, base_force

    p = TruthParams()

    def vectorised_one_sample():
        ctx = _context(np.array([0.01]), np.array([0.2]), np.array([2.0]), None, 1e-3, p)
        ctx.v_h = ctx.v
        return float(base_force(ctx)[0])

    print(f"vectorised law on one sample: {per_call_us(vectorised_one_sample):.1f} us")
    for effects in ((), ("gas_spring",)):
        d = TruthDamper(effects=effects)
        print(f"TruthDamper.step {list(effects) or 'no effects'}: "
              f"{per_call_us(lambda: d.step(1e-3, 0.01, 0.2, 2.0)):.1f} us")

    from dampnet.recipes import maneuvers
    from dampnet.sim.dampers import load_spec, truth_spec

    specs = [load_spec("default"), truth_spec(["gas_spring"], "truth")]
    tests = {"bsst_heave": maneuvers.build("bsst", 1e-3, {"bsst_rate_oct_s": 1.0}),
             "dlc_80": maneuvers.build("dlc", 1e-3, {"speed_kmh": 80.0}), "dlc": maneuvers.build("dlc", 1e-3)}
    t0 = time.perf_counter()
    maneuvers.run_study(specs, tests, damping=("low", "high", "skyhook"))
    print(f"full-vehicle study (default model and truth, 3 tests x 3 dampings): {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
