"""Tests for the measurement artefacts of dampnet.artefacts: each says whether the artefact is there,
how big it is, and the data fix it implies (a data fix, not a model term).

  time_offset      the force's time shift against the motion: the shift s at which a static
                   function of the motion now (hydraulics on a lagged velocity, the seal friction's
                   sign on the velocity itself, position, control) fits the force at t + s best
                   (a cross-correlation generalised to a nonlinear damper). The seal friction
                   flips with the velocity itself in every damper, with no hydraulic lag; so a
                   shift that moves that flip is a recording delay, not compressibility, which
                   the lagged velocity absorbs. Found when the shift is at least MIN_OFFSET_S and
                   SHIFT_Z jackknife spreads (over groups of tests) from zero, and realigning cuts the fit's RMS
                   by MIN_FALL.
  run_order_drift  a regression of the residual on the run order (alone, times the predicted
                   force, times velocity), scored like a candidate (held out, against the null)
                   beyond the motion's history (the leftover test's other columns join the
                   baseline: a hysteresis larger at slow tests is not a drift); found when significant. With a temperature channel the thermal candidate
                   tests it instead.
"""

from __future__ import annotations

import numpy as np

from dampnet.artefacts import artefact
from dampnet.diagnosis import score as S
from dampnet.diagnosis.basis import SIGN_WIDTHS
from dampnet.diagnosis.leftover import history_columns, run_order
from dampnet.features import first_order_lag

MAX_OFFSET_S = 0.030
HYDRAULIC_LAGS_S = (0.0, 0.001, 0.002, 0.003, 0.004, 0.006, 0.008, 0.012)
MIN_OFFSET_S = 0.001
MIN_FALL = 0.03   # realigning must cut the static fit's RMS by this share
ROWS_PER_TEST = 1000  # rows of each test the time offset is fitted on (the friction flip needs dense rows)
SHIFT_Z = 4.0
GROUPS = 5


def _per_test_sse(ctx, k_max: int, max_rows: int = ROWS_PER_TEST) -> np.ndarray:
    """SSE [test, hydraulic lag, shift] of a per-test least-squares fit of the force at t + k samples
    (k = -k_max..k_max) on the motion at t: hydraulics as a piecewise-linear function of the lagged
    velocity (each test has its own control level, so a fit per test needs no control terms), the seal
    friction's sign of the velocity itself, and position."""
    vmax = max(float(np.max(np.abs(np.concatenate(ctx.at_rows("velocity"))))), 1e-12)
    knots = np.linspace(-0.9, 0.9, 19)
    out = np.zeros((ctx.n_tests, len(HYDRAULIC_LAGS_S), 2 * k_max + 1))
    for i, td in enumerate(ctx.tests):
        t = td.test
        n = len(t)
        rows = np.arange(k_max, n - k_max, max(1, (n - 2 * k_max) // max_rows))
        v = t.channels["velocity"]
        Y = t.channels["force"][rows[:, None] + np.arange(-k_max, k_max + 1)[None, :]]
        fixed = [np.ones(len(rows))] + [np.tanh(v[rows] / vmax / e) for e in SIGN_WIDTHS]
        x = t.channels.get("displacement")
        if x is not None:
            z = (x[rows] - np.mean(x)) / max(float(np.std(x)), 1e-12)
            fixed += [z, z * z, z ** 3]
        for j, tau in enumerate(HYDRAULIC_LAGS_S):
            vh = (first_order_lag(v, t.dt, tau) if tau > 0 else v)[rows] / vmax
            X = np.stack(fixed + [vh] + [np.maximum(vh - k, 0.0) for k in knots], axis=1)
            X = X / np.maximum(np.sqrt(np.mean(X * X, axis=0)), 1e-12)
            G = X.T @ X
            G += 1e-9 * np.trace(G) / G.shape[0] * np.eye(G.shape[0])
            H = X.T @ Y
            B = np.linalg.solve(G, H)
            out[i, j] = np.sum(Y * Y, axis=0) - np.sum(B * H, axis=0)
    return out


def _best(sse_by_tau: np.ndarray, k_max: int) -> tuple[float, int]:
    """(shift [samples, parabola-refined], index of the best lag) of the smallest SSE."""
    j, k = np.unravel_index(int(np.argmin(sse_by_tau)), sse_by_tau.shape)
    row = sse_by_tau[j]
    shift = float(k)
    if 0 < k < len(row) - 1:
        a, b, c = row[k - 1], row[k], row[k + 1]
        den = a - 2 * b + c
        if den > 0:
            shift = k + 0.5 * (a - c) / den
    return shift - k_max, int(j)


def time_offset(ctx) -> dict:
    """The force's time offset against the motion (see the module doc), with its jackknife spread."""
    dt = min(td.test.dt for td in ctx.tests)
    k_max = max(1, int(round(MAX_OFFSET_S / dt)))
    if any(len(td.test) < 4 * k_max for td in ctx.tests):
        return {"artefact": "time_offset", "testable": False, "detected": False,
                "note": f"tests shorter than {4 * k_max} samples"}
    per_test = _per_test_sse(ctx, k_max)
    n = ctx.n_tests
    sse = per_test.sum(0)                                    # [lag, shift]
    shift, j = _best(sse, k_max)
    g = min(GROUPS, n)
    loo = np.asarray([_best(per_test[[i for i in range(n) if i % g != k]].sum(0), k_max)[0] for k in range(g)])
    spread = float(np.sqrt((g - 1) / g * np.sum((loo - loo.mean()) ** 2))) if g >= 2 else 0.0
    offset_s = shift * dt
    spread_s = max(spread * dt, 0.25 * dt)  # below a quarter sample: the rounding of the shift
    n_rows = sum(int(np.ceil((len(td.test) - 2 * k_max) / max(1, (len(td.test) - 2 * k_max) // ROWS_PER_TEST)))
                 for td in ctx.tests)
    rms_at_zero = float(np.sqrt(max(np.min(sse[:, k_max]), 0.0) / n_rows))
    rms_aligned = float(np.sqrt(max(np.min(sse), 0.0) / n_rows))
    fall = 1.0 - rms_aligned / rms_at_zero if rms_at_zero > 0 else 0.0
    detected = bool(abs(offset_s) >= MIN_OFFSET_S and abs(offset_s) >= SHIFT_Z * spread_s and fall >= MIN_FALL)
    late = "late" if offset_s > 0 else "early"
    sentence = (f"the force channel is recorded {1000 * abs(offset_s):.1f} +- {1000 * spread_s:.1f} ms {late} "
                f"against the motion (the seal friction's flip at velocity reversals moves with it, which no "
                f"hydraulic lag does); realigned, a static fit of the force per test falls from {rms_at_zero:.1f} to "
                f"{rms_aligned:.1f} N RMS ({100 * fall:.0f} %). Fix: {artefact('time_offset').fix} "
                f"(--align-force-s {offset_s:.4g})")
    return {"artefact": "time_offset", "testable": True, "detected": detected, "offset_s": offset_s,
            "uncertainty_s": spread_s, "hydraulic_lag_s": HYDRAULIC_LAGS_S[j],
            "static_fit_rms_n": {"as_recorded": rms_at_zero, "realigned": rms_aligned, "fall": fall},
            "fix": {"option": "--align-force-s", "value": offset_s}, "sentence": sentence}


class _RunOrder:
    id = "run_order_drift"
    theta_name = None

    def grid(self, ctx):
        return [None]

    def testable(self, ctx):
        return (ctx.n_tests >= 3, "" if ctx.n_tests >= 3 else "fewer than 3 tests")

    def columns(self, ctx, theta):
        order = run_order(ctx)
        fs = max(float(np.std(np.concatenate(ctx.pred_rows()))), 1e-9)
        vmax = max(float(np.max(np.abs(np.concatenate(ctx.at_rows("velocity"))))), 1e-12)
        out = []
        for i, td in enumerate(ctx.tests):
            r = np.full(len(td.rows), order[i])
            out.append(np.stack([r, r * td.pred[td.rows] / fs, r * td.test.channels["velocity"][td.rows] / vmax], axis=1))
        ctx.notes["run_order_scale"] = fs
        return out


class _History:
    """The leftover test's columns without the run order: the motion's history joins the baseline,
    so a drift is credited to the run order only beyond what the history explains."""

    def columns(self, ctx, theta):
        drop = set(ctx.notes["leftover_run_order_columns"])
        return [c[:, [j for j in range(c.shape[1]) if j not in drop]] for c in history_columns(ctx)]


def run_order_drift(ctx, folds, n_surrogates: int, seed: int) -> dict:
    """A drift of the force along the run order that no channel explains (see the module doc)."""
    has_t = all(t is not None for t in ctx.at_rows("temperature"))
    saved = list(ctx.notes.get("included", []))
    ctx.notes["included"] = saved + [(_History(), None)]
    ctx.notes.pop("baseline", None)
    ctx.notes.pop("baseline_products", None)
    try:
        resid = S.reference_residual(ctx)
        Y = [np.column_stack([r, s]) for r, s in zip(resid, S.surrogates(resid, n_surrogates, seed))]
        res = S.score_candidate(ctx, _RunOrder(), Y, folds, S.baseline_cv(ctx, Y, folds))
    finally:
        ctx.notes["included"] = saved
        ctx.notes.pop("baseline", None)
        ctx.notes.pop("baseline_products", None)
    if not res["testable"]:
        return {"artefact": "run_order_drift", "testable": False, "detected": False, "note": res["note"]}
    fs = ctx.notes["run_order_scale"]
    gain_pct = float(200.0 * res["beta"][1] / fs)   # the force's change from the first test to the last
    detected = bool(res["significant"]) and not has_t
    sentence = (f"the force drifts along the run order: {gain_pct:+.1f} % from the first test to the last "
                f"(held out {100 * res['score']:.1f} % of the residual's variance beyond the motion's history, "
                f"z {res['z']:.1f}); no channel the model has explains it (thermal, but no temperature channel: "
                f"add one). Fix: {artefact('run_order_drift').fix}")
    return {"artefact": "run_order_drift", "testable": True, "detected": detected,
            "significant": bool(res["significant"]), "score": float(res["score"]), "z": float(res["z"]),
            "force_change_percent": gain_pct, "temperature_channel": has_t, "sentence": sentence}


def find_artefacts(ctx, folds, n_surrogates: int, seed: int) -> list[dict]:
    """Every artefact test's result (JSON-ready), in the catalogue's order."""
    return [time_offset(ctx), run_order_drift(ctx, folds, n_surrogates, seed)]
