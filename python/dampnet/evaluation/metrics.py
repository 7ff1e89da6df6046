"""Error tables of a force model on dyno tests: overall, per test, per frequency (thesis Table 4).

Every function returns plain dicts/lists of floats with stable key names, so
that `dampnet evaluate --json`, the demo report and the diagnosis reuse them:

  overall        {n_tests, n_samples, force_range_n, rmse_n, nrmse, max_abs_error_n,
                  mean_abs_error_n, mean_pct_error}
  per_test       [{test_id, frequency_hz, amplitude_m, control, control_name,
                   n_samples, force_range_n, rmse_n, nrmse, max_abs_error_n,
                   mean_abs_error_n, mean_pct_error}, ...]   in the tests' order
  per_frequency  [{frequency_hz, controls, n_tests, n_samples, rmse_n, nrmse,
                   max_abs_error_n, mean_abs_error_n, mean_pct_error}, ...]  by frequency
  per_frequency_control  the same, one row per (frequency, nominal control)

Definitions (errors e = predicted - measured force, in N):
  rmse_n          sqrt(mean(e^2))
  nrmse           rmse_n / (max - min of the measured force): the thesis's Table 3
                  definition ("root mean squared error divided by max-min range of its
                  dataset"); per test the range is the test's own, overall the range of
                  all samples evaluated together.
  max_abs_error_n max |e| (thesis Table 4 "Maximum Error", here in N, not lbf)
  mean_pct_error  100 * mean|e| / mean|F_measured|, in %. The thesis's Table 4
                  "Average % Error" is not defined there; a per-sample mean of |e|/|F|
                  is unbounded near the force's zero crossings, so dampnet normalises
                  the mean absolute error by the mean absolute force of the same samples.
Tests with no frequency (random excitation) are grouped under frequency_hz None.
"""

from __future__ import annotations

from typing import Any, Callable, Iterable, Sequence

import numpy as np

LBF_PER_N = 1.0 / 4.4482216152605


def error_stats(y_pred: np.ndarray, y_true: np.ndarray) -> dict[str, float]:
    """rmse_n, nrmse, max_abs_error_n, mean_abs_error_n, mean_pct_error, force_range_n, n_samples."""
    y_pred = np.asarray(y_pred, dtype=np.float64).ravel()
    y_true = np.asarray(y_true, dtype=np.float64).ravel()
    if y_pred.shape != y_true.shape:
        raise ValueError(f"predicted ({y_pred.size}) and measured ({y_true.size}) forces differ in length")
    if y_true.size == 0:
        raise ValueError("no samples to evaluate")
    e = y_pred - y_true
    ae = np.abs(e)
    rmse = float(np.sqrt(np.mean(e * e)))
    span = float(np.ptp(y_true))
    mean_abs_f = float(np.mean(np.abs(y_true)))
    return {
        "n_samples": int(y_true.size),
        "force_range_n": span,
        "rmse_n": rmse,
        "nrmse": rmse / span if span > 0 else float("nan"),
        "max_abs_error_n": float(ae.max()),
        "mean_abs_error_n": float(ae.mean()),
        "mean_pct_error": 100.0 * float(ae.mean()) / mean_abs_f if mean_abs_f > 0 else float("nan"),
    }


def _group(rows: list[dict], preds: list[np.ndarray], trues: list[np.ndarray], key) -> list[dict]:
    groups: dict[Any, list[int]] = {}
    for i, r in enumerate(rows):
        groups.setdefault(key(r), []).append(i)

    def order(k):
        k = k if isinstance(k, tuple) else (k,)
        return tuple((v is None, v if v is not None else 0.0) for v in k)

    out = []
    for k in sorted(groups, key=order):
        idx = groups[k]
        s = error_stats(np.concatenate([preds[i] for i in idx]), np.concatenate([trues[i] for i in idx]))
        s.pop("force_range_n")
        row = {"frequency_hz": rows[idx[0]]["frequency_hz"]}
        if isinstance(k, tuple):
            row["control"] = rows[idx[0]]["control"]
        else:
            row["controls"] = sorted({rows[i]["control"] for i in idx if rows[i]["control"] is not None})
        row.update({"n_tests": len(idx), **s})
        out.append(row)
    return out


def evaluate_predictions(tests: Sequence[Any], preds: Sequence[np.ndarray]) -> dict[str, Any]:
    """Tables for predictions `preds[i]` [N] of `tests[i]` (DynoTest, measured force channel)."""
    if len(tests) == 0:
        raise ValueError("no tests to evaluate")
    if len(tests) != len(preds):
        raise ValueError(f"{len(tests)} tests but {len(preds)} predictions")
    trues = [np.asarray(t.channels["force"], dtype=np.float64) for t in tests]
    preds = [np.asarray(p, dtype=np.float64).ravel() for p in preds]
    per_test = []
    for t, p, y in zip(tests, preds, trues):
        if p.shape != y.shape:
            raise ValueError(f"test {t.test_id}: {p.size} predictions for {y.size} samples")
        per_test.append({"test_id": t.test_id,
                         "frequency_hz": None if t.frequency_hz is None else float(t.frequency_hz),
                         "amplitude_m": None if t.amplitude_m is None else float(t.amplitude_m),
                         "control": None if t.control_nominal is None else float(t.control_nominal),
                         "control_name": t.control_name,
                         **error_stats(p, y)})
    overall = {"n_tests": len(tests), **error_stats(np.concatenate(preds), np.concatenate(trues))}
    return {
        "overall": overall,
        "per_frequency": _group(per_test, preds, trues, lambda r: r["frequency_hz"]),
        "per_frequency_control": _group(per_test, preds, trues,
                                        lambda r: (r["frequency_hz"], r["control"])),
        "per_test": per_test,
    }


def evaluate_model(predict: Callable[[Any], np.ndarray], tests: Iterable[Any]) -> dict[str, Any]:
    """Tables for a force model given as `predict(test) -> force [N]` (see evaluate_predictions)."""
    tests = list(tests)
    return evaluate_predictions(tests, [predict(t) for t in tests])


def format_table(report: dict[str, Any], title: str = "", lbf: bool = False) -> str:
    """The per-frequency table (thesis Table 4 style) and the overall line, as text."""
    unit, k = ("lbf", LBF_PER_N) if lbf else ("N", 1.0)
    lines = [title] if title else []
    lines.append(f"{'frequency [Hz]':>14}  {'tests':>5}  {'NRMSE':>8}  {'max error [' + unit + ']':>16}  "
                 f"{'avg % error':>11}")
    for r in report["per_frequency"]:
        f = "-" if r["frequency_hz"] is None else f"{r['frequency_hz']:g}"
        lines.append(f"{f:>14}  {r['n_tests']:>5}  {r['nrmse']:>8.4f}  {r['max_abs_error_n'] * k:>16.2f}  "
                     f"{r['mean_pct_error']:>11.2f}")
    o = report["overall"]
    lines.append(f"{'overall':>14}  {o['n_tests']:>5}  {o['nrmse']:>8.4f}  {o['max_abs_error_n'] * k:>16.2f}  "
                 f"{o['mean_pct_error']:>11.2f}   (RMSE {o['rmse_n']:.2f} N over {o['n_samples']} samples)")
    return "\n".join(lines)
