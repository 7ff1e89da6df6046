"""Planning dyno tests on the thesis plan (issue 20; bench/RESULTS.md, "Planning dyno tests").

A model trained on the rig's thesis plan (Table 2: 1-inch sines at 0.25-3 Hz x 15 voltages), its
quarter-car impulse against the truth damper (sprung-acceleration RMS, low and high damping) and
the share of the run outside its training envelope; `dampnet.campaign.planning` proposes BUDGET tests for
the impulse, the rig runs them, the model is retrained on the thesis plan plus those tests, and
the impulse is run again. Usage:
    python bench/plan_tests_thesis.py [--budgets 4,6,8] [--seeds 0,1,2] [--epochs 200] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import time

from dampnet.campaign import planning
from dampnet.data.types import Dataset
from dampnet.envelope import envelope_of
from dampnet.rig import generate
from dampnet.sim.calibration import damping_levels
from dampnet.sim.dampers import neural_spec, truth_spec
from dampnet.sim.roads import impulse
from dampnet.sim.quarter_car.runs import simulate
from dampnet.sim.vehicle import Controller
from dampnet.training.pipeline import train_dataset


def impulse_runs(spec):
    lv = damping_levels(spec)
    return {k: simulate(spec, impulse(), None, Controller(kind="passive", u_passive=lv[k])) for k in ("low", "high")}


def score(model, env, truth):
    runs = impulse_runs(neural_spec(model, envelope=env))
    return {k: dict(error=r["metrics"]["acc_rms_m_s2"] / truth[k]["metrics"]["acc_rms_m_s2"] - 1,
                    outside=r["coverage"]["outside"]["share_time"]) for k, r in runs.items()}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--budgets", default="4,6,8")
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--epochs", type=int, default=200)
    ap.add_argument("--json")
    a = ap.parse_args()
    truth = impulse_runs(truth_spec())
    ds = generate("thesis", seed=0)
    rows = []
    for seed in map(int, a.seeds.split(",")):
        t0 = time.perf_counter()
        model, _, split = train_dataset(ds, max_epochs=a.epochs, seed=seed)
        env = envelope_of(model, split)
        before = score(model, env, truth)
        t_train = time.perf_counter() - t0
        print(f"seed {seed}: trained in {t_train:.1f} s; impulse before: " + ", ".join(
            f"{k} {100 * v['error']:+.1f} % ({100 * v['outside']:.1f} % outside)" for k, v in before.items()), flush=True)
        for budget in map(int, a.budgets.split(",")):
            res = planning.plan_tests(model, env, planning.load_runs(model, env, ["impulse"]), budget)
            extra = generate(planning.rig_plan(res), seed=1)
            for t in extra.tests:
                t.test_id = "X" + t.test_id
            both = Dataset(tests=ds.tests + extra.tests, source="thesis + planned", meta=ds.meta)
            m2, _, s2 = train_dataset(both, max_epochs=a.epochs, seed=seed)
            after = score(m2, envelope_of(m2, s2), truth)
            row = dict(seed=seed, budget=budget, before=before, after=after, share_covered=res["share_covered"],
                       share_covered_by_training=res["share_covered_by_training"],
                       tests=[(p["frequency_hz"], p["amplitude_m"], p["control"]) for p in res["tests"]])
            rows.append(row)
            print(f"  budget {budget}: covered {100 * res['share_covered_by_training']:.0f} -> "
                  f"{100 * res['share_covered']:.0f} %; tests {row['tests']}; impulse after: " + ", ".join(
                      f"{k} {100 * v['error']:+.1f} % ({100 * v['outside']:.1f} % outside)" for k, v in after.items()),
                  flush=True)
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
