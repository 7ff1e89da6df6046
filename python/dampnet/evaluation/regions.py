"""Where a model was guessing on measured data, and its error there (issue 53 item 3).

A model is judged by its overall error, which hides the places its training data were thin: a
damper standing still (no motion, often at the lowest control: the start and end of a real
record), or inputs outside its training envelope. On measured data both can be found and the
error there measured:

  at_rest_mask(v, t)        the samples where the damper stands still: |v| at most
                            REST_SPEED_FRACTION of the test's peak |v| (and at most
                            REST_SPEED_MAX_M_S) for REST_MIN_S or longer
  at_rest_errors(tests, preds, masks)
                            the error on those samples (any force model's)
  region_errors(model, tests, preds, envelope=None)
      -> {"at_rest": {share_time, n_samples, rmse_n, bias_n (mean of model - measured),
                      force_rms_n (the measured force's own change at rest within a test, RMS:
                      what a model of the inputs cannot follow), rmse_elsewhere_n, controls} or None,
          "outside_envelope": {share_time, rmse_n, rmse_inside_n, measure} ,
          "per_test": [{test_id, share_at_rest, rmse_at_rest_n, share_outside, rmse_outside_n}],
          "note": why a part is missing}
  summary_lines(regions)    what the commands print; share_text(share) a share of time in words

"At rest" is read from the model's own velocity input (the feature the runtime keeps as v), so
a dataset whose velocity is derived from displacement is judged as the model sees it; a model
without a velocity input gets no at-rest part ("not testable here"). A test that never moves at
all (its peak |v| under REST_SPEED_MAX_M_S) is at rest throughout.

"Outside the envelope" is dampnet.envelope.coverage's: outside a training range, or (with the
envelope file beside the model) farther than its threshold from every training sample.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

#: at rest: |v| at most this fraction of the test's peak |v| ...
REST_SPEED_FRACTION = 0.02
#: ... and never more than this [m/s] (a test that never exceeds it is still throughout)
REST_SPEED_MAX_M_S = 0.005
#: ... held this long [s] (a sine's reversal passes v = 0 in a few ms: not rest)
REST_MIN_S = 0.1


def at_rest_mask(v: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The samples of one test where the damper stands still (see the module docstring)."""
    v = np.asarray(v, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    if v.size == 0:
        return np.zeros(0, dtype=bool)
    peak = float(np.nanmax(np.abs(v)))
    slow = np.abs(v) <= min(REST_SPEED_FRACTION * peak, REST_SPEED_MAX_M_S) if peak > REST_SPEED_MAX_M_S \
        else np.isfinite(v)
    out = np.zeros(v.size, dtype=bool)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], slow.astype(np.int8), [0]])))
    for start, stop in zip(edges[::2], edges[1::2]):      # each run of slow samples [start, stop)
        if t[stop - 1] - t[start] >= REST_MIN_S:
            out[start:stop] = True
    return out


def _rmse(e: np.ndarray) -> float | None:
    return float(np.sqrt(np.mean(e * e))) if e.size else None


def _share(mask: np.ndarray, w: np.ndarray) -> float:
    total = float(np.sum(w))
    return float(np.sum(w[mask]) / total) if total > 0 else 0.0


def at_rest_errors(tests: Sequence[Any], preds: Sequence[np.ndarray], masks: Sequence[np.ndarray]) -> dict | None:
    """The error of force predictions `preds[i]` [N] on the at-rest samples `masks[i]` of `tests[i]`
    (at_rest_mask's): {share_time, n_samples, rmse_n, bias_n (mean of model - measured), force_rms_n
    (the measured force's own change at rest within a test, RMS), rmse_elsewhere_n, controls}; None
    when no sample is at rest. Any force model's: bench/real_data.py scores its peers with it."""
    from dampnet.envelope.coverage import step_durations

    err, dev, w, rest, controls = [], [], [], [], set()
    for test, pred, mask in zip(tests, preds, masks):
        y = np.asarray(test.channels["force"], dtype=np.float64)
        err.append(np.asarray(pred, dtype=np.float64).ravel() - y)
        dev.append(y[mask] - np.mean(y[mask]) if mask.any() else y[:0])   # the force's own change at rest
        w.append(step_durations(len(y), np.asarray(test.time, dtype=np.float64)))
        rest.append(mask)
        if mask.any() and test.control_nominal is not None:
            controls.add(float(test.control_nominal))
    e, d, w, rest = np.concatenate(err), np.concatenate(dev), np.concatenate(w), np.concatenate(rest)
    if not rest.any():
        return None
    return {"share_time": _share(rest, w), "n_samples": int(rest.sum()), "rmse_n": _rmse(e[rest]),
            "bias_n": float(np.mean(e[rest])), "force_rms_n": _rmse(d), "rmse_elsewhere_n": _rmse(e[~rest]),
            "controls": sorted(controls)}


def region_errors(model, tests: Sequence[Any], preds: Sequence[np.ndarray], envelope=None) -> dict[str, Any]:
    """The error at rest and outside the training envelope (see the module docstring); `preds[i]`
    the model's force [N] on `tests[i]` (DynoTests with a measured force)."""
    from dampnet.envelope.coverage import outside_steps, step_durations
    from dampnet.features import velocity_column
    from dampnet.predict import model_inputs

    j = velocity_column(model.features)
    per_test, rests, outs, err_all, w_all = [], [], [], [], []
    for test, pred in zip(tests, preds):
        X = model_inputs(model, test)
        e = np.asarray(pred, dtype=np.float64).ravel() - np.asarray(test.channels["force"], dtype=np.float64)
        w = step_durations(len(e), np.asarray(test.time, dtype=np.float64))
        rest = at_rest_mask(X[:, j], test.time) if j is not None else np.zeros(len(e), dtype=bool)
        out = outside_steps(model, X, envelope)
        per_test.append({"test_id": test.test_id, "share_at_rest": _share(rest, w) if j is not None else None,
                         "rmse_at_rest_n": _rmse(e[rest]), "share_outside": _share(out, w),
                         "rmse_outside_n": _rmse(e[out])})
        rests.append(rest), outs.append(out), err_all.append(e), w_all.append(w)
    out, e, w = np.concatenate(outs), np.concatenate(err_all), np.concatenate(w_all)
    res: dict[str, Any] = {"at_rest": at_rest_errors(tests, preds, rests) if j is not None else None,
                           "note": None, "per_test": per_test,
                           "definition": {"rest_speed_fraction": REST_SPEED_FRACTION,
                                          "rest_speed_max_m_s": REST_SPEED_MAX_M_S, "rest_min_s": REST_MIN_S}}
    if j is None:
        res["note"] = "at rest: not testable here (the model has no velocity input)"
    elif res["at_rest"] is None:
        res["note"] = f"at rest: not measured here (no sample stands still for {REST_MIN_S:g} s or longer)"
    res["outside_envelope"] = {"share_time": _share(out, w), "rmse_n": _rmse(e[out]), "rmse_inside_n": _rmse(e[~out]),
                               "measure": "ranges and joint envelope" if envelope is not None else "ranges"}
    return res


def share_text(share: float) -> str:
    """A share of time as a percentage for a line or a table cell: two significant digits under 1 %."""
    pct = 100 * share
    return f"{pct:.2g}" if pct < 1 else f"{pct:.1f}"


def _n(x: float | None) -> str:
    return "-" if x is None else f"{x:.1f} N"


def summary_lines(regions: dict[str, Any]) -> list[str]:
    """The lines `dampnet evaluate` prints: the error at rest and outside the envelope."""
    lines = []
    r = regions.get("at_rest")
    if r is not None:
        d = regions["definition"]
        lines.append(f"at rest (|v| under {100 * d['rest_speed_fraction']:g} % of the test's peak, at most "
                     f"{1e3 * d['rest_speed_max_m_s']:g} mm/s, for {d['rest_min_s']:g} s or longer): "
                     f"{100 * r['share_time']:.1f} % of the time, RMSE {_n(r['rmse_n'])} (bias {r['bias_n']:+.1f} N; "
                     f"the measured force there changes by {r['force_rms_n']:.1f} N RMS within a test) against "
                     f"{_n(r['rmse_elsewhere_n'])} elsewhere")
    elif regions.get("note"):
        lines.append(regions["note"])
    o = regions["outside_envelope"]
    if o["share_time"] >= 1.0:
        lines.append(f"outside the training envelope ({o['measure']}): all of the time (inputs the model was not "
                     "trained on, e.g. a control level between trained ones: its error here is the interpolation's)")
    elif o["share_time"] > 0:
        lines.append(f"outside the training envelope ({o['measure']}): {share_text(o['share_time'])} % of the time, "
                     f"RMSE {_n(o['rmse_n'])} there against {_n(o['rmse_inside_n'])} inside")
    else:
        lines.append(f"outside the training envelope ({o['measure']}): never")
    return lines
