"""The derived acceleration (issue 49, item 17): the zero-phase derivative (dampnet.data.derivative,
the default) against the thesis's 20 ms moving average (the training option acceleration_window=0.02).

  python bench/experiments/acceleration.py [--seeds 2]      # about 6 min on 2 cores

Three measurements, printed:
  1. sines: the worst error over the whole test, as % of the analytic acceleration's peak, of
     1, 8 and 20 Hz sines at 1 and 5 kHz (2.3 cycles, at least 2.3 s; 8 phases), from the velocity;
  2. rig: the pooled NRMSE against the rig's true acceleration (quick plan seed 3, thesis plan seed 3);
  3. loop: a model trained on the road plan of tests/python/test_simulate.py (LM, 200 epochs, the seed)
     with each acceleration, in the quarter car on the thesis's rough road at 10, 20 and 30 m/s,
     passive high and low, on-off skyhook, unfiltered continuous skyhook: the body acceleration's
     RMS against the truth damper's, in %. The loop feeds a model the true acceleration: a model
     trained on an acceleration flattened by the moving average sees another quantity there.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests" / "python"))


def sines() -> None:
    from dampnet.data import DynoTest
    from dampnet.data.preprocess import acceleration_of

    for window, name in ((None, "zero-phase"), (0.02, "20 ms moving average")):
        row = []
        for fs in (1000.0, 5000.0):
            for f in (1.0, 8.0, 20.0):
                t = np.arange(int(max(2.3 / f, 2.3) * fs)) / fs
                w0 = 2 * np.pi * f
                worst = 0.0
                for ph in np.linspace(0, 2 * np.pi, 8, endpoint=False):
                    test = DynoTest("s", t, {"velocity": np.cos(w0 * t + ph), "force": t, "voltage": 0 * t})
                    worst = max(worst, float(np.max(np.abs(acceleration_of(test, window) + w0 * np.sin(w0 * t + ph)))) / w0)
                row.append(f"{fs / 1000:g} kHz {f:g} Hz {100 * worst:.2f} %")
        print(f"sines, {name}: " + ", ".join(row))


def rig() -> None:
    from dampnet.data.preprocess import acceleration_error
    from dampnet.rig import generate

    for plan in ("quick", "thesis"):
        ds = generate(plan, seed=3, truth_channels=True)
        truth = [t.channels["true_acceleration"] for t in ds.tests]
        print(f"rig {plan} plan, pooled NRMSE: zero-phase {acceleration_error(ds.tests, truth, None):.4f}, "
              f"20 ms moving average {acceleration_error(ds.tests, truth, 0.02):.4f}")


def loop(seeds: int) -> None:
    from test_simulate import ROAD_PLAN

    from dampnet.rig import Plan, generate
    from dampnet.sim.calibration import continuous_skyhook, damping_levels, semi_active
    from dampnet.sim.dampers import neural_spec, truth_spec
    from dampnet.sim.quarter_car.runs import simulate
    from dampnet.sim.roads import thesis_rough_road
    from dampnet.sim.vehicle import Controller
    from dampnet.training.pipeline import train_dataset

    truth, road = truth_spec(), thesis_rough_road()
    cont = continuous_skyhook(truth, damping_levels(truth))
    laws = {"high": Controller(kind="passive", u_passive=0.0), "low": Controller(kind="passive", u_passive=5.0),
            "onoff": semi_active("skyhook_onoff", damping_levels(truth)), "cont_unf": replace(cont, u_tau_s=0.0)}
    cases = [(s, k) for s in (10.0, 20.0, 30.0) for k in laws]
    ref = {c: simulate(truth, road, c[0], laws[c[1]])["metrics"]["acc_rms_m_s2"] for c in cases}
    for seed in range(seeds):
        ds = generate(Plan(**ROAD_PLAN), seed=seed)
        for window, name in ((None, "zero-phase"), (0.02, "20 ms moving average")):
            for t in ds.tests:
                t.channels.pop("acceleration", None)
                t.meta.pop("acceleration_derived", None)
            model, _, _ = train_dataset(ds, algorithm="lm", max_epochs=200, seed=seed, holdout_voltage=None,
                                        acceleration_window=window)
            n = neural_spec(model)
            err = {c: 100 * (simulate(n, road, c[0], laws[c[1]])["metrics"]["acc_rms_m_s2"] - ref[c]) / ref[c] for c in cases}
            print(f"loop seed {seed}, {name}: mean |error| {np.mean(np.abs(list(err.values()))):.2f} %; "
                  + ", ".join(f"{s:g} m/s {k} {e:+.2f}" for (s, k), e in err.items()), flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=2)
    a = ap.parse_args()
    sines()
    rig()
    loop(a.seeds)


if __name__ == "__main__":
    main()
