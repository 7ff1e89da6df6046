"""The valve term fitted with the network, not only before it (issue 54 item 2: "fit the term first,
then the network on what it leaves (or jointly, if that is better: measure both)").

Today's hybrid fits the valve term alone to the force, then the network to what it leaves ("first").
This script measures a joint fit by block coordinate descent from there, on the rig's thesis plan
(rig seed 0, 2.25 V held out), `dampnet.train`'s default otherwise (algorithm auto, restarts 1):

  round 0   the hybrid as trained today (valve fitted first)
  round k   the valve refitted (bounded least squares, all 10 parameters, from round k-1's) to
            what round k-1's network leaves of the force on the training rows, then the network
            trained again from round k-1's weights (a warm start) on what the new valve leaves

Each round's validation NRMSE (the rows the fit held back: same split every round) and held-out
RMSE over the load cell's noise floor are printed, one JSON line a round. Not a product feature.

  python bench/experiments/valve_joint.py [--seeds 0,1] [--rounds 3]

About 2-4 minutes a round on an idle 2-core machine.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np


def refit_valve(p0, v, u, target):
    """The valve's 10 parameters fitted to `target` [N] from p0 (dampnet.terms' own sample
    evaluation and Jacobian, the bounds of `_fit_valve`)."""
    from scipy.optimize import least_squares

    from dampnet.terms import VALVE_K_D_MAX, _ValveSamples

    ok = np.isfinite(v) & np.isfinite(u) & np.isfinite(target)
    v, u, target = v[ok], u[ok], target[ok]
    samples = _ValveSamples(v, u)
    lower = np.array([1e-6, 0, 0, 1e-6, 0, 0, 0, 0, 0, 0], float)
    upper = np.array([np.inf] * 8 + [VALVE_K_D_MAX] * 2)
    sol = least_squares(lambda p: samples.force(p) - target, np.clip(np.asarray(p0, float), lower, upper),
                        jac=samples.jacobian, bounds=(lower, upper), method="trf", x_scale="jac", max_nfev=200,
                        tr_solver="lsmr")
    return [float(a) for a in np.clip(sol.x, lower, upper)], float(np.sqrt(2 * sol.cost / v.size))


def summary(trained, seed: int, rnd: int, t0: float, extra: dict) -> dict:
    m = trained.metrics
    hv = m.get("noise_floor", {}).get("holdout_vs_floor", {})
    per = {f"{r['frequency_hz']:g}": round(r["ratio"], 2) for r in hv.get("per_frequency", [])}
    return {"seed": seed, "round": rnd, "val_nrmse": round(m["training"]["nrmse"]["val"], 6),
            "holdout_nrmse": round(m["holdout"]["overall"]["nrmse"], 5),
            "floor_ratio": round(hv.get("ratio", float("nan")), 3),
            "worst_frequency_ratio": max(per.values()) if per else None,
            "valve": [round(x, 5) for x in trained.model.terms[0]["params"]],
            "time_s": round(time.perf_counter() - t0, 1), **extra}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="0,1", help="comma-separated training seeds")
    ap.add_argument("--rounds", type=int, default=3, help="refits after the first hybrid")
    ap.add_argument("--plan", default="thesis", help="the rig's plan")
    a = ap.parse_args()
    import dampnet
    from dampnet.rig import generate
    from dampnet.terms import terms_force
    from dampnet.training.pipeline import prepare_training

    ds = generate(a.plan, seed=0)
    options = {"algorithm": "auto", "restarts": 1, "holdout_voltage": 2.25}
    for seed in (int(s) for s in a.seeds.split(",")):
        t0 = time.perf_counter()
        trained = dampnet.train(ds, seed=seed, terms=[{"kind": "valve"}], **options)
        print(json.dumps(summary(trained, seed, 0, t0, {})), flush=True)
        prep = prepare_training(ds, terms=[{"kind": "valve"}], holdout_voltage=2.25)
        for rnd in range(1, a.rounds + 1):
            t0 = time.perf_counter()
            model = trained.model
            net = model.predict(prep.X)  # the network's force on the training rows, without the term
            others = terms_force(model.terms[1:], prep.xd, prep.v, u=prep.u)
            p, rms = refit_valve(model.terms[0]["params"], prep.v, prep.u, prep.force - net - others)
            terms = [{"kind": "valve", "params": p}, *model.terms[1:]]
            trained = dampnet.train(ds, seed=seed, terms=terms, init=model, **options)
            print(json.dumps(summary(trained, seed, rnd, t0, {"valve_refit_rms_n": round(rms, 2)})), flush=True)


if __name__ == "__main__":
    main()
