"""What closes the gap between the held-out error and the noise floor inside the envelope (issue 20)?

The demo's data (`dampnet demo --quick`: 4 frequencies x 8 voltages with the gas spring) and its
improved model's inputs (velocity, acceleration, voltage, displacement), 2.25 V held out. Each
variant trains with seeds 0-2 (restarts=1, so the variant and not the selection is measured) and
reports the held-out RMSE over the sensor noise's RMS (dampnet.training.pipeline.holdout_vs_noise_floor),
overall and per frequency: median over the seeds.

  python bench/experiments/noise_floor_gap.py [--seeds 3] [--json FILE]
  python bench/experiments/noise_floor_gap.py --where     # where the rest of the gap is (below)
  python bench/experiments/noise_floor_gap.py --only NAME --seeds S --ensemble K   # means of K models

--ensemble K: the seeds' models in disjoint groups of K consecutive seeds (S // K groups), each
group's predictions averaged: whether what is left is the seeds' scatter (averaging helps) or a
bias they share (it does not); the ratio of each group's mean and their median. The mean of K
one-hidden-layer networks with the same input and output scaling is one network with their
hidden layers side by side and output weights divided by K, so an ensemble that fits the
runtime's DN_MAX_HIDDEN (64) is deployable as it is.

--distill: a deployable single network taught by an ensemble. K teacher models of a variant
(seeds 0..K-1, --teachers K, kept in --cache DIR so a second run reuses them) are averaged on the
training samples; one student network (--student-hidden H, at most the runtime's 64) is trained
by the same variant on those averaged forces instead of the measured ones (the seeds' scatter and
much of the sensor noise averaged out of its targets), seeds --seeds; each is scored on the
hold-out's measured force as above, beside the teachers alone and their mean.

  python bench/experiments/noise_floor_gap.py --distill NAME --teachers 6 --student-hidden 60 --seeds 3

--where: for the best variant (compressibility and friction added, 45 hidden, max_fail 20, 10 ms
window), seeds 0-1, the ratio on the hold-out beside the ratio on the model's own training tests at
full rate (interpolation or fit?), and the floor the *input* noise adds: the truth damper evaluated
on the measured displacement, velocity and voltage of the hold-out tests against the true force.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

VARIANTS = {
    "demo (150 LM epochs, 20 ms window, 30 hidden)": {"max_epochs": 150},
    "400 epochs": {"max_epochs": 400},
    "1000 epochs": {"max_epochs": 1000},
    "1000 epochs, max_fail 20": {"max_epochs": 1000, "max_fail": 20},
    "acceleration window 10 ms": {"max_epochs": 150, "acceleration_window": 0.010},
    "acceleration window 40 ms": {"max_epochs": 150, "acceleration_window": 0.040},
    "20 hidden": {"max_epochs": 150, "hidden": (20,)},
    "45 hidden": {"max_epochs": 150, "hidden": (45,)},
    "45 hidden, 400 epochs": {"max_epochs": 400, "hidden": (45,)},
    "no decimation (5 kHz)": {"max_epochs": 150, "decimate": 1},
    "compressibility added (velocity lag)": {"max_epochs": 150, "add": "compressibility"},
    "compressibility added, 45 hidden, max_fail 20": {"max_epochs": 1000, "max_fail": 20, "hidden": (45,),
                                                       "add": "compressibility"},
    "compressibility and friction added, 45 hidden, max_fail 20": {"max_epochs": 1000, "max_fail": 20,
                                                                    "hidden": (45,),
                                                                    "add": "compressibility,friction"},
    "compressibility added, 60 hidden, max_fail 20": {"max_epochs": 1000, "max_fail": 20, "hidden": (60,),
                                                       "add": "compressibility"},
    "compressibility added, 25-25 hidden, max_fail 20": {"max_epochs": 1000, "max_fail": 20, "hidden": (25, 25),
                                                          "add": "compressibility"},
    "45 hidden, max_fail 20, window 10 ms": {"max_epochs": 1000, "max_fail": 20, "hidden": (45,),
                                              "acceleration_window": 0.010},
    # Bayesian regularisation (MATLAB's trainbr: no early stopping, the evidence sets the weight decay)
    "BR 300 epochs, compressibility and friction added, 45 hidden": {"algorithm": "br", "max_epochs": 300,
                                                                      "hidden": (45,),
                                                                      "add": "compressibility,friction"},
    "BR 300 epochs, compressibility and friction added, 30 hidden": {"algorithm": "br", "max_epochs": 300,
                                                                      "add": "compressibility,friction"},
    "BR 300 epochs, compressibility and friction added, 60 hidden": {"algorithm": "br", "max_epochs": 300,
                                                                      "hidden": (60,),
                                                                      "add": "compressibility,friction"},
    "BR 1000 epochs, compressibility and friction added, 45 hidden, window 10 ms": {
        "algorithm": "br", "max_epochs": 1000, "hidden": (45,), "acceleration_window": 0.010,
        "add": "compressibility,friction"},
    "BR 1000 epochs, compressibility and friction added, 45 hidden": {
        "algorithm": "br", "max_epochs": 1000, "hidden": (45,), "add": "compressibility,friction"},
    "BR 2000 epochs, compressibility and friction added, 45 hidden, window 10 ms": {
        "algorithm": "br", "max_epochs": 2000, "hidden": (45,), "acceleration_window": 0.010,
        "add": "compressibility,friction"},
    "BR 1000 epochs, compressibility and friction added, 20 hidden, window 10 ms": {
        "algorithm": "br", "max_epochs": 1000, "hidden": (20,), "acceleration_window": 0.010,
        "add": "compressibility,friction"},
    "BR 1000 epochs, compressibility and friction added, 30 hidden, window 10 ms": {
        "algorithm": "br", "max_epochs": 1000, "hidden": (30,), "acceleration_window": 0.010,
        "add": "compressibility,friction"},
    # the truth damper's force depends on displacement, velocity (and its lag) and the control, not on
    # the acceleration: is the derived acceleration's noise (1 mm/s velocity noise differentiated)
    # part of what is left?
    "BR 1000 epochs, compressibility and friction added, 30 hidden, no acceleration input": {
        "algorithm": "br", "max_epochs": 1000, "hidden": (30,), "add": "compressibility,friction",
        "drop": "acceleration"},
    "BR 1000 epochs, compressibility and friction added, 45 hidden, no acceleration input": {
        "algorithm": "br", "max_epochs": 1000, "hidden": (45,), "add": "compressibility,friction",
        "drop": "acceleration"},
    # what `dampnet train --restarts 6 --average 2` does: the two best-scored of six restarts as one
    # 60-hidden network (the restarts' own seeds, derived from each seed)
    "BR 1000 epochs, compressibility and friction added, 30 hidden, window 10 ms, 6 restarts, best 2 averaged": {
        "algorithm": "br", "max_epochs": 1000, "hidden": (30,), "acceleration_window": 0.010,
        "add": "compressibility,friction", "restarts": 6, "average": 2},
    "BR 1000 epochs, compressibility and friction added, 60 hidden, window 10 ms": {
        "algorithm": "br", "max_epochs": 1000, "hidden": (60,), "acceleration_window": 0.010,
        "add": "compressibility,friction"},
}


def where() -> None:
    from dampnet.demo.run import HIDDEN_EFFECT, QUICK_PLAN
    from dampnet.evaluation.metrics import evaluate_predictions
    from dampnet.features import default_features
    from dampnet.predict import predict_force
    from dampnet.rig import generate
    from dampnet.rig.truth import truth_force
    from dampnet.training.pipeline import apply_additions, model_metrics, train_dataset

    ds = generate(QUICK_PLAN, effects=[HIDDEN_EFFECT], seed=0, progress=False, truth_channels=True)
    settings, _ = apply_additions({"features": default_features(ds)}, ds, HIDDEN_EFFECT)
    for effect in ("compressibility", "friction"):
        settings = apply_additions(settings, ds, effect)[0]
    for seed in range(2):
        model, info, split = train_dataset(ds, algorithm="lm", seed=seed, max_epochs=1000, max_fail=20, hidden=(45,),
                                           acceleration_window=0.010, **settings)
        m = model_metrics(model, info, split, lookup=False)
        train = split.train.tests
        ev = evaluate_predictions(train, [predict_force(model, t) for t in train])
        print(f"seed {seed}: hold-out {m['noise_floor']['holdout_vs_floor']['ratio']:.2f}x the floor, its own "
              f"training tests {ev['overall']['rmse_n'] / m['noise_floor']['rmse_n']:.2f}x", flush=True)
    sigma = ds.meta["noise"]["force_n"]
    err = []
    for t in split.holdout.tests:
        dt = float(np.median(np.diff(t.time)))
        f = truth_force(t.channels["displacement"], t.channels["velocity"], t.channels["voltage"], dt=dt,
                        effects=[HIDDEN_EFFECT])
        err.append(f - t.channels["true_force"])
    r = float(np.sqrt(np.mean(np.concatenate(err) ** 2)))
    print(f"truth on the measured inputs vs the true force: {r:.2f} N RMS; with the force noise ({sigma} N) a floor "
          f"{np.hypot(r, sigma) / sigma:.2f}x the force-noise one")


def _drop(settings: dict, names: str) -> dict:
    """settings without the features named (comma-separated), e.g. "acceleration"."""
    drop = [n for n in names.split(",") if n]
    return {**settings, "features": [f for f in settings["features"] if f not in drop]} if drop else settings


def _slug(text: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in text).strip("_")[:80]


def distill(name: str, teachers: int, student_hidden: int, seeds: int, cache: str | None,
            out_json: str | None, groups: int = 0) -> None:
    import dataclasses
    from pathlib import Path

    from dampnet.demo.run import HIDDEN_EFFECT, QUICK_PLAN
    from dampnet.training.ensemble import average_networks
    from dampnet.evaluation.metrics import evaluate_predictions
    from dampnet.features import default_features
    from dampnet.model import MlpModel
    from dampnet.predict import predict_force
    from dampnet.rig import generate
    from dampnet.training.pipeline import (apply_additions, fit_prepared, holdout_vs_noise_floor, noise_floors,
                                           prepare_training)

    ds = generate(QUICK_PLAN, effects=[HIDDEN_EFFECT], seed=0, progress=False)
    settings, _ = apply_additions({"features": default_features(ds)}, ds, HIDDEN_EFFECT)
    kw = dict(VARIANTS[name])
    for effect in (kw.pop("add").split(",") if "add" in kw else []):
        settings = apply_additions(settings, ds, effect)[0]
    settings = _drop(settings, kw.pop("drop", ""))
    prep = prepare_training(ds, **settings, **{"algorithm": "lm", **kw})
    hold = prep.split.holdout.tests
    floor = noise_floors(prep.split.holdout)["rmse_n"]

    def ratio(preds) -> tuple[float, list[float]]:
        hv = holdout_vs_noise_floor(evaluate_predictions(hold, preds), floor)
        return hv["ratio"], [r["ratio"] for r in hv["per_frequency"]]

    models = []
    for seed in range(teachers):
        path = Path(cache) / _slug(name) / f"seed{seed}.json" if cache else None
        if path is not None and path.is_file():
            models.append(MlpModel.load(path))
            continue
        m, _ = fit_prepared(prep, seed)
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            m.save(path, overwrite=True)
        models.append(m)
    t_preds = [[predict_force(m, t) for t in hold] for m in models]
    alone = [ratio(p)[0] for p in t_preds]
    ens, ens_pf = ratio([np.mean(ps, axis=0) for ps in zip(*t_preds)])
    print(f"teachers ({name}), seeds 0-{teachers - 1}: alone {np.median(alone):.2f} ({min(alone):.2f}-{max(alone):.2f}), "
          f"their mean {ens:.2f} ({' / '.join(f'{x:.1f}' for x in ens_pf)})", flush=True)
    # groups of teachers as one network each (dampnet.training.ensemble: e.g. two of 30 hidden, one of 60)
    group_ratios = []
    for g in range(teachers // groups if groups else 0):
        merged = average_networks(models[g * groups:(g + 1) * groups])
        group_ratios.append(ratio([predict_force(merged, t) for t in hold])[0])
    if group_ratios:
        print(f"teachers {groups} by {groups} (seeds 0-{groups - 1}, ...) as one {groups * models[0].hidden[0]}-hidden "
              "network each: " + ", ".join(f"{x:.2f}" for x in group_ratios)
              + f"; median {np.median(group_ratios):.2f}", flush=True)
    if seeds == 0:
        return
    target = np.mean([predict_force(m, prep.X, prep.xd) for m in models], axis=0)
    student_prep = dataclasses.replace(prep, force=target,
                                       request=prep.request.replace(hidden=(student_hidden,)))
    res = []
    for seed in range(seeds):
        t0 = time.perf_counter()
        st, _ = fit_prepared(student_prep, 100 + seed)
        r, pf = ratio([predict_force(st, t) for t in hold])
        res.append({"seed": 100 + seed, "ratio": r, "per_frequency": pf, "time_s": time.perf_counter() - t0})
        print(f"student {student_hidden} hidden, seed {100 + seed}: {r:.2f} ({' / '.join(f'{x:.1f}' for x in pf)}), "
              f"{res[-1]['time_s']:.0f} s", flush=True)
    rs = [x["ratio"] for x in res]
    print(f"students: median {np.median(rs):.2f} ({min(rs):.2f}-{max(rs):.2f}) the noise floor", flush=True)
    if out_json:
        with open(out_json, "w") as f:
            json.dump({"variant": name, "teachers_alone": alone, "teachers_mean": ens,
                       "teachers_mean_per_frequency": ens_pf, "student_hidden": student_hidden,
                       "students": res}, f, indent=1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--only", default=None, help="variant names separated by semicolons (default: all)")
    ap.add_argument("--json", default=None)
    ap.add_argument("--where", action="store_true", help="where the rest of the gap is (see above)")
    ap.add_argument("--distill", metavar="NAME", default=None, help="a student taught by NAME's ensemble (above)")
    ap.add_argument("--teachers", type=int, default=6)
    ap.add_argument("--student-hidden", type=int, default=60)
    ap.add_argument("--groups", type=int, default=0, metavar="K",
                    help="--distill: also the means of consecutive groups of K teachers (--seeds 0: only these)")
    ap.add_argument("--cache", default=None, metavar="DIR", help="--distill: keep / reuse the teacher models here")
    ap.add_argument("--ensemble", type=int, default=0, metavar="K",
                    help="also the means of groups of K seeds' models (see above)")
    args = ap.parse_args()
    if args.where:
        return where()
    if args.distill:
        return distill(args.distill, args.teachers, args.student_hidden, args.seeds, args.cache, args.json,
                       args.groups)
    from dampnet.demo.run import HIDDEN_EFFECT, QUICK_PLAN
    from dampnet.features import default_features
    from dampnet.rig import generate
    from dampnet.evaluation.metrics import evaluate_predictions
    from dampnet.predict import predict_force
    from dampnet.training.pipeline import apply_additions, holdout_vs_noise_floor, model_metrics, train_dataset

    def data():  # afresh for each variant: training adds the acceleration channel to the tests in place
        return generate(QUICK_PLAN, effects=[HIDDEN_EFFECT], seed=0, progress=False)

    ds = data()
    base, _ = apply_additions({"features": default_features(ds)}, ds, HIDDEN_EFFECT)
    names = args.only.split(";") if args.only else list(VARIANTS)
    out = {}
    print("| variant | held-out RMSE / noise RMS, median of seeds | per frequency 0.25 / 1 / 2 / 3 Hz | train time [s] |")
    print("|---|---|---|---|")
    for name in names:
        ratios, perf, times, preds = [], [], [], []
        ds = data()
        kw = dict(VARIANTS[name])
        settings = base
        for effect in (kw.pop("add").split(",") if "add" in kw else []):
            settings = apply_additions(settings, ds, effect)[0]
        settings = _drop(settings, kw.pop("drop", ""))
        for seed in range(args.seeds):
            t0 = time.perf_counter()
            model, info, split = train_dataset(ds, seed=seed, **settings, **{"algorithm": "lm", **kw})
            times.append(time.perf_counter() - t0)
            mm = model_metrics(model, info, split, lookup=False)
            nf = mm["noise_floor"]
            hv = nf["holdout_vs_floor"]
            ratios.append(hv["ratio"])
            rs = mm["training"].get("restarts")
            if rs and rs.get("averaged"):  # the best restart alone and each averaged one, on the same scale
                scale = hv["ratio"] / mm["holdout"]["overall"]["nrmse"]
                print(f"  seed {seed}: averaged {hv['ratio']:.2f}; the best restart alone "
                      f"{scale * rs['runs'][rs['kept']]['holdout_nrmse']:.2f}; the restarts "
                      + ", ".join(f"{scale * x['holdout_nrmse']:.2f}" for x in rs["runs"]), flush=True)
            if args.ensemble:
                preds.append([predict_force(model, t) for t in split.holdout.tests])
            perf.append([r["ratio"] for r in hv["per_frequency"]])
        k = int(np.argsort(ratios)[len(ratios) // 2])
        out[name] = {"ratios": ratios, "per_frequency_median_seed": perf[k], "time_s": times}
        print(f"| {name} | {np.median(ratios):.2f} ({min(ratios):.2f}-{max(ratios):.2f}) | "
              f"{' / '.join(f'{x:.1f}' for x in perf[k])} | {np.median(times):.1f} |", flush=True)
        if args.ensemble:
            k = args.ensemble
            groups = []
            for g in range(len(preds) // k):
                mean = [np.mean(ps, axis=0) for ps in zip(*preds[g * k:(g + 1) * k])]
                hv = holdout_vs_noise_floor(evaluate_predictions(split.holdout.tests, mean), nf["rmse_n"])
                groups.append({"seeds": list(range(g * k, (g + 1) * k)), "ratio": hv["ratio"],
                               "per_frequency": [r["ratio"] for r in hv["per_frequency"]]})
            if len(groups) > 1:  # and every seed's model together
                mean = [np.mean(ps, axis=0) for ps in zip(*preds)]
                hv = holdout_vs_noise_floor(evaluate_predictions(split.holdout.tests, mean), nf["rmse_n"])
                out[name]["ensemble_all"] = {"seeds": len(preds), "ratio": hv["ratio"],
                                             "per_frequency": [r["ratio"] for r in hv["per_frequency"]]}
                pf = " / ".join(f"{x:.1f}" for x in out[name]["ensemble_all"]["per_frequency"])
                print(f"| {name}, mean of all {len(preds)} seeds' models | {hv['ratio']:.2f} | {pf} | |", flush=True)
            out[name]["ensembles"] = groups
            r = [g["ratio"] for g in groups]
            m = groups[int(np.argsort(r)[len(r) // 2])]
            print(f"| {name}, mean of {k} seeds' models ({len(groups)} groups) | {np.median(r):.2f} "
                  f"({min(r):.2f}-{max(r):.2f}) | {' / '.join(f'{x:.1f}' for x in m['per_frequency'])} | |", flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
