"""Can the diagnosis see the valves' blow-off knee? (issue 54 item 3, a prototype measured before a
candidate is built.)

A preloaded blow-off valve opens at a fixed pressure, so its knee is at a fixed FORCE per direction
at every control (at a speed that grows with the bypass opening). A network of tanh units rounds
that corner, and its residual is then a narrow band around the knee force. The prototype candidate
tested here has, per direction, a Gaussian bump of the model's own force around a knee force F_k
(theta: F_k as a share of the direction's largest force, on a grid), its odd companion and a hinge
at F_k; it is scored by the diagnosis's own cross-validation and null (dampnet.diagnosis.score).

The data: test_diagnose_hidden's plan (5 frequencies x 8 control levels at 1 kHz), the rig as it is
(with knees) and with the shim stacks opening from zero pressure (no knee); the same network-only
training (LM, every 4th sample, 120 epochs, no control prior). Both ways: a candidate the product
can ship must score on the first and not on the second.

    python bench/experiments/knee_candidate.py          # about 1 minute on 2 cores
    python bench/experiments/knee_candidate.py --real   # and the real MR dampers (no blow-off
                                                        # valve: it must not fire), ~5 minutes

On the real data sets the model is `dampnet train`'s default on bench/real_data.py's training
tests, scored on those tests.
"""

from __future__ import annotations

import sys
from dataclasses import replace

import numpy as np

PLAN = {"name": "diag", "frequencies_hz": [0.25, 0.5, 1.0, 2.0, 3.0], "amplitudes_m": [0.0254],
        "voltages_v": [0.0, 0.5, 1.0, 1.5, 2.25, 3.0, 4.0, 5.0], "sample_rate_hz": 1000.0,
        "samples": 2000, "min_cycles": 2}
TRAIN = {"decimate": 4, "max_epochs": 120, "control_prior": 0.0}
GRID = (0.03, 0.05, 0.07, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.6, 0.8)


def knee_columns(ctx, theta):
    """Per test [rows, 6]: for each direction, a bump exp(-z^2), its odd companion z exp(-z^2) and a
    hinge max(z, 0), z = (|f| - F_k) / (0.15 F_k), f the model's force, F_k = theta x the
    direction's 99th-percentile force."""
    preds = ctx.pred_rows()
    vel = ctx.at_rows("velocity")
    f_all, v_all = np.concatenate(preds), np.concatenate(vel)
    out_cols = []
    peaks = {d: float(np.percentile(np.abs(f_all[np.sign(v_all) == d]), 99)) for d in (1.0, -1.0)}
    for f, v in zip(preds, vel):
        cols = []
        for d in (1.0, -1.0):
            fk = theta * peaks[d]
            z = (np.abs(f) - fk) / (0.15 * fk)
            on = (np.sign(v) == d).astype(float)
            g = np.exp(-z * z)
            cols += [d * on * g, d * on * z * g, d * on * np.maximum(z, 0.0) / 10.0]
        out_cols.append(np.stack(cols, axis=1))
    return out_cols


def score(ds, label: str, grid_min: float, model=None) -> dict:
    from dampnet.diagnosis import score as S
    from dampnet.diagnosis.catalogue import Candidate
    from dampnet.diagnosis.context import build_context
    from dampnet.diagnosis.run import diagnose
    from dampnet.training.pipeline import train_dataset

    if model is None:
        model, _, _ = train_dataset(ds, **TRAIN)
    ctx = build_context(model, ds)
    ctx.notes["included"] = []
    resid = S.reference_residual(ctx)
    Y = [np.column_stack([r, s]) for r, s in zip(resid, S.surrogates(resid, S.N_SURROGATES, 0))]
    folds = S.folds_of(ctx)
    base_cv = S.baseline_cv(ctx, Y, folds)
    grid = [g for g in GRID if g >= grid_min]
    cand = Candidate(id="knee", needs="velocity, the model's force", signature="", columns=knee_columns,
                     grid=lambda ctx: grid)
    res = S.score_candidate(ctx, cand, Y, folds, base_cv)
    d = diagnose(model, ds)
    print(f"{label:8s}: knee prototype score {100 * res['score']:.2f} % (null {100 * res['null_mean']:.2f} +- "
          f"{100 * res['null_sd']:.2f} %, z {res['z']:.1f}), significant {res['significant']}, theta {res['theta']:.2f}; "
          f"the diagnosis as it is: {d['finding']['kind']}: {d['finding']['sentence'][:160]}", flush=True)
    return res


def main(argv=None) -> int:
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--real", action="store_true", help="also the real data sets (about 5 minutes more)")
    ap.add_argument("--grid-min", type=float, default=0.0, help="the smallest knee share tried")
    args = ap.parse_args(argv)
    from dampnet.rig import generate
    from dampnet.rig.truth import TruthParams

    p0 = TruthParams()
    score(generate(PLAN, seed=1), "knees", args.grid_min)
    score(generate(PLAN, seed=1, params=replace(p0, crack_pressure_rebound_pa=0.0,
                                                crack_pressure_compression_pa=0.0)), "no knee", args.grid_min)
    if args.real:
        from pathlib import Path
        sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
        from real_data import split

        from dampnet.data import Dataset
        from dampnet.data.real import load_real
        from dampnet.recipes.training import train

        for name in ("labcontrol", "utfsm"):
            ds = load_real(name)
            _, test = split(name, ds)
            trained = train(ds, holdout_voltage=None, holdout_tests=[t.test_id for t in test], seed=0,
                            algorithm="auto", restarts="auto", workers=1)
            tr = Dataset(tests=list(trained.split.train.tests), source=ds.source, meta=dict(ds.meta))
            score(tr, name, args.grid_min, model=trained.model)
    return 0


if __name__ == "__main__":
    sys.exit(main())
