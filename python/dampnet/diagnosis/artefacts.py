"""Tests for the measurement artefacts of dampnet.data.artefacts: each says whether the artefact is there,
how big it is, and the data fix it implies (a data fix, not a model term).

  time_offset      the force's time shift against the motion: the shift s at which a static
                   function of the motion now (hydraulics on a lagged velocity, the seal friction's
                   sign on the velocity itself, position, control) fits the force at t + s best
                   (a cross-correlation generalised to a nonlinear damper). The seal friction
                   flips with the velocity itself in every damper, with no hydraulic lag; so a
                   shift that moves that flip is a recording delay, not compressibility, which
                   the lagged velocity absorbs. Found when the shift is at least MIN_OFFSET_S and
                   SHIFT_Z jackknife spreads (over groups of tests) from zero, and realigning cuts the fit's RMS
                   by MIN_FALL. Sine tests only: on random-content tests the rig's own 2 ms hydraulic
                   lag was taken for a 1.9 ms delay (not testable there). And only a constant delay
                   (issue 50): estimated frequency by frequency, the delays must agree within their
                   spreads (delay_constancy); a lag that grows or shrinks with frequency (lost motion,
                   compressibility, a filter) is not a recording delay, and the uncertainty is at
                   least what the per-frequency delays' scatter allows.
  run_order_drift  a regression of the residual on the run order (alone, times the predicted
                   force, times velocity), scored like a candidate (held out, against the null)
                   beyond the motion's history (the leftover test's other columns join the
                   baseline: a hysteresis larger at slow tests is not a drift); found when significant.
                   Only on a run order the data state (dampnet.data.runorder: a run_order or
                   started manifest column) that frequency, stroke and control do not explain
                   (order_freedom): else not testable, with the reason (issue 50).
  sign_slip, unit_slip, sensor_offset  per-test consistency of the channels (channel_checks):
                   velocity against the displacement's derivative, the force's work and gain, and
                   each test's displacement zero (displacement_zero: a sine's centre or a rest,
                   never the mean of a partial cycle, with the bound its own motion puts on it) and
                   its force at the velocity reversals (both ends alike) against the other tests'.
                   With a temperature channel the thermal candidate tests it instead.
"""

from __future__ import annotations

import numpy as np

from dampnet.data.artefacts import artefact
from dampnet.diagnosis import score as S
from dampnet.diagnosis.basis import SIGN_WIDTHS
from dampnet.diagnosis.catalogue import _x_frame, gas_columns_of
from dampnet.diagnosis.leftover import history_columns, run_order
from dampnet.data.units import G, INCH, LBF
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
    xs = ctx.at_rows("displacement")
    x_frame = _x_frame(ctx) if all(x is not None for x in xs) else None
    out = np.zeros((ctx.n_tests, len(HYDRAULIC_LAGS_S), 2 * k_max + 1))
    for i, td in enumerate(ctx.tests):
        t = td.test
        n = len(t)
        rows = np.arange(k_max, n - k_max, max(1, (n - 2 * k_max) // max_rows))
        v = t.channels["velocity"]
        # the force at t + k for every k: rows of a sliding window (contiguous gathers)
        Y = np.lib.stride_tricks.sliding_window_view(t.channels["force"], 2 * k_max + 1)[rows - k_max]
        YY = np.sum(Y * Y, axis=0)
        fixed = [np.ones(len(rows))] + [np.tanh(v[rows] / vmax / e) for e in SIGN_WIDTHS]
        x = t.channels.get("displacement")
        P = None
        if x is not None:  # position: the gas spring's polynomials and end-of-travel hinges (bump stops)
            P = gas_columns_of(x[rows], *x_frame)
            fixed += list(P.T)
        # the columns that do not depend on the hydraulic lag, and their products, once per test
        Xf = _unit_rms(np.stack(fixed, axis=1))
        Gff, Hf = Xf.T @ Xf, Xf.T @ Y
        for j, tau in enumerate(HYDRAULIC_LAGS_S):
            vh = (first_order_lag(v, t.dt, tau) if tau > 0 else v)[rows] / vmax
            cols = [vh[:, None], np.maximum(vh[:, None] - knots[None, :], 0.0)]
            if P is not None:  # a stop stiffer while compressing than releasing
                cols.append(P[:, 5:] * vh[:, None])
            Xl = _unit_rms(np.hstack(cols))
            Gfl = Xf.T @ Xl
            G = np.block([[Gff, Gfl], [Gfl.T, Xl.T @ Xl]])
            G += 1e-9 * np.trace(G) / G.shape[0] * np.eye(G.shape[0])
            H = np.vstack([Hf, Xl.T @ Y])
            B = np.linalg.solve(G, H)
            out[i, j] = YY - np.sum(B * H, axis=0)
    return out


def _unit_rms(X: np.ndarray) -> np.ndarray:
    """X's columns divided by their RMS."""
    return X / np.maximum(np.sqrt(np.mean(X * X, axis=0)), 1e-12)


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


def _jack(values: np.ndarray) -> float:
    g = len(values)
    return float(np.sqrt((g - 1) / g * np.sum((values - values.mean()) ** 2))) if g >= 2 else 0.0


def per_frequency_delays(ctx, per_test: np.ndarray, k_max: int, dt: float) -> list[dict]:
    """The shift estimated frequency by frequency [{frequency_hz, offset_s, spread_s (jackknife over
    the frequency's tests in up to GROUPS groups, at least a quarter sample; None for one test),
    tests}], in frequency order."""
    out = []
    freqs = sorted({td.test.frequency_hz for td in ctx.tests})
    for fz in freqs:
        idx = [i for i, td in enumerate(ctx.tests) if td.test.frequency_hz == fz]
        shift, _ = _best(per_test[idx].sum(0), k_max)
        g = min(GROUPS, len(idx))
        spread = None
        if g >= 2:
            loo = np.asarray([_best(per_test[[idx[j] for j in range(len(idx)) if j % g != k]].sum(0), k_max)[0]
                              for k in range(g)])
            spread = max(_jack(loo) * dt, 0.25 * dt)
        out.append({"frequency_hz": fz, "offset_s": shift * dt, "spread_s": spread, "tests": len(idx)})
    return out


#: a recording delay is the same at every frequency: the per-frequency estimates must agree within
#: their spreads plus CONSTANT_REL_TOL of the delay (the per-frequency estimate's own model error:
#: a 10 ms delay on the rig was estimated 9.1 to 11.2 ms frequency by frequency), at p >= CONSTANT_P
CONSTANT_REL_TOL = 0.15
CONSTANT_P = 0.001


def delay_constancy(by_f: list[dict], dt: float) -> dict:
    """Whether the per-frequency delays are one constant delay: a chi-square of their deviations from
    their weighted mean (each weighted by its jackknife spread, widened by CONSTANT_REL_TOL of the mean
    delay; one test's frequency takes the median spread), and the standard error of that mean from the
    delays' own scatter (inflated by sqrt(chi2 / dof) of the raw spreads when they scatter more than
    their spreads allow). {"testable", "constant", "p_value", "mean_s", "se_s", "words"}."""
    from scipy.stats import chi2 as _chi2

    est = [b for b in by_f]
    if len(est) < 2:
        return {"testable": False, "constant": True, "note": "one frequency: the delay's constancy over "
                "frequency cannot be checked"}
    known = [b["spread_s"] for b in est if b["spread_s"] is not None]
    d = np.asarray([b["offset_s"] for b in est])
    words = ", ".join(f"{1000 * b['offset_s']:.1f} ms at {b['frequency_hz']:g} Hz" for b in est)
    if len(known) < 2:   # one test per frequency: no spread to judge the agreement by
        return {"testable": False, "constant": True, "words": words,
                "se_s": float(np.std(d, ddof=1) / np.sqrt(len(d))),
                "note": "fewer than two frequencies with two tests or more: the delays' agreement over "
                        "frequency cannot be judged; the uncertainty is their scatter's standard error"}
    fill = float(np.median(known))
    sd = np.asarray([b["spread_s"] if b["spread_s"] is not None else fill for b in est])
    w = 1.0 / sd ** 2
    mean = float(np.sum(w * d) / np.sum(w))
    wide = np.sqrt(sd ** 2 + (CONSTANT_REL_TOL * mean) ** 2)
    ww = 1.0 / wide ** 2
    mean_w = float(np.sum(ww * d) / np.sum(ww))
    chi = float(np.sum(((d - mean_w) / wide) ** 2))
    dof = len(est) - 1
    p = float(_chi2.sf(chi, dof))
    raw_chi = float(np.sum(((d - mean) / sd) ** 2))
    se = float(np.sqrt(1.0 / np.sum(w)) * max(1.0, np.sqrt(raw_chi / dof)))
    return {"testable": True, "constant": p >= CONSTANT_P, "p_value": p, "chi2": chi, "dof": dof,
            "mean_s": mean, "se_s": se, "words": words}


def time_offset(ctx) -> dict:
    """The force's time offset against the motion (see the module doc), with its jackknife spread."""
    if any(td.test.frequency_hz is None for td in ctx.tests):
        # measured: on random-content tests (track replays, band-limited noise) the rig's own 2 ms
        # hydraulic lag was taken for a 1.9 ms recording delay; the friction flip that tells them
        # apart is clean only at a sine's two reversals per cycle
        return {"artefact": "time_offset", "testable": False, "detected": False,
                "note": "needs sine tests (random-content tests do not separate a delay from a lag)"}
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
    # a recording delay is one constant: estimated frequency by frequency it must agree within its
    # spread (a lag that grows or shrinks with frequency is lost motion, compressibility, a filter),
    # and its uncertainty is at least what that spread allows
    by_f = per_frequency_delays(ctx, per_test, k_max, dt)
    const = delay_constancy(by_f, dt)
    if "se_s" in const:
        spread_s = max(spread_s, const["se_s"])
    shifted = bool(abs(offset_s) >= MIN_OFFSET_S and abs(offset_s) >= SHIFT_Z * spread_s and fall >= MIN_FALL)
    detected = shifted and const["constant"]
    late = "late" if offset_s > 0 else "early"
    sentence = (f"the force channel is recorded {1000 * abs(offset_s):.1f} +- {1000 * spread_s:.1f} ms {late} "
                f"against the motion (the seal friction's flip at velocity reversals moves with it, which no "
                f"hydraulic lag does; frequency by frequency {const.get('words', 'one frequency')}); realigned, a "
                f"static fit of the force per test falls from {rms_at_zero:.1f} to "
                f"{rms_aligned:.1f} N RMS ({100 * fall:.0f} %). Fix: {artefact('time_offset').fix} "
                f"(--align-force-s {offset_s:.4g})")
    note = ""
    # a shift large enough to matter (the z gate aside: the delays' own scatter widens it), not one delay
    if not const["constant"] and abs(offset_s) >= MIN_OFFSET_S and fall >= MIN_FALL:
        note = (f"a lag that changes with frequency ({const['words']}; not one delay: chi2 {const['chi2']:.1f} on "
                f"{const['dof']} dof, p {const['p_value']:.1g}), not a constant recording delay: lost motion, "
                "compressibility or a filter, which realigning by one time would not fix")
    return {"artefact": "time_offset", "testable": True, "detected": detected, "offset_s": offset_s,
            "constant_over_frequency": const, "note": note,
            "uncertainty_s": spread_s, "hydraulic_lag_s": HYDRAULIC_LAGS_S[j], "by_frequency": by_f,
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


def run_order_gain_percent(ctx) -> float:
    """The drift in the fix's own terms (dampnet.data.artefacts.remove_run_order_drift): each test's
    gain g_i = <F, pred> / <pred, pred> of its measured force over the model's, a line g_0 (1 +
    p/100 s_i) fitted over its place s_i in [0, 1] of the run order; returns p [%], the force's change from the first test
    to the last (0 for fewer than 2 tests)."""
    from dampnet.data.runorder import run_positions

    n = ctx.n_tests
    if n < 2:
        return 0.0
    gains = []
    for td in ctx.tests:
        pred, f = td.pred[td.rows], td.test.channels["force"][td.rows]
        gains.append(float(f @ pred / max(float(pred @ pred), 1e-300)))
    pos = run_positions([td.test for td in ctx.tests])   # the stated run order, as the fix applies it
    slope, start = np.polyfit(pos, np.asarray(gains), 1)
    return float(100.0 * slope / start) if start > 0 else 0.0


#: a stated run order is testable for a drift only if frequency and control (and stroke) leave at
#: least this share of its variance unexplained (an additive fit, each a category): on a 12 x 15
#: grid a campaign sorted by frequency and control has 0, one sorted by frequency with the controls
#: shuffled in each 0.006, a shuffled one 0.86 on average (5 x 8: 0.73, the least of 200 shuffles 0.43)
MIN_ORDER_FREEDOM = 0.10


def order_freedom(tests, pos: np.ndarray) -> float:
    """1 - R^2 of the run order on frequency, stroke and control, each a category (additive least
    squares): how much of the order is not a function of the test's settings."""
    cols = [np.ones(len(pos))]
    for key in (lambda t: t.frequency_hz, lambda t: t.amplitude_m, lambda t: t.control_nominal):
        vals = [key(t) for t in tests]
        levels = sorted({v for v in vals if v is not None}) + ([None] if None in vals else [])
        for lv in levels[1:]:
            cols.append(np.asarray([v == lv for v in vals], dtype=np.float64))
    X = np.stack(cols, axis=1)
    y = np.asarray(pos, dtype=np.float64)
    beta, *_ = np.linalg.lstsq(X, y, rcond=None)
    ss = float(np.sum((y - y.mean()) ** 2))
    return float(np.sum((y - X @ beta) ** 2) / ss) if ss > 0 else 0.0


def _not_testable(note: str) -> dict:
    return {"artefact": "run_order_drift", "testable": False, "detected": False, "note": note}


def run_order_drift(ctx, folds, n_surrogates: int, seed: int) -> dict:
    """A drift of the force along the run order that no channel explains (see the module doc).
    Only on a stated run order (dampnet.data.runorder) that is not a function of the tests'
    settings: a manifest sorted by frequency or control is not a run order, and a drift along a
    run order that follows frequency cannot be told from a frequency dependence."""
    from dampnet.data.runorder import stated_run_order

    tests = [td.test for td in ctx.tests]
    pos, source = stated_run_order(tests)
    if pos is None:
        return _not_testable(source)
    free = order_freedom(tests, pos)
    if free < MIN_ORDER_FREEDOM:
        return {**_not_testable(f"the run order ({source}) follows the tests' frequency, stroke and control: they "
                                f"explain {100 * (1 - free):.0f} % of it, so a drift cannot be told from a dependence on "
                                "them (randomise the run order, or repeat a reference test through the campaign)"),
                "order_freedom": free}
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
    gain_pct = run_order_gain_percent(ctx)   # the force's change from the first test to the last
    detected = bool(res["significant"]) and not has_t
    sentence = (f"the force drifts along the run order: {gain_pct:+.1f} % from the first test to the last "
                f"(held out {100 * res['score']:.1f} % of the residual's variance beyond the motion's history, "
                f"z {res['z']:.1f}); no channel the model has explains it (thermal, but no temperature channel: "
                f"add one). Fix: {artefact('run_order_drift').fix} (here --run-order-drift-pct {gain_pct:.3g})")
    return {"artefact": "run_order_drift", "testable": True, "detected": detected, "run_order": source,
            "order_freedom": free, "significant": bool(res["significant"]), "score": float(res["score"]), "z": float(res["z"]),
            "force_change_percent": gain_pct, "temperature_channel": has_t,
            "fix": {"option": "--run-order-drift-pct", "value": gain_pct}, "sentence": sentence}


#: unit conversions a slipped channel is likely in (factor to SI): mm, in, lbf, kgf and their inverses
UNIT_FACTORS = (1e-3, INCH, LBF, G, 1e3, 1 / INCH, 1 / LBF, 1 / G)


def _unit(factor: float) -> float:
    """The known unit conversion within 15 % of an estimated factor, else the estimate."""
    best = min(UNIT_FACTORS, key=lambda u: abs(np.log(abs(factor) / u)) if factor else np.inf)
    return float(best) if factor and abs(np.log(abs(factor) / best)) < np.log(1.15) else float(factor)


REST_SHARE = 0.03  # a test's samples "at rest" for the force-zero check: |v| below this share of its peak
#: a rest segment (what defines a displacement zero without a sine): the test's start or end, still
#: (|v| below REST_SHARE of its peak) for at least this long [s] and at least this share of a cycle
REST_MIN_S = 0.25
REST_MIN_CYCLES = 1.0
#: a test's sine centre is fitted with these harmonics (a rig's stroke is not a pure sine)
CENTRE_HARMONICS = 3
OFFSET_Z = 6.0   # a zero moved: this many robust spreads of the other tests' zeros away


def _rest_segments(t) -> list[np.ndarray]:
    """The samples of the rest at the test's start and at its end (each when long enough)."""
    v = t.channels["velocity"]
    still = np.abs(v) < REST_SHARE * max(float(np.max(np.abs(v))), 1e-12)
    need = REST_MIN_S
    if t.frequency_hz:
        need = max(need, REST_MIN_CYCLES / t.frequency_hz)
    k = int(np.ceil(need / t.dt))
    out = []
    n = len(still)
    if n and still[0]:
        end = int(np.argmin(still)) if not still.all() else n
        if end >= k:
            out.append(np.arange(0, end))
    if n and still[-1] and not still.all():
        start = n - int(np.argmin(still[::-1]))
        if n - start >= k:
            out.append(np.arange(start, n))
    return out


def displacement_zero(t) -> dict:
    """What defines the zero of a test's displacement, never the mean of a partial cycle:

      centre  a sine test with at least one whole cycle of motion (its rests left out): the centre
              c of a least-squares fit x = c + sum over h = 1..CENTRE_HARMONICS of a_h sin(h w t)
              + b_h cos(h w t), whatever the cycle count (2.5 cycles of a sine have a mean of 0.13
              amplitudes, their centre 0); its uncertainty the most the fit's residual r (ramps,
              distortion, noise) can move c: sqrt([(X'X)^-1]_cc) |r| (Cauchy-Schwarz), what the
              test's own motion makes of a true zero
      rest    a test without such a sine that starts or ends at rest (REST_MIN_S): the position
              there; its uncertainty half the difference of the two rests (and the rest's scatter).
              Not for a sine test: a real table's sine may start from rest at the bottom of its
              stroke (measured: labcontrol's tests rest at 0 or at -18 mm, their sines centred at
              up to 12 mm), so its rest is where it waited, not its zero

    {"zero": m, "uncertainty": m, "from": "rest" | "centre"}, or {"zero": None, "note": why not}."""
    x = t.channels["displacement"]
    rests = _rest_segments(t)
    moving = np.ones(len(x), dtype=bool)
    for r in rests:
        moving[r] = False
    f = t.frequency_hz
    span = float(np.sum(moving)) * t.dt
    if not f or span * f < 1.0 - 1e-9:
        if rests:
            pos = [float(np.mean(x[r])) for r in rests]
            scatter = max(float(np.std(x[r])) for r in rests)
            return {"zero": float(np.mean(pos)), "uncertainty": max(0.5 * float(np.ptp(pos)), scatter), "from": "rest"}
        if not f:
            return {"zero": None, "note": "no rest at its start or end and no sine: nothing defines its zero"}
        return {"zero": None, "note": f"less than one whole cycle ({span * f:.2f}) and no rest"}
    x = x[moving]
    tt = (t.time - t.time[0])[moving]
    cols = [np.ones_like(tt)]
    for h in range(1, CENTRE_HARMONICS + 1):
        w = 2 * np.pi * f * h
        cols += [np.sin(w * tt), np.cos(w * tt)]
    X = np.stack(cols, axis=1)
    G = X.T @ X
    beta = np.linalg.solve(G, X.T @ x)
    r = x - X @ beta
    gcc = float(np.linalg.inv(G)[0, 0])
    return {"zero": float(beta[0]), "uncertainty": float(np.sqrt(max(gcc, 0.0)) * np.linalg.norm(r)), "from": "centre"}


def _force_at_reversals(f: np.ndarray, v: np.ndarray, x: np.ndarray | None, centre: float, lag: int) -> float | None:
    """The force at the velocity reversals (|v| below REST_SHARE of its peak), each end of the
    stroke weighted alike: the mean at the extended end and the mean at the compressed end,
    averaged (2.5 cycles have three reversals at one end and two at the other, and the gas force
    differs between the ends). Without a displacement, the reversals by the velocity's sign
    change. None when one end has no reversal."""
    rest = np.flatnonzero(np.abs(v) < REST_SHARE * max(float(np.max(np.abs(v))), 1e-12))
    rest = rest[(rest + lag < len(f)) & (rest + lag >= 0)]
    if not rest.size:
        return None
    if x is not None:
        top = x[rest] > centre
    else:
        a = np.gradient(v)
        top = a[rest] < 0        # decelerating through v = 0 from extension: the extended end
    ends = [rest[top], rest[~top]]
    if any(e.size == 0 for e in ends):
        return None
    return 0.5 * (float(np.mean(f[ends[0] + lag])) + float(np.mean(f[ends[1] + lag])))


def _robust_outliers(values: np.ndarray, floor: float, z: float = 6.0) -> np.ndarray:
    """Indices whose value is more than z robust spreads (1.4826 MAD, at least `floor`) from the median."""
    med = float(np.median(values))
    spread = max(1.4826 * float(np.median(np.abs(values - med))), floor)
    return np.flatnonzero(np.abs(values - med) > z * spread)


def _result(aid: str, hits: list[dict], what: str) -> dict:
    ids = [h["test_id"] for h in hits]
    sentence = (f"{what} in {len(ids)} test(s): " + "; ".join(h["words"] for h in hits[:5])
                + ("; ..." if len(hits) > 5 else "") + f". Fix: {artefact(aid).fix}") if hits else ""
    return {"artefact": aid, "testable": True, "detected": bool(hits), "tests": hits, "sentence": sentence}


def channel_checks(ctx, noise_rms_n: float, force_offset_s: float = 0.0) -> list[dict]:
    """sign_slip, unit_slip and sensor_offset, per test, from the channels' consistency:
    the velocity against the displacement's derivative (slope 1: -1 is a sign slip, 1000 a unit slip,
    and the force's work decides which channel slipped: a damper only dissipates, so F v > 0 on
    average), the force's gain against the model's prediction (a test in lbf: 1 / 4.448; only a
    gain within 15 % of a known unit conversion counts, the model may simply fit a test badly) and a
    test's mean displacement, or its force at the velocity reversals (the static force: gas and
    friction both ways), far from the other tests' of the same stroke (a moved sensor zero)."""
    signs, units, offsets = [], [], []
    has_x = all("displacement" in td.test.channels for td in ctx.tests)
    gains, zeros_x, means_r, rms_f = [], [], [], []
    for td in ctx.tests:
        t = td.test
        f, v = t.channels["force"], t.channels["velocity"]
        wv = float(np.mean(f * v))
        pred = td.pred
        gains.append(float(np.dot(f - f.mean(), pred - pred.mean()) / max(np.dot(pred - pred.mean(), pred - pred.mean()), 1e-30)))
        zero = displacement_zero(t) if has_x else {"zero": None, "note": "no displacement channel"}
        zeros_x.append(zero)
        # the force at the velocity reversals (both ends alike): the damper's static part (gas force
        # at the ends of the stroke, friction cancelling), the same in every test of the same stroke
        # (read force_offset_s later: a force recorded late, time_offset, is realigned first)
        centre = zero["zero"] if zero["zero"] is not None else (
            float(np.median(t.channels["displacement"])) if has_x else 0.0)
        means_r.append(_force_at_reversals(f, v, t.channels.get("displacement"), centre,
                                           int(round(force_offset_s / t.dt))))
        rms_f.append(float(np.sqrt(np.mean(f * f))))
        if not has_x:
            continue
        x = t.channels["displacement"]
        # the displacement the velocity integrates to (detrended: robust to noise, unlike dx/dt)
        xv = np.concatenate(([0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t.time))))
        tt = t.time - t.time.mean()
        detrend = lambda y: y - y.mean() - tt * np.dot(tt, y) / max(np.dot(tt, tt), 1e-30)  # noqa: E731
        xv, xc = detrend(xv), detrend(x)
        k = float(np.dot(xv, xc) / max(np.dot(xc, xc), 1e-30))  # 1: consistent
        xd = np.gradient(x, t.dt)
        wx = float(np.mean(f * xd))
        if k < -0.5:
            ch = "velocity" if wv < 0 < wx else "displacement" if wx < 0 < wv else "velocity or displacement"
            signs.append({"test_id": t.test_id, "channel": ch, "words": f"{t.test_id}: {ch} (the velocity integrates to {k:.2f} x the displacement)"})
        elif k > 0 and abs(np.log10(k)) > 1.5:
            ch = "velocity" if k > 1 else "displacement"   # which one reads 10^n too large
            factor = _unit(1.0 / k if ch == "velocity" else k)
            if factor not in UNIT_FACTORS:
                continue  # inconsistent, but by no unit's factor: not a unit slip
            units.append({"test_id": t.test_id, "channel": ch, "factor": factor,
                          "words": f"{t.test_id}: {ch} (the velocity integrates to {k:.4g} x the displacement; "
                                   f"fix factor {factor:.4g})"})
        if wv < 0 and wx < 0:
            signs.append({"test_id": t.test_id, "channel": "force",
                          "words": f"{t.test_id}: force (the damper would generate {-wv:.1f} W: a damper dissipates)"})
    g = np.asarray(gains)
    med = float(np.median(g))
    for i in np.flatnonzero(np.abs(np.log(np.maximum(np.abs(g), 1e-12) / max(abs(med), 1e-12))) > np.log(2.0)):
        tid = ctx.tests[i].test.test_id
        if g[i] < 0 or any(h["test_id"] == tid and h["channel"] == "force" for h in signs):
            continue  # a sign slip, not a unit
        factor = _unit(med / g[i])
        if factor not in UNIT_FACTORS:
            continue  # a test the model fits badly, not a unit: only a known conversion is a slip
        units.append({"test_id": tid, "channel": "force", "factor": factor,
                      "words": f"{tid}: force (gain {g[i] / med:.3g} of the other tests'; fix factor {factor:.4g})"})
    slipped = {h["test_id"] for h in signs + units}
    untestable = []   # (test id, channel, why its zero is not defined)
    if has_x:
        amp = np.median([np.std(td.test.channels["displacement"]) for td in ctx.tests])
        ok = [i for i, z in enumerate(zeros_x) if z["zero"] is not None]
        untestable += [(ctx.tests[i].test.test_id, "displacement", z["note"])
                       for i, z in enumerate(zeros_x) if z["zero"] is None]
        if len(ok) >= 3:
            zs = np.asarray([zeros_x[i]["zero"] for i in ok])
            for j in _robust_outliers(zs, floor=0.02 * amp, z=OFFSET_Z):
                i = ok[j]
                tid = ctx.tests[i].test.test_id
                d = float(zs[j] - np.median(zs))
                u = zeros_x[i]["uncertainty"]
                # beyond what the test's own motion makes of a true zero (the bound on its zero's error)
                if tid not in slipped and abs(d) > u:
                    how = "its rest" if zeros_x[i]["from"] == "rest" else "its sine's centre"
                    offsets.append({"test_id": tid, "channel": "displacement", "offset": d, "uncertainty": u,
                                    "words": f"{tid}: displacement zero ({how}) {1000 * d:+.2f} mm from the other "
                                             f"tests' (its own motion allows {1000 * u:.2f} mm)"})
    strokes: dict = {}
    for i, td in enumerate(ctx.tests):
        if means_r[i] is None:
            untestable.append((td.test.test_id, "force", "no velocity reversal at one end of its stroke"))
            continue
        strokes.setdefault(td.test.amplitude_m, []).append(i)
    for group in strokes.values():
        if len(group) < 5:
            continue
        rest = np.asarray([means_r[i] for i in group])
        for j in _robust_outliers(rest, floor=max(noise_rms_n, 1e-9)):
            tid = ctx.tests[group[j]].test.test_id
            # "at rest" is |v| < 3 % of the peak: the dynamic force there, which the two directions
            # cancel only in a symmetric damper, is up to ~3 % of the test's force (measured: 29 N of
            # a 1,665 N RMS test at 3 Hz and 0 V, no offset); a zero must stand out beyond twice that
            if tid not in slipped and abs(rest[j] - np.median(rest)) > 2 * REST_SHARE * rms_f[group[j]]:
                d = float(rest[j] - np.median(rest))
                offsets.append({"test_id": tid, "channel": "force", "offset": d,
                                "words": f"{tid}: force zero {d:+.1f} N from the other tests' (force at the "
                                         "velocity reversals)"})
    offset = _result("sensor_offset", offsets, "a sensor's zero moved")
    if untestable:
        offset["not_testable"] = [{"test_id": tid, "channel": ch, "note": why} for tid, ch, why in untestable]
    x_ok = has_x and sum(z["zero"] is not None for z in zeros_x) >= 3
    f_ok = any(len(g) >= 5 for g in strokes.values())
    if not (x_ok or f_ok):
        offset.update(testable=False, note="not testable here: fewer than 3 tests whose displacement zero is "
                      "defined (a rest, or a sine's whole cycle) and no 5 tests of one stroke with reversals at both "
                      "ends" + (": " + "; ".join(f"{tid} ({ch}): {why}" for tid, ch, why in untestable[:3])
                                + ("; ..." if len(untestable) > 3 else "") if untestable else ""))
    return [_result("sign_slip", signs, "a channel's sign slipped"),
            _result("unit_slip", units, "a channel is in another unit"), offset]


def find_artefacts(ctx, folds, n_surrogates: int, seed: int, noise_rms_n: float) -> list[dict]:
    """Every artefact test's result (JSON-ready), in the catalogue's order."""
    offset = time_offset(ctx)
    shift = offset["offset_s"] if offset.get("detected") else 0.0
    return [offset, run_order_drift(ctx, folds, n_surrogates, seed), *channel_checks(ctx, noise_rms_n, shift)]
