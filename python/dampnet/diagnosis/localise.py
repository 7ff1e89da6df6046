"""Where the model fails: the error by test and within the cycle.

All numbers are RMS residuals [N] (residual = measured - predicted force) of a
region of the samples, with `ratio` = region RMS / overall RMS (above 1: the
model is worse there), so they can be read without the pictures.
"""

from __future__ import annotations

import numpy as np

from dampnet.evaluation.metrics import evaluate_predictions
from dampnet.evaluation.regions import at_rest_mask

N_WORST = 5


def overall_metrics(ctx) -> dict:
    rep = evaluate_predictions([td.test for td in ctx.tests], [td.pred for td in ctx.tests])
    worst = sorted(rep["per_test"], key=lambda r: -r["nrmse"] if r["nrmse"] == r["nrmse"] else 0)[:N_WORST]
    rep["worst_tests"] = [{"test_id": r["test_id"], "frequency_hz": r["frequency_hz"], "control": r["control"],
                           "nrmse": r["nrmse"], "rmse_n": r["rmse_n"], "max_abs_error_n": r["max_abs_error_n"]}
                          for r in worst]
    return rep


def _rms(x):
    return float(np.sqrt(np.mean(x * x))) if x.size else None


def binned(values: np.ndarray, resid: np.ndarray, n_bins: int = 12) -> dict:
    """Mean and RMS residual in quantile bins of `values`."""
    ok = np.isfinite(values)
    values, resid = values[ok], resid[ok]
    if values.size == 0 or np.ptp(values) == 0:
        return {"centres": [], "mean_n": [], "rms_n": [], "count": []}
    edges = np.unique(np.quantile(values, np.linspace(0, 1, n_bins + 1)))
    k = np.clip(np.searchsorted(edges, values, side="right") - 1, 0, len(edges) - 2)
    out = {"centres": [], "mean_n": [], "rms_n": [], "count": []}
    for b in range(len(edges) - 1):
        m = k == b
        if not np.any(m):
            continue
        out["centres"].append(float(np.mean(values[m])))
        out["mean_n"].append(float(np.mean(resid[m])))
        out["rms_n"].append(_rms(resid[m]))
        out["count"].append(int(np.sum(m)))
    return out


def _region(resid, mask, overall):
    r = _rms(resid[mask]) if np.any(mask) else None
    return {"rms_n": r, "ratio": None if r is None or overall == 0 else r / overall,
            "share_of_samples": float(np.mean(mask))}


def localise(ctx) -> dict:
    """RMS residual by region (see the module doc), binned residual against each channel."""
    r = np.concatenate(ctx.resid_rows())
    overall = _rms(r)
    v = np.concatenate(ctx.at_rows("velocity"))
    vmax = float(np.max(np.abs(v))) or 1.0
    out = {"overall_rms_n": overall, "regions": {}, "by_channel": {}}
    reg = out["regions"]
    reg["rebound"] = _region(r, v > 0, overall)
    reg["compression"] = _region(r, v < 0, overall)
    reg["near_zero_velocity"] = _region(r, np.abs(v) < 0.05 * vmax, overall)
    # standing still (dampnet.evaluation.regions: held for REST_MIN_S or longer, not a reversal); only
    # where the data do (a real record's still ends), never on sines that always move
    if all("velocity" in td.test.channels for td in ctx.tests):
        still = np.concatenate([at_rest_mask(td.test.channels["velocity"], td.test.time)[td.rows] for td in ctx.tests])
        if still.any():
            reg["at_rest"] = _region(r, still, overall)
    xs = ctx.at_rows("displacement")
    if all(x is not None for x in xs):
        x = np.concatenate(xs)
        lo, hi = np.percentile(x, [0.5, 99.5])
        c, h = 0.5 * (lo + hi), 0.5 * (hi - lo) or 1.0
        reg["near_end_of_travel"] = _region(r, np.abs(x - c) > 0.85 * h, overall)
        reg["mid_stroke"] = _region(r, np.abs(x - c) < 0.5 * h, overall)
    # around control steps: within 100 ms after a change of more than 5 % of the control's range
    name = ctx.control_name
    us = ctx.at_rows(name)
    if all(u is not None for u in us):
        span = float(np.ptp(np.concatenate([td.test.channels[name] for td in ctx.tests]))) or 1.0
        masks = []
        for td in ctx.tests:
            u = td.test.channels[name]
            du = np.abs(np.diff(u, prepend=u[0]))
            steps = np.nonzero(du > 0.05 * span)[0]
            near = np.zeros(len(u), bool)
            w = int(round(0.1 / td.test.dt))
            for s in steps:
                near[s:s + w] = True
            masks.append(near[td.rows])
        m = np.concatenate(masks)
        if np.any(m):
            reg["after_control_steps"] = _region(r, m, overall)
    tfrac = np.concatenate([(td.test.time[td.rows] - td.test.time[0]) / max(np.ptp(td.test.time), 1e-12)
                            for td in ctx.tests])
    reg["first_tenth_of_test"] = _region(r, tfrac < 0.1, overall)
    reg["last_tenth_of_test"] = _region(r, tfrac > 0.9, overall)
    by = out["by_channel"]
    for ch in ("displacement", "velocity", "acceleration", name, "temperature"):
        vals = ctx.at_rows(ch)
        if all(x is not None for x in vals):
            by[ch] = binned(np.concatenate(vals), r)
    by["time_fraction"] = binned(tfrac, r)
    # per test: RMS residual by frequency x control
    out["per_test_rms_n"] = [{"test_id": td.test.test_id, "frequency_hz": td.test.frequency_hz,
                              "control": td.test.control_nominal, "rms_n": _rms(td.resid)} for td in ctx.tests]
    return out
