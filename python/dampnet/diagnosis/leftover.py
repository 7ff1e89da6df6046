"""Structure left in the residual, tested without the catalogue.

The candidates (catalogue.py) can only name what the catalogue knows. This test asks, of the
same reference residual and with the same cross-validation over tests and the same
phase-randomised null (score.py), whether the residual is predictable at all from the model's
inputs and their history, beyond the baseline basis of the inputs themselves:

  position      Legendre polynomials 1-5 of the displacement and end-of-travel hinges
  turning points  the travel since the last velocity reversal, saturating over 0.1, 0.5, 2
                and 8 mm (Dahl states), alone and times the control
  velocity history  a lagged velocity minus the velocity (2, 6, 20 ms), alone and times its sign
  control history  a lagged control minus the control (5, 20, 80 ms), times velocity (tests that
                step the control)
  run order     the test's place in the dataset's order (the run order), alone and times the
                predicted force and the velocity
  time in test  the time since the test started, times the predicted force (heating within a test)
  temperature   when the data have it: alone and times the predicted force

A ridge regression on these columns, fitted on some tests and scored on the others, is the
"anything" model: if it explains a significant share of the held-out residual, structure is
left; if no catalogue effect explains most of that share, it is not a known effect. It is run
given the accepted catalogue effects too (they join the baseline), so what is left after them is
tested the same way. Where the structure is: the fitted leftover part's RMS by frequency,
control, phase of the cycle and run order.

The noise floor is the force channel's noise RMS: the rig's sensor record when the data come
from the rig, else estimated from the force's sample-to-sample scatter (second differences).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dampnet.diagnosis import score as S
from dampnet.diagnosis.catalogue import gas_columns_of
from dampnet.features import dahl_state, first_order_lag

VELOCITY_LAGS_S = (0.002, 0.006, 0.020)
CONTROL_LAGS_S = (0.005, 0.020, 0.080)
TRAVELS_M = (1e-4, 5e-4, 2e-3, 8e-3)
#: a catalogue effect is named only when it explains at least this share of the structure the
#: leftover test finds (else its significance is partial: it mimics an unknown effect)
MIN_EXPLAINED = 0.5


@dataclass
class Leftover:
    """Duck-typed like a Candidate, so score.score_candidate tests it the same way."""

    id: str = "leftover"
    theta_name: str | None = None

    def grid(self, ctx):
        return [None]

    def testable(self, ctx):
        return True, ""

    def columns(self, ctx, theta):
        return history_columns(ctx)


def run_order(ctx) -> np.ndarray:
    """Each test's place in the run order, in [-1, 1]: the stated one (dampnet.data.runorder),
    else the dataset's order (a per-test column all the same; only the run_order_drift artefact
    needs the order to be the one the tests were run in, and it asks for a stated one)."""
    from dampnet.data.runorder import run_positions

    return 2.0 * run_positions([td.test for td in ctx.tests]) - 1.0


def history_columns(ctx) -> list[np.ndarray]:
    """Per test [rows, q]: the columns of the module doc, each scaled to order 1."""
    if "leftover_columns" in ctx.notes:
        return ctx.notes["leftover_columns"]
    ctx.notes["leftover_run_order_columns"] = []
    vmax = max(float(np.max(np.abs(np.concatenate(ctx.at_rows("velocity"))))), 1e-12)
    xs = ctx.at_rows("displacement")
    has_x = all(x is not None for x in xs)
    if has_x:
        lo, hi = np.percentile(np.concatenate(xs), [0.5, 99.5])
        xc, xh = 0.5 * (lo + hi), max(0.5 * (hi - lo), 1e-12)
    name = ctx.control_name
    us = [td.test.channels.get(name) for td in ctx.tests]
    has_u = all(u is not None for u in us)
    if has_u:
        allu = np.concatenate(us)
        uc, uh = float(np.mean(allu)), max(float(np.ptp(allu)) / 2, 1e-12)
        steps = max(float(np.ptp(u)) for u in us) > 0.05 * 2 * uh
    temps = ctx.at_rows("temperature")
    has_t = all(t is not None for t in temps)
    if has_t:
        tall = np.concatenate(temps)
        tc, th = float(np.mean(tall)), max(float(np.ptp(tall)) / 2, 1e-6)
    fs = max(float(np.std(np.concatenate(ctx.pred_rows()))), 1e-9)
    order = run_order(ctx)
    out = []
    for i, td in enumerate(ctx.tests):
        t, rows = td.test, td.rows
        v = t.channels["velocity"]
        zv = v[rows] / vmax
        sg = np.tanh(zv / 0.05)
        fn = td.pred[rows] / fs
        cols = []
        if has_x:  # the gas spring's polynomials and end-of-travel hinges: any position-dependent force
            cols += list(gas_columns_of(t.channels["displacement"][rows], xc, xh).T)
        for travel in TRAVELS_M:
            z = dahl_state(v, t.dt, travel)[rows]
            cols += [z] + ([z * (us[i][rows] - uc) / uh] if has_u else [])
        for tau in VELOCITY_LAGS_S:
            d = (first_order_lag(v, t.dt, tau) - v)[rows] / vmax
            cols += [d, d * sg]
        if has_u and steps:
            for tau in CONTROL_LAGS_S:
                d = (first_order_lag(us[i], t.dt, tau) - us[i])[rows] / uh
                cols += [d, d * zv]
        if ctx.n_tests >= 3:
            r = np.full(len(rows), order[i])
            ctx.notes["leftover_run_order_columns"] = list(range(len(cols), len(cols) + 3))
            cols += [r, r * fn, r * zv]
        tf = (t.time[rows] - t.time[0]) / max(float(np.ptp(t.time)), 1e-12) - 0.5
        cols.append(tf * fn)
        if has_t:
            tt = (temps[i] - tc) / th
            cols += [tt, tt * fn]
        out.append(np.stack(cols, axis=1))
    ctx.notes["leftover_columns"] = out
    return out


def noise_floor(ctx) -> dict:
    """{"rms_n": the force channel's noise RMS [N], "source": where it comes from}."""
    from dampnet.rig import noise_floor_rmse_n

    try:
        return {"rms_n": noise_floor_rmse_n(ctx.dataset), "source": "the rig's sensor record (load-cell noise "
                "and the force channel's rounding)"}
    except ValueError:
        pass
    # white noise: var(second difference) = 6 sigma^2; the signal's own second difference is
    # small at dyno sampling rates (a 3 Hz sine at 1 kHz: 4e-4 of its amplitude)
    per_test = [float(np.std(np.diff(td.test.channels["force"], 2))) / np.sqrt(6.0) for td in ctx.tests]
    return {"rms_n": float(np.median(per_test)), "source": "estimated from the force's sample-to-sample "
            "scatter (second differences: too low if the acquisition filtered the force, too high where the "
            "signal changes fast)"}


def _rms(x) -> float:
    x = np.asarray(x, dtype=np.float64)
    return float(np.sqrt(np.mean(x * x))) if x.size else 0.0


def _binned_rms(keys, parts, label) -> list[dict]:
    out = []
    for k in sorted(set(keys), key=lambda z: (z is None, z)):
        sel = [p for kk, p in zip(keys, parts) if kk == k]
        out.append({label: k, "rms_n": _rms(np.concatenate(sel))})
    return out


def where(ctx, part: list[np.ndarray]) -> dict:
    """Where the leftover part is: its RMS [N] by frequency, control, phase of the cycle, run order."""
    freqs = [td.test.frequency_hz for td in ctx.tests]
    ctrls = [td.test.control_nominal for td in ctx.tests]
    out = {"by_frequency": _binned_rms(freqs, part, "frequency_hz"),
           "by_control": _binned_rms(ctrls, part, "control")}
    # phase of the cycle from displacement and velocity: 0 = mid-stroke extending, 90 = full extension
    ph, pr = [], []
    for td, p in zip(ctx.tests, part):
        x = td.test.channels.get("displacement")
        if x is None:
            continue
        xr, vr = x[td.rows] - np.mean(x), td.test.channels["velocity"][td.rows]
        w = np.std(vr) / max(np.std(xr), 1e-12)
        ph.append(np.degrees(np.arctan2(xr * w, vr)) % 360.0)
        pr.append(p)
    if ph:
        ph, pr = np.concatenate(ph), np.concatenate(pr)
        edges = np.arange(0, 361, 45)
        out["by_phase_deg"] = [{"phase_deg": float(0.5 * (a + b)), "rms_n": _rms(pr[(ph >= a) & (ph < b)])}
                               for a, b in zip(edges[:-1], edges[1:])]
    order = run_order(ctx)
    by = np.argsort(order, kind="stable")       # the tests in run order
    k = max(1, ctx.n_tests // 5)
    out["by_run_order"] = [{"tests": f"{ctx.tests[by[j]].test.test_id}..{ctx.tests[by[min(j + k, ctx.n_tests) - 1]].test.test_id}",
                            "run_order": float(np.mean(order[by[j:j + k]])),
                            "mean_n": float(np.mean(np.concatenate([part[i] for i in by[j:j + k]]))),
                            "rms_n": _rms(np.concatenate([part[i] for i in by[j:j + k]]))}
                           for j in range(0, ctx.n_tests, k)]
    # the dimension along which the part varies most (its largest bin RMS over the smallest)
    spread = {}
    for key in ("by_frequency", "by_control", "by_phase_deg", "by_run_order"):
        vals = [b["rms_n"] for b in out.get(key, []) if b["rms_n"] > 0]
        if len(vals) >= 2:
            spread[key[3:]] = max(vals) / min(vals)
    out["most_uneven"] = max(spread, key=spread.get) if spread else None
    return out


def leftover(ctx, Y, folds, base_cv, noise: dict) -> dict:
    """The leftover test's numbers (JSON-ready): significance, how much, where (see the module doc)."""
    res = S.score_candidate(ctx, Leftover(), Y, folds, base_cv)
    resid = [y[:, 0] for y in Y]
    r_all = np.concatenate(resid)
    part = res["effect_rows"]  # the full-data fit of the columns: what the structure looks like
    model_rms = _rms(np.concatenate(ctx.resid_rows()))
    held_gain = max(float(res["score"]), 0.0) * float(np.sum(r_all * r_all))
    structure_rms = float(np.sqrt(held_gain / r_all.size))
    # the picture shows the first call's fit (before any catalogue effect joins the baseline: the
    # structure itself, not what is left of it beside collinear effect columns)
    ctx.notes.setdefault("leftover_part", part)
    return {"significant": bool(res["significant"]), "score": float(res["score"]), "z": float(res["z"]),
            "p_value": float(res["p_value"]),
            "null": {"mean": res["null_mean"], "sd": res["null_sd"], "max": res["null_max"]},
            "structure_rms_n": structure_rms,
            "reference_residual_rms_n": _rms(r_all),
            "model_residual_rms_n": model_rms,
            "noise_floor_rms_n": noise["rms_n"], "noise_floor_source": noise["source"],
            "model_residual_vs_noise": model_rms / noise["rms_n"] if noise["rms_n"] > 0 else None,
            "where": where(ctx, part)}
