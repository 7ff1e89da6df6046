"""diagnose(model, dataset) -> the diagnosis as a JSON-ready dict (see dampnet.diagnosis)."""

from __future__ import annotations

import dataclasses

import numpy as np

from dampnet.diagnosis import score as S
from dampnet.diagnosis.catalogue import CANDIDATES
from dampnet.diagnosis.artefacts import find_artefacts
from dampnet.diagnosis.context import ROWS_PER_TEST, build_context
from dampnet.diagnosis.leftover import leftover, noise_floor
from dampnet.diagnosis.report import not_addable_words
from dampnet.diagnosis.verdict import three_way
from dampnet.effects import additions
from dampnet.outputs import jsonable

MAX_ACCEPTED = 3  # forward selection stops after this many effects


def _jackknife(values: list[float]) -> float | None:
    v = np.asarray([x for x in values if x is not None and np.isfinite(x)], dtype=np.float64)
    if len(v) < 2:
        return None
    k = len(v)
    return float(np.sqrt((k - 1) / k * np.sum((v - v.mean()) ** 2)))


def _parameters(ctx, cand, res, folds):
    if cand.parameters is None:
        return {}, {}
    fit = {"beta": res["beta"], "effect_rows": res["effect_rows"]}
    est = dict(cand.parameters(ctx, res["theta"], fit))
    own = est.pop("_uncertainty", {})  # a candidate may estimate a parameter's spread itself
    fold_est = []
    for th, b in zip(res["fold_thetas"], res["fold_betas"]):
        rows = [c @ b for c in res["columns"]]
        fold_est.append(cand.parameters(ctx, th, {"beta": b, "effect_rows": rows}))
    unc = {}
    for k, v in est.items():
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            unc[k] = own[k] if k in own else _jackknife([fe.get(k) for fe in fold_est])
    return est, unc


def _reusing_columns(cand, store: dict):
    """`cand` with its columns(ctx, theta) kept in `store`: a catalogue candidate's columns depend
    on the data and the model only, not on the baseline, so each forward-selection pass after the
    first reuses them instead of recomputing them (lags, Dahl states, model predictions)."""
    def columns(ctx, theta):
        if theta not in store:
            store[theta] = cand.columns(ctx, theta)
        return store[theta]
    return dataclasses.replace(cand, columns=columns)


def fixed_by_artefacts(ds, found: list[dict]):
    """`ds` with the data fixes of the artefacts found applied (dampnet.data.artefacts: realign, the
    run-order term, sign, unit, offset per test), as a user would apply them; None if none applies."""
    from dampnet.data import artefacts as A

    out, applied = ds, False
    for a in found:
        if not a.get("detected"):
            continue
        aid = a["artefact"]
        if aid == "time_offset":
            out, applied = A.align_force(out, a["fix"]["value"]), True
        elif aid == "run_order_drift":
            out, applied = A.remove_run_order_drift(out, a["fix"]["value"]), True
        for h in a.get("tests", []):
            ch = h.get("channel")
            if ch not in ("velocity", "displacement", "force"):
                continue   # "velocity or displacement": which one slipped is not known
            if aid == "sign_slip":
                out = A.flip_sign(out, ch, [h["test_id"]])
            elif aid == "unit_slip":
                out = A.rescale(out, ch, h["factor"], [h["test_id"]])
            elif aid == "sensor_offset":
                out = A.remove_offset(out, ch, h["offset"], [h["test_id"]])
            applied = True
    return out if applied else None


def _leftover_after_fixes(model, ds, found, included, rows_per_test, n_surrogates, seed, noise):
    """The leftover test (before any catalogue effect) on the data with the artefacts' fixes
    applied: is there structure beyond the artefacts? None when no fix applies."""
    from dampnet.diagnosis.context import build_context as _build

    fixed = fixed_by_artefacts(ds, found)
    if fixed is None:
        return None
    ctx = _build(model, fixed, rows_per_test=rows_per_test)
    ctx.notes["included"] = [(CANDIDATES[c], th) for c, th in included.items()]
    resid = S.reference_residual(ctx)
    Y = [np.column_stack([r, s]) for r, s in zip(resid, S.surrogates(resid, n_surrogates, seed))]
    folds = S.folds_of(ctx)
    return leftover(ctx, Y, folds, S.baseline_cv(ctx, Y, folds), noise)


def missing_channels(cid: str, ds, control: str) -> list[str]:
    """The channels the inputs `--add CID` adds are computed from that some test of `ds` lacks
    (thermal's temperature, say), sorted; [] when it can be added."""
    from dampnet.features import FEATURES, missing_channel

    return sorted({c for f in additions(cid, {}, control)["features"] if f in FEATURES
                   for t in ds.tests if (c := missing_channel(f, t)) is not None})


def diagnose(model, ds, *, candidates=None, n_surrogates: int = S.N_SURROGATES, seed: int = 0,
             rows_per_test: int = ROWS_PER_TEST, ctx=None, dataset_label: str = "DATA") -> dict:
    """Compare, localise and test every candidate effect; returns the JSON-ready diagnosis."""
    from dampnet.diagnosis.localise import localise, overall_metrics

    ctx = ctx or build_context(model, ds, rows_per_test=rows_per_test)
    metrics = overall_metrics(ctx)
    # Effects whose inputs the model already has are part of the baseline, not candidates:
    # their regressors, at the model's own time constant where it has one, join the baseline.
    included = {}
    for cid in (candidates or list(CANDIDATES)):
        cand = CANDIDATES[cid]
        if cand.info.adds is None:
            continue
        rec = additions(cid, {}, ctx.control_name)
        if rec["features"] and all(f in model.features for f in rec["features"]):
            key = next(iter(rec["feature_params"]), None)
            theta = model.feature_params.get(key) if key else None
            if theta is None and cand.theta_name is not None:
                theta = list(cand.grid(ctx))[len(list(cand.grid(ctx))) // 2]
            ok, _ = cand.testable(ctx)
            if ok:
                included[cid] = theta
    loc = None
    cids = list(candidates or list(CANDIDATES))
    scored = {cid: _reusing_columns(CANDIDATES[cid], {}) for cid in cids}

    def score_pass(accepted: dict) -> tuple[dict, dict, float, list]:
        """Score every candidate not in the baseline; `accepted` effects join the baseline."""
        nonlocal loc
        ctx.notes["included"] = [(CANDIDATES[c], th) for c, th in {**included, **accepted}.items()]
        ctx.notes.pop("baseline", None)
        ctx.notes.pop("baseline_products", None)
        if loc is None:
            loc = localise(ctx)
        resid = S.reference_residual(ctx)
        sur = S.surrogates(resid, n_surrogates, seed)
        Y = [np.column_stack([r, s]) for r, s in zip(resid, sur)]
        folds = S.folds_of(ctx)
        base_cv = S.baseline_cv(ctx, Y, folds)
        ss_tot = sum(float(np.sum(r * r)) for r in resid)
        share = float((ss_tot - base_cv[0][:, 0].sum()) / ss_tot) if ss_tot > 0 else 0.0
        results = {cid: S.score_candidate(ctx, scored[cid], Y, folds, base_cv)
                   for cid in cids if cid not in included and cid not in accepted}
        return results, (Y, base_cv), share, folds

    # Forward selection: the most likely effect is accepted into the baseline and the
    # others are scored again given it, so that an effect which only partly mimics the
    # accepted one (e.g. compressibility's lagged force next to a valve lag) is judged
    # on what it adds. Each accepted effect keeps the score it had when it was accepted.
    accepted: dict = {}
    accepted_results: dict = {}
    results, first, baseline_share, folds = score_pass(accepted)
    noise = noise_floor(ctx)
    left0 = leftover(ctx, first[0], folds, first[1], noise)  # before any catalogue effect
    found = find_artefacts(ctx, folds, n_surrogates, seed, noise["rms_n"])
    # structure beyond the artefacts: the leftover test again on the data their fixes give
    left_fixed = _leftover_after_fixes(model, ds, found, included, rows_per_test, n_surrogates, seed, noise)
    last = first
    while len(accepted) < MAX_ACCEPTED:
        testable = {c: r for c, r in results.items() if r["testable"]}
        if not testable:
            break
        best = max(testable, key=lambda c: testable[c]["score"])
        if not testable[best]["significant"]:
            break
        accepted[best] = testable[best]["theta"]
        accepted_results[best] = testable[best]
        results, last, _, folds = score_pass(accepted)
    results = {**results, **accepted_results}
    left1 = leftover(ctx, last[0], folds, last[1], noise) if accepted else None

    out = []
    for cid in cids:
        cand = CANDIDATES[cid]
        if cid in included:
            res = {"testable": False, "note": f"already in the model: its inputs {additions(cid, {}, ctx.control_name)['features']} "
                                              "are model features (the effect's regressors are part of the baseline)"}
        else:
            res = results[cid]
        lacking = missing_channels(cid, ds, ctx.control_name)
        entry = {"effect": cid, "title": cand.title, "needs": cand.needs, "physics": cand.physics,
                 "signature": cand.signature,
                 # what `--add` needs that these data lack: no command that would only be refused
                 "add_command": None if lacking else f"dampnet train {dataset_label} --add {cid}",
                 "missing_channels": lacking}
        if not res["testable"]:
            entry.update({"testable": False, "score": None, "significant": False, "p_value": None,
                          "z": None, "parameters": {}, "uncertainty": {},
                          "evidence": f"cannot be tested: {res['note']}", "note": res["note"]})
        else:
            ctx.notes.setdefault("candidate_effects", {})[cid] = res["effect_rows"]
            est, unc = _parameters(ctx, cand, res, folds)
            gains = res["per_test_gain"]
            improved = int(np.sum(gains > 0))
            top = [ctx.tests[i].test.test_id for i in np.argsort(-gains)[:3] if gains[i] > 0]
            ev = cand.evidence(est, loc) if cand.evidence else cand.signature
            acc = list(accepted)
            given = acc[:acc.index(cid)] if cid in accepted else acc  # scored given these effects
            ev += (f". Held out, it explains {100 * res['score']:.1f} % of the residual variance"
                   + (f" left after {', '.join(given)}" if given else "")
                   + f" (null {100 * res['null_mean']:.2f} +- {100 * res['null_sd']:.2f} %), improving "
                   f"{improved} of {ctx.n_tests} tests" + (f", most {', '.join(top)}" if top else ""))
            entry.update({"testable": True, "score": res["score"], "significant": res["significant"],
                          "p_value": res["p_value"], "z": res["z"],
                          "null": {"mean": res["null_mean"], "sd": res["null_sd"], "max": res["null_max"],
                                   "n_surrogates": n_surrogates},
                          "parameters": est, "uncertainty": unc, "evidence": ev, "note": res["note"],
                          "tests_improved": improved, "given": given})
        out.append(entry)
    # Accepted effects first, in the order they were accepted; then the rest by score.
    order = {c: i for i, c in enumerate(accepted)}
    out.sort(key=lambda e: (e["effect"] not in order, order.get(e["effect"], 0), not e["testable"],
                            -(e["score"] if e["score"] is not None else -1e9)))

    finding = three_way(accepted_results, left0, left1, found, ctx, left_fixed=left_fixed)
    cannot_add = {e["effect"]: e["missing_channels"] for e in out
                  if e["effect"] in finding["effects"] and e["missing_channels"]}
    if cannot_add:
        finding["sentence"] += "; " + "; ".join(not_addable_words(cid, chans) for cid, chans in cannot_add.items())
    finding["not_addable"] = cannot_add
    verdict = finding["effects"][0] if finding["effects"] else None
    return jsonable({
        "model": {"id": model.model_id(), "features": model.features, "terms": [t.get("kind") for t in model.terms],
                  "feature_params": model.feature_params},
        "data": {"source": ds.source, "n_tests": len(ds.tests)},
        "overall": metrics["overall"],
        "per_test": metrics["per_test"],
        "per_frequency": metrics.get("per_frequency"),
        "worst_tests": metrics["worst_tests"],
        "localisation": loc,
        "method": {"folds": len(folds), "fold_unit": "test", "rows_per_test": int(np.median([len(t.rows) for t in ctx.tests])),
                   "baseline_share": baseline_share, "n_surrogates": n_surrogates,
                   "min_score": S.MIN_SCORE, "z_min": S.Z_MIN,
                   "score": "held-out share of residual variance explained beyond a flexible function "
                            "of the model's own inputs (cross-validation over tests)",
                   "null": "phase-randomised residuals per test (same spectrum), same cross-validation",
                   "selection": "forward: the best significant effect joins the baseline and the rest are "
                                "scored again, up to %d effects" % MAX_ACCEPTED,
                   "accepted": list(accepted)},
        "candidates": out,
        "leftover": {"before_effects": left0, "after_effects": left1, "after_artefact_fixes": left_fixed},
        "artefacts": found,
        "finding": finding,
        "verdict": verdict,
    })
