"""Train on the thesis's sines, validate on a replayed rough road, plan the missing tests, retrain.

The story of a damper lab that validates beyond sines (issue 34), on the virtual dyno:

  1. the thesis's dyno sines (Table 2: 12 frequencies 0.25-3 Hz x 15 voltages, 1-inch amplitude)
  2. track replay: the damper stroke of a quarter car over the thesis's rough road at 20 m/s under
     on-off skyhook, played on the rig like a drive file (dampnet rig --replay); and, never used
     for planning, a replay of an ISO 8608 class C road
  3. the model trained on the sines, validated on the replays: error, and the time the replay
     spends outside the model's training envelope
  4. dampnet plan-tests on the rough-road replay: the dyno sines that cover its missing region
  5. those sines run on the rig, the model retrained on sines + planned tests, validated again

    python examples/python/sines_to_road_replay.py [--quick] [--out results.json]

--quick runs the 9-test quick plan and short replays (about a minute); the full run trains on
the 180 thesis tests (several minutes on 2 cores). Numbers: RESULTS.md, "Sines to road replay".
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

import dampnet
from dampnet.data import merge_datasets
from dampnet.envelope.coverage import coverage
from dampnet.evaluation.metrics import evaluate_model
from dampnet.features import feature_matrix
from dampnet.campaign.planning import RunInputs, plan_tests, rig_plan
from dampnet.predict import predict_force
from dampnet.campaign.replay import replay_tests


def validate(trained, replays) -> dict:
    """Error and coverage of a trained model on each replay test."""
    model, env = trained.model, trained.envelope
    rep = evaluate_model(lambda t: predict_force(model, t), replays.tests)
    out = {}
    for t, row in zip(replays.tests, rep["per_test"]):
        X = feature_matrix([t], model.features, model.feature_params)
        cov = coverage(model, X, env, t=t.time)
        out[t.test_id] = {"nrmse": row["nrmse"], "rmse_n": row["rmse_n"], "max_abs_error_n": row["max_abs_error_n"],
                          "share_time_outside": cov["outside"]["share_time"],
                          "outside_mostly": cov["outside"]["mostly"]}
    return out


def required_runs(trained, replays) -> list[RunInputs]:
    """The replays' damper inputs as plan-tests' required runs (each sample's duration its dt)."""
    runs = []
    for t in replays.tests:
        X = feature_matrix([t], trained.model.features, trained.model.feature_params)
        runs.append(RunInputs(t.test_id, X, np.full(len(t), t.dt), "dampnet rig --replay"))
    return runs


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the quick plan and short replays (about a minute)")
    ap.add_argument("--budget", type=int, default=6, help="dyno tests to plan (default 6)")
    ap.add_argument("--out", default=None, help="write the numbers as JSON to this file (a new file unless --force)")
    ap.add_argument("--force", action="store_true", help="replace --out if it exists")
    args = ap.parse_args(argv)
    if args.out:   # before the minutes of work, not after
        import os
        from pathlib import Path

        out = Path(args.out)
        parent = out.parent
        if out.is_dir():
            ap.error(f"--out {args.out}: is a directory: expected a file name")
        if out.exists() and not args.force:
            ap.error(f"--out {args.out}: exists; give --force to replace it")
        if not parent.is_dir() or not os.access(parent, os.W_OK):
            ap.error(f"--out {args.out}: cannot write into {parent} (not a writable directory)")
    t0 = time.perf_counter()
    plan = "quick" if args.quick else "thesis"
    duration = 2.0 if args.quick else 6.0
    train_opts = dict(restarts=1, seed=0, max_epochs=100 if args.quick else 1000)

    sines = dampnet.rig.generate(plan, seed=0)
    planned_on = replay_tests(["rough"], speed_m_s=20.0, law="skyhook_onoff", duration_s=duration, seed=0)
    unseen = replay_tests(["iso:C"], speed_m_s=20.0, law="skyhook_onoff", duration_s=duration, seed=10)
    print(f"1-2. {len(sines)} sine tests ({plan} plan); replays: {planned_on.test_ids[0]}, {unseen.test_ids[0]} "
          f"({duration:g} s each)", flush=True)

    first = dampnet.train(sines, **train_opts)
    before = {**validate(first, planned_on), **validate(first, unseen)}
    print("3. trained on the sines only:")
    for k, v in before.items():
        print(f"   {k}: NRMSE {v['nrmse']:.4f}, max |error| {v['max_abs_error_n']:.0f} N, "
              f"{100 * v['share_time_outside']:.1f} % of the time outside the training envelope", flush=True)

    proposal = plan_tests(first.model, first.envelope, required_runs(first, planned_on), args.budget)
    print(f"4. plan-tests on {planned_on.test_ids[0]}: " + "; ".join(
        f"{p['frequency_hz']:g} Hz x {1e3 * p['amplitude_m']:g} mm at {p['control']:g} V" for p in proposal["tests"]))
    extra = dampnet.rig.generate(rig_plan(proposal, "replay-plan"), seed=1)
    for t in extra.tests:
        t.test_id = f"P{t.test_id}"
    second = dampnet.train(merge_datasets([sines, extra]), **train_opts)
    after = {**validate(second, planned_on), **validate(second, unseen)}
    print(f"5. retrained on the sines + {len(extra)} planned tests:")
    for k, v in after.items():
        print(f"   {k}: NRMSE {v['nrmse']:.4f} (was {before[k]['nrmse']:.4f}), max |error| "
              f"{v['max_abs_error_n']:.0f} N (was {before[k]['max_abs_error_n']:.0f}), "
              f"{100 * v['share_time_outside']:.1f} % outside (was {100 * before[k]['share_time_outside']:.1f} %)")
    result = {"plan": plan, "replay_duration_s": duration, "train": train_opts,
              "planned_tests": [{k: p[k] for k in ("frequency_hz", "amplitude_m", "control")} for p in proposal["tests"]],
              "before": before, "after": after, "elapsed_s": round(time.perf_counter() - t0, 1)}
    print(f"done in {result['elapsed_s']:.0f} s")
    if args.out:
        from dampnet.outputs import write_json

        write_json(args.out, result, overwrite=args.force)
    return 0


if __name__ == "__main__":
    sys.exit(main())
