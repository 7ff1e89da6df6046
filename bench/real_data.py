"""Real dampers (issue 53, item 1): dampnet beside the lookup table, the modified Bouc-Wen model
and a GRU, on the real MR-damper data sets kept in ../shared/data. One command:

    python bench/real_data.py                      # both data sets, the full budgets (14 min on 2 loaded cores)
    python bench/real_data.py --quick --out DIR    # a small slice of UTFSM, small budgets (~30 s)

For each data set (dampnet.data.real: `utfsm`, `labcontrol`) the held-out tests are fixed and
stated (SPLITS); every model is fitted on the other tests only and scored on the held-out ones:

  lookup table   dampnet's baseline (dampnet.evaluation.lookup: peak force against peak velocity
                 per control level, bilinear), fitted on the training tests
  dampnet        `dampnet.train` as `dampnet train` trains by default (algorithm and restarts
                 'auto'), the held-out tests passed as holdout_tests
  + EFFECT       the diagnosis loop (dampnet.recipes.loop): `dampnet.diagnose` of the last model on
                 the TRAINING tests (never the held-out ones); every effect it names added, in its
                 order (as `dampnet train --add A --add B --diagnosis d.json`), retrained; up to
                 MAX_STEPS effects, until it names nothing new or nothing the data can carry
  Bouc-Wen       the modified Bouc-Wen model (Spencer, Dyke, Sain and Carlson 1997;
                 bench/peers/bouc_wen.py), fitted with scipy.optimize.least_squares
  GRU            a GRU over a 20-sample history window of (displacement, velocity, control)
                 in torch (bench/peers/sequence.py), trained within the budget stated

Per model: RMSE [N] and NRMSE (RMSE over the held-out tests' force range, max - min; dampnet's
definition, dampnet.evaluation.metrics) over all held-out samples, and per test; training time
[s] (wall clock, this machine, whatever else it was running); parameters; inference time per
sample in the runtime that would run it: dampnet's MLP in its C++ kernel through the Python
binding (`_core.Mlp.forward`, one sample a call, float kernel; the features precomputed), the
lookup table in the C runtime's table damper (`_core.Damper.forces`, one call over a record), Bouc-Wen in numpy (one record, its fixed-step
integration; per sample, substeps included), the GRU in torch (one 20-sample window a call).

Writes OUT/real_data.json (every number, per-test errors, budgets, fitted parameters) and
OUT/real_data.md (the tables); prints the tables.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from peers import bouc_wen as bw  # noqa: E402
from peers import sequence as seq  # noqa: E402

from dampnet.recipes.loop import MAX_STEPS  # noqa: E402

#: held-out tests per data set, and how the split is stated in the table
SPLITS = {
    "utfsm": {"holdout": lambda t: t.control_nominal == 0.5,
              "text": "by test: every test at 0.5 A held out (6 of 30: all six amplitude/frequency pairs at the "
                      "middle current, i.e. interpolation between currents, as `dampnet train --holdout-voltage`)"},
    "labcontrol": {"holdout": lambda t: t.test_id in {"ensaio3.1", "ensaio7.1", "ensaio3.2.2", "ensaio7.2.2",
                                                      "ensaio.B.3", "ensaio.B.7", "ensaio.A.3", "ensaio.A.7"},
                   "text": "by test: tests 3 and 7 of each voltage series held out (8 of 38: ensaio3.1, ensaio7.1, "
                           "ensaio3.2.2, ensaio7.2.2, ensaio.B.3, ensaio.B.7, ensaio.A.3, ensaio.A.7; every "
                           "voltage is trained on, the held-out frequencies/amplitudes lie between trained ones)"},
}
#: --quick: a small slice of UTFSM (the 5 Hz and 3 Hz tests, 10 of 30), 0.5 A held out (2 tests)
QUICK_SLICE = {"utfsm": lambda t: t.frequency_hz in (3.0, 5.0)}

#: the GRU's budget is its epochs: the time cap is a safety net that a run on a loaded machine does
#: not reach, so the trained network does not depend on the load
BUDGETS = {
    "full": {"dampnet": {}, "steps": MAX_STEPS,
             "bouc_wen": {"max_nfev": 40, "points_per_period": 200, "substeps": 2},
             "gru": {"window": 20, "hidden": 32, "epochs": 20, "seconds": 900.0, "batch": 256, "lr": 3e-3,
                     "max_windows": 40000, "threads": 1}},
    "quick": {"dampnet": {"max_epochs": 40, "restarts": 1}, "steps": 1,
              "bouc_wen": {"max_nfev": 6, "points_per_period": 100, "substeps": 2},
              "gru": {"window": 20, "hidden": 16, "epochs": 3, "seconds": 300.0, "batch": 256, "lr": 3e-3,
                      "max_windows": 4000, "threads": 1}},
}


def load(name: str, quick: bool):
    from dampnet.data.real import load_real

    ds = load_real(name)
    if quick:
        keep = QUICK_SLICE.get(name)
        if keep is None:
            raise ValueError(f"--quick has no slice of {name}; it runs {', '.join(QUICK_SLICE)}")
        ds.tests = [t for t in ds.tests if keep(t)]
    return ds


def split(name: str, ds):
    hold = SPLITS[name]["holdout"]
    test = [t for t in ds.tests if hold(t)]
    train = [t for t in ds.tests if not hold(t)]
    if not test or not train:
        raise ValueError(f"{name}: the split leaves {len(train)} training and {len(test)} held-out tests")
    return train, test


def default_on_split(name: str, seed: int = 0):
    """`dampnet train`'s default on the data set's split (the table's first dampnet row, one worker):
    (the data set, the training result, the training tests as a Dataset: what a diagnosis reads)."""
    from dampnet.data import Dataset
    from dampnet.data.real import load_real
    from dampnet.recipes.training import TrainingRequest, train
    from dampnet.training.settings import command_defaults

    ds = load_real(name)
    _, test = split(name, ds)
    req = TrainingRequest.of(**command_defaults(), seed=seed,
                             holdout_tests=[t.test_id for t in test], holdout_voltage=None)
    first = train(ds, request=req, workers=1)
    return ds, first, Dataset(tests=list(first.split.train.tests), source=ds.source, meta=dict(ds.meta))


def scores(tests, preds) -> dict:
    """RMSE [N], NRMSE, the largest error [N], per test; and the error where the damper stands still
    (dampnet.evaluation.regions: at_rest_mask on the test's velocity channel, the same samples for
    every model; at_rest_errors), None when no held-out test stands still."""
    from dampnet.evaluation.metrics import evaluate_predictions
    from dampnet.evaluation.regions import at_rest_errors, at_rest_mask

    rep = evaluate_predictions(tests, preds)
    o = rep["overall"]
    at_rest = at_rest_errors(tests, preds, [at_rest_mask(t.channels["velocity"], t.time) for t in tests])
    return {"rmse_n": o["rmse_n"], "nrmse": o["nrmse"], "max_abs_error_n": o["max_abs_error_n"], "at_rest": at_rest,
            "per_test": [{"test_id": r["test_id"], "rmse_n": r["rmse_n"], "nrmse": r["nrmse"]} for r in rep["per_test"]]}


def _per_call(fn, n: int) -> float:
    for k in range(min(50, n)):
        fn(k)
    t0 = time.perf_counter()
    for k in range(n):
        fn(k)
    return (time.perf_counter() - t0) / n


# -- the models ---------------------------------------------------------------------------------

def run_lookup(train, test) -> dict:
    from dampnet.evaluation.lookup import fit_lookup

    t0 = time.perf_counter()
    lut = fit_lookup(train)
    secs = time.perf_counter() - t0
    preds = [lut.predict_test(t) for t in test]
    per = _table_time_per_sample(lut, test[0])
    return {"model": "lookup table", **scores(test, preds), "train_s": secs,
            "parameters": int(lut.forces.size + lut.velocities.size + lut.voltages.size),
            "infer_us": per * 1e6, "runtime": "dampnet C runtime's table damper (dn_damper_create_table) via "
                                              "_core.Damper.forces, one call over a record, per sample"}


def _table_time_per_sample(lut, t, repeats: int = 20) -> float:
    """Seconds per sample of the C runtime's lookup-table damper (the one `dampnet` runs the
    table in), checked against LookupTable.force on the record first."""
    from dampnet import _core

    d = _core.Damper.table(lut.velocities, lut.voltages, lut.forces)
    v = np.ascontiguousarray(t.channels["velocity"], dtype=np.float64)
    u = np.ascontiguousarray(t.control, dtype=np.float64) * np.ones_like(v)
    z = np.zeros_like(v)
    f = d.forces(z, v, z, u, u, z)[0]
    err = float(np.max(np.abs(f - lut.force(v, u))))
    if err > 1e-6:
        raise RuntimeError(f"the C runtime's table differs from LookupTable.force by {err:g} N")
    t0 = time.perf_counter()
    for _ in range(repeats):
        d.forces(z, v, z, u, u, z)
    return (time.perf_counter() - t0) / (repeats * len(v))


def _mlp_params(model) -> int:
    n = model.w1.size + model.b1.size + model.w_out.size + 1
    if model.w2 is not None:
        n += model.w2.size + model.b2.size
    return int(n + sum(len(t.get("params", [])) for t in model.terms))


def _dampnet_row(label, model, test, secs, extra=None) -> dict:
    from dampnet.features import feature_matrix
    from dampnet.predict import predict_force

    preds = [predict_force(model, t) for t in test]
    X = feature_matrix([test[0]], model.features, model.feature_params,
                       model.meta.get("data", {}).get("acceleration_window_s"))
    X = np.ascontiguousarray(X[:2000], dtype=np.float64)
    core = model.core()
    xs = [np.ascontiguousarray(x) for x in X]
    per = _per_call(lambda k: core.forward(xs[k], True), len(xs))
    return {"model": label, **scores(test, preds), "train_s": secs, "parameters": _mlp_params(model),
            "infer_us": per * 1e6, "runtime": "dampnet C++ float kernel via pybind11 (_core.Mlp.forward), features precomputed",
            "features": list(model.features), "hidden": list(model.hidden),
            "algorithm": model.meta.get("algorithm"), **(extra or {})}


def run_dampnet(ds, train, test, budget, steps, seed=0, log=print) -> list[dict]:
    """dampnet's default model and the diagnosis loop after it (dampnet.recipes.loop.run_loop, as
    `dampnet demo --data` runs it), one row per model."""
    from dampnet.recipes.loop import run_loop

    hold = [t.test_id for t in test]
    options = dict(algorithm="auto", restarts="auto", holdout_voltage=None, holdout_tests=hold)
    options.update(budget)
    loop = run_loop(ds, max_steps=steps, seed=seed, log=lambda s: log(f"    {s}"), workers=1, **options)
    rows = []
    for step in loop:
        label = "dampnet (default)" if not step.added else f"dampnet + {' + '.join(step.added)}"
        extra = {"restarts": step.trained.restarts}
        if step.added:
            extra.update(added=list(step.added), step=len(step.added))
        rows.append(_dampnet_row(label, step.trained.model, test, step.train_s, extra))
        if step.diagnosis is not None:
            rows[-1]["diagnosis"] = {"verdict": step.named, "named": step.named_all,
                                     "three_way": _three_way(step.diagnosis), "seconds": step.diagnose_s,
                                     "stop": step.stop}
            if step.not_addable:
                rows[-1]["diagnosis"]["not_addable"] = step.not_addable
    return rows


def _three_way(diag: dict) -> dict:
    """The diagnosis's three-way finding (dampnet.diagnosis.verdict): kind, effects named, sentence."""
    f = diag.get("finding") or {}
    return {"kind": f.get("kind"), "effects": f.get("effects"), "sentence": f.get("sentence"),
            "explained_share": f.get("explained_share"), "partial": f.get("partial")}


def _motion(t):
    return t.channels["displacement"], t.channels["velocity"], np.asarray(t.control, dtype=np.float64)


def run_bouc_wen(train, test, budget, log=print) -> dict:
    ppp = budget["points_per_period"]
    recs = []
    for t in train:
        x, xd, u = _motion(t)
        recs.append(bw.fit_window(x, xd, u, t.channels["force"], t.dt, 1.0 / t.frequency_hz, points_per_period=ppp))
    res = bw.fit(recs, max_nfev=budget["max_nfev"], substeps=budget["substeps"])
    preds = []
    for t in test:
        x, xd, u = _motion(t)
        preds.append(bw.simulate(res.params, x, xd, u, t.dt, substeps=budget["substeps"]))
    x, xd, u = _motion(test[0])
    n = min(1000, len(x))
    t0 = time.perf_counter()
    bw.simulate(res.params, x[:n], xd[:n], u[:n], test[0].dt, substeps=budget["substeps"])
    per = (time.perf_counter() - t0) / n
    row = {"model": "Bouc-Wen (Spencer 1997)", **scores(test, preds), "train_s": res.seconds,
           "parameters": len(bw.PARAM_NAMES), "infer_us": per * 1e6,
           "runtime": f"numpy, one record, Rosenbrock-Euler, {budget['substeps']} substeps a sample",
           "fitted": res.params, "fixed": res.fixed, "start": res.start, "fit_rmse_n": res.cost_rmse_n,
           "nfev": res.nfev, "fit_message": res.message, "budget": dict(budget)}
    log(f"    Bouc-Wen: NRMSE {row['nrmse']:.4f} ({res.seconds:.0f} s, {res.nfev} evaluations)")
    return row


def run_gru(train, test, budget, seed=0, log=print) -> dict:
    def rec(t):
        x, xd, u = _motion(t)
        return seq.SeqRecord(x, xd, u, t.channels["force"])

    peer = seq.train_gru([rec(t) for t in train], seed=seed, **budget)
    preds = [peer.predict(rec(t)) for t in test]
    per = peer.time_per_sample(rec(test[0]))
    row = {"model": f"GRU ({budget['hidden']} units, {budget['window']}-sample window)", **scores(test, preds),
           "train_s": peer.info["seconds"], "parameters": peer.n_parameters(), "infer_us": per * 1e6,
           "runtime": f"torch eager, float32, {budget['threads']} thread, one window a call",
           "budget": dict(budget), "training": peer.info}
    log(f"    GRU: NRMSE {row['nrmse']:.4f} ({peer.info['seconds']:.0f} s, {peer.info['epochs_run']} epochs)")
    return row


# -- the tables ---------------------------------------------------------------------------------

def markdown(result: dict) -> str:
    lines = []
    for name, d in result["datasets"].items():
        lines.append(f"**{name}** ({d['n_train']} training tests, {d['n_test']} held out, "
                     f"{d['n_test_samples']:,} held-out samples, force range {d['force_range_n']:.0f} N). "
                     f"Split: {d['split']}.\n")
        lines.append("| model | RMSE [N] | NRMSE | worst test NRMSE | at rest: RMSE (bias) [N] | training [s] | "
                     "parameters | inference [us/sample] | diagnosis of it named |")
        lines.append("|---|---|---|---|---|---|---|---|---|")
        for r in d["models"]:
            worst = max(r["per_test"], key=lambda p: p["nrmse"])
            named = ""
            if "diagnosis" in r:
                dg = r["diagnosis"]
                lacking = dg.get("not_addable") or {}
                named = ", ".join(e + (f" (not addable: the data have no {' or '.join(lacking[e])} channel)"
                                       if lacking.get(e) else "") for e in dg["named"]) or "no effect"
                if not dg.get("verdict") and (dg.get("three_way") or {}).get("kind") == "artefact":
                    named += " (a measurement artefact instead: see the JSON's finding)"
                if (dg.get("stop") or "").startswith("adding"):
                    named += " (not added: see the JSON's stop)"
            rest = r.get("at_rest")
            rest = "none at rest" if rest is None else f"{rest['rmse_n']:.1f} ({rest['bias_n']:+.1f})"
            lines.append(f"| {r['model']} | {r['rmse_n']:.1f} | {r['nrmse']:.4f} | {worst['nrmse']:.4f} "
                         f"({worst['test_id']}) | {rest} | {r['train_s']:.1f} | {r['parameters']:,} | {r['infer_us']:.1f} | {named} |")
        lines.append("")
        ids = [p["test_id"] for p in d["models"][0]["per_test"]]
        lines.append("Per held-out test, RMSE [N]:\n")
        lines.append("| test | " + " | ".join(r["model"] for r in d["models"]) + " |")
        lines.append("|---|" + "---|" * len(d["models"]))
        for i, tid in enumerate(ids):
            lines.append(f"| {tid} | " + " | ".join(f"{r['per_test'][i]['rmse_n']:.1f}" for r in d["models"]) + " |")
        lines.append("")
        lines.append("Runtimes timed: " + "; ".join(f"{r['model']}: {r['runtime']}" for r in d["models"]) + ".\n")
    return "\n".join(lines)


def run(names, quick: bool, out: Path, seed: int = 0, log=print) -> dict:
    budgets = BUDGETS["quick" if quick else "full"]
    result = {"schema": "dampnet.bench.real_data/1", "quick": quick, "seed": seed, "budgets": budgets,
              "machine": {"platform": platform.platform(), "processor": platform.processor() or platform.machine(),
                          "cpus": os.cpu_count(), "python": platform.python_version()},
              "started": time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime()), "datasets": {}}
    t_all = time.perf_counter()
    for name in names:
        ds = load(name, quick)
        train, test = split(name, ds)
        log(f"{name}: {len(train)} training tests, {len(test)} held out")
        f_all = np.concatenate([t.channels["force"] for t in test])
        rows = [run_lookup(train, test)]
        log(f"    lookup table: NRMSE {rows[0]['nrmse']:.4f}")
        rows += run_dampnet(ds, train, test, budgets["dampnet"], budgets["steps"], seed=seed, log=log)
        rows.append(run_bouc_wen(train, test, budgets["bouc_wen"], log=log))
        rows.append(run_gru(train, test, budgets["gru"], seed=seed, log=log))
        result["datasets"][name] = {
            "split": SPLITS[name]["text"] + (" [--quick: " + "5 Hz and 3 Hz tests only]" if quick else ""),
            "held_out": [t.test_id for t in test], "n_train": len(train), "n_test": len(test),
            "n_test_samples": int(f_all.size), "force_range_n": float(np.ptp(f_all)), "models": rows}
    result["seconds"] = time.perf_counter() - t_all
    out.mkdir(parents=True, exist_ok=True)
    (out / "real_data.json").write_text(json.dumps(result, indent=1, default=float) + "\n")
    md = markdown(result)
    (out / "real_data.md").write_text(md + "\n")
    log(md)
    log(f"total {result['seconds']:.0f} s; wrote {out / 'real_data.json'} and {out / 'real_data.md'}")
    return result


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="a small slice of UTFSM and small budgets (the test's run)")
    p.add_argument("--out", default=str(HERE / "real_data_results"), help="directory for real_data.json and real_data.md")
    p.add_argument("--datasets", default=None, help="comma-separated: utfsm,labcontrol (default both; --quick: utfsm)")
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args(argv)
    names = a.datasets.split(",") if a.datasets else (["utfsm"] if a.quick else ["utfsm", "labcontrol"])
    for n in names:
        if n not in SPLITS:
            p.error(f"--datasets: unknown {n!r}; expected utfsm, labcontrol")
    from dampnet.data import DataError

    try:
        run(names, a.quick, Path(a.out), seed=a.seed)
    except DataError as e:
        print(f"real_data.py: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
