"""PNG figures of a force model against dyno data (matplotlib, Agg backend; no display needed).

  error_histogram(errors, path)            distribution of force errors (thesis Fig. 35)
  test_figure(test, pred, path, ...)       predicted vs measured force over time, force-velocity
                                           and force-displacement loops of one test (Figs. 36-39)
  error_heatmap(report, path, key)         an error measure against frequency and control (heat map),
                                           replay / random tests in their own row
  test_heatmap(rows, key, path, ...)       the same for any per-test value (the diagnosis's residual)
  lookup_figure(table, path)               the lookup table's force-velocity curves (Fig. 43)

Each function writes one PNG and returns its path; units are SI (forces in N).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Sequence

import numpy as np

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from dampnet.figures import save_figure
from dampnet.features import FEATURES

DPI = 120


def _save(fig, path, tight: bool = True) -> Path:
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    # tight: not for a figure made with layout="constrained" (a colorbar shared by several axes)
    return save_figure(fig, p, DPI, tight=tight)


def error_histogram(errors: np.ndarray | dict[str, np.ndarray], path: str | os.PathLike,
                    title: str = "Error distribution of the predicted damper force",
                    bins: int = 40) -> Path:
    """Histogram of errors (predicted - measured) [N], with the zero-error line (thesis Fig. 35).

    `errors`: one array, or {label: array} to overlay several models (e.g. MLP and lookup table).
    """
    sets = errors if isinstance(errors, dict) else {"model": errors}
    allv = np.concatenate([np.asarray(v, dtype=np.float64).ravel() for v in sets.values()])
    lo, hi = np.percentile(allv, [0.1, 99.9]) if allv.size else (-1.0, 1.0)
    span = max(abs(lo), abs(hi), 1e-9)
    edges = np.linspace(-span, span, bins + 1)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for label, v in sets.items():
        v = np.asarray(v, dtype=np.float64).ravel()
        ax.hist(np.clip(v, edges[0], edges[-1]), bins=edges, alpha=0.6,
                label=f"{label} (RMS {np.sqrt(np.mean(v * v)):.1f} N)")
    ax.axvline(0.0, color="tab:red", linewidth=1.5, label="zero error")
    ax.set_xlabel("error = predicted - measured force [N]")
    ax.set_ylabel("samples")
    ax.set_title(title)
    ax.legend()
    return _save(fig, path)


def test_figure(test, pred: np.ndarray | dict[str, np.ndarray], path: str | os.PathLike,
                title: str | None = None) -> Path:
    """Measured and predicted force of one test: against time, velocity and displacement.

    `pred`: one array [N] or {label: array} (e.g. {"MLP": ..., "lookup table": ...}).
    """
    preds = pred if isinstance(pred, dict) else {"predicted": pred}
    t = np.asarray(test.time)
    f = np.asarray(test.channels["force"])
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.5))
    ax = axes[0]
    ax.plot(t, f, color="k", linewidth=1.0, label="measured")
    for label, p in preds.items():
        ax.plot(t, p, linewidth=1.0, label=label)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("force [N]")
    ax.set_title("force over time")
    ax.legend(loc="best")
    for ax, ch, xl in ((axes[1], "velocity", "velocity [m/s]"), (axes[2], "displacement", "displacement [m]")):
        if ch not in test.channels:
            ax.set_visible(False)
            continue
        x = np.asarray(test.channels[ch])
        ax.plot(x, f, color="k", linewidth=0.8, label="measured")
        for label, p in preds.items():
            ax.plot(x, p, linewidth=0.8, label=label)
        ax.set_xlabel(xl)
        ax.set_ylabel("force [N]")
        ax.set_title(f"force-{ch} loop")
        ax.legend(loc="best")
    if title is None:
        parts = [f"test {test.test_id}"]
        if test.frequency_hz is not None:
            parts.append(f"{test.frequency_hz:g} Hz")
        if test.control_nominal is not None:
            parts.append(f"{test.control_nominal:g} {'A' if test.control_name == 'current' else 'V'}")
        title = "Predicted vs measured force: " + ", ".join(parts)
    fig.suptitle(title)
    return _save(fig, path)


def error_heatmap(report: dict[str, Any], path: str | os.PathLike, key: str = "nrmse",
                  title: str | None = None) -> Path:
    """Heat map of `key` (e.g. nrmse, max_abs_error_n, mean_pct_error) against frequency and control,
    from a report's per_test rows (dampnet.evaluation.metrics.evaluate_predictions); tests without
    a frequency (track replay, random) in their own row below (`test_heatmap`)."""
    units = {"nrmse": "NRMSE [-]", "rmse_n": "RMSE [N]", "max_abs_error_n": "maximum |error| [N]",
             "mean_abs_error_n": "mean |error| [N]", "mean_pct_error": "average error [%]"}
    rows = report["per_test"]
    name = next((r["control_name"] for r in rows if r.get("control_name")), "voltage")
    return test_heatmap(rows, key, path, units.get(key, key), title or f"{units.get(key, key)} per test", name)


def test_heatmap(rows: Sequence[dict], key: str, path: str | os.PathLike, label: str, title: str,
                 control_name: str = "voltage") -> Path:
    """One value per test: sines as a grid (frequency x nominal control, tests of one cell
    averaged), tests without a frequency or a nominal control (track replay, random content) in
    their own row beneath, one cell per test named by its id; one colour scale for both."""
    grid_rows = [r for r in rows if r["frequency_hz"] is not None and r["control"] is not None]
    other = [r for r in rows if r["frequency_hz"] is None or r["control"] is None]
    freqs = sorted({r["frequency_hz"] for r in grid_rows})
    ctrls = sorted({r["control"] for r in grid_rows})
    grid = np.full((len(ctrls), len(freqs)), np.nan)
    acc: dict[tuple[int, int], list[float]] = {}
    for r in grid_rows:
        acc.setdefault((ctrls.index(r["control"]), freqs.index(r["frequency_hz"])), []).append(r[key])
    for (i, j), vals in acc.items():
        grid[i, j] = float(np.mean(vals))
    vals = [float(r[key]) for r in rows if r[key] is not None and np.isfinite(r[key])]
    vmin, vmax = (min(vals), max(vals)) if vals else (0.0, 1.0)
    unit = FEATURES[control_name].unit
    width = max(7.0, 1.5 + 0.6 * len(freqs), 1.5 + 1.6 * len(other))
    axes_h = [1.5 + 0.35 * max(len(ctrls), 4)] if grid_rows else []
    if other:
        axes_h.append(1.6)
    fig, axs = plt.subplots(len(axes_h), 1, figsize=(width, sum(axes_h) + 1.0 * len(axes_h)),
                            gridspec_kw={"height_ratios": axes_h}, squeeze=False, layout="constrained")
    axs = list(axs[:, 0])
    im = None
    if grid_rows:
        ax = axs.pop(0)
        im = ax.imshow(grid, origin="lower", aspect="auto", cmap="viridis", vmin=vmin, vmax=vmax)
        ax.set_xticks(range(len(freqs)), [f"{f:g}" for f in freqs], rotation=45)
        ax.set_yticks(range(len(ctrls)), [f"{c:g}" for c in ctrls])
        ax.set_xlabel("test frequency [Hz]")
        ax.set_ylabel(f"{control_name} [{unit}]")
        ax.set_title(title)
    if other:
        ax = axs.pop(0)
        strip = np.array([[float(r[key]) if r[key] is not None else np.nan for r in other]])
        im = ax.imshow(strip, aspect="auto", cmap="viridis", vmin=vmin, vmax=vmax)
        ax.set_xticks(range(len(other)), [r["test_id"] for r in other], rotation=20, ha="right", fontsize="small")
        ax.set_yticks([0], ["replay /\nrandom"])
        mid = 0.5 * (vmin + vmax)
        for j, r in enumerate(other):
            if r[key] is not None and np.isfinite(r[key]):
                ax.text(j, 0, f"{r[key]:.3g}", ha="center", va="center", fontsize="small",
                        color="k" if r[key] > mid else "w")
        if not grid_rows:
            ax.set_title(title)
        ax.set_xlabel("tests without one frequency (track replay, random content)")
    fig.colorbar(im, ax=fig.axes, label=label)
    return _save(fig, path, tight=False)   # constrained layout: the colorbar beside both axes


def lookup_figure(table, path: str | os.PathLike, voltages: Sequence[float] | None = None,
                  title: str = "Lookup-table damper model (peak force vs peak velocity)") -> Path:
    """Force-velocity curves of a LookupTable at its voltages (all, or the ones given)."""
    us = table.voltages if voltages is None else np.asarray(voltages, dtype=np.float64)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    unit = FEATURES[table.control_name].unit
    for u in us:
        ax.plot(table.velocities, table.column(u), marker="o", markersize=3, label=f"{u:g} {unit}")
    ax.axhline(0, color="0.7", linewidth=0.8)
    ax.axvline(0, color="0.7", linewidth=0.8)
    ax.set_xlabel("peak velocity [m/s] (negative: compression)")
    ax.set_ylabel("peak force [N]")
    ax.set_title(title)
    ax.legend(fontsize="small", ncol=2)
    return _save(fig, path)
