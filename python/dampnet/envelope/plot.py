"""The coverage plot: a run's damper inputs over the model's training data (PNG, matplotlib Agg).

Two panels, (velocity, acceleration) and (velocity, control), in feature units: grey dots (drawn over
the runs), the envelope's stored training samples (without an envelope file: none); dashed, the training range
of each input (the model's saturation limits); each run's trajectory a thin line, its steps
outside the envelope (dampnet.envelope.coverage: outside a range, or farther than the joint threshold
from every training sample) marked with dots of the same colour.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from dampnet.figures import save_figure


def _pair_axes(model) -> list[tuple[int, int]]:
    """(x, y) input indices of the two panels: (velocity, acceleration) and (velocity, control),
    the control being the input the runtime reads from dn_damper_input.u (voltage or current);
    for other feature sets, the first input against each of the next two."""
    from dampnet.features import FEATURES

    names = list(model.features)

    def by_field(field: str) -> int | None:
        for i, f in enumerate(names):
            if f in FEATURES and FEATURES[f].field == field and FEATURES[f].state is None:
                return i
        return None

    v, a, u = by_field("v"), by_field("a"), by_field("u")
    pairs = [(v, a), (v, u)] if v is not None else []
    pairs = [p for p in pairs if p[1] is not None]
    if not pairs:
        n = len(names)
        pairs = [(0, j) for j in range(1, min(n, 3))] or [(0, 0)]
    return pairs


def outside_mask(model, X: np.ndarray, envelope=None) -> np.ndarray:
    """Steps outside the envelope: an input outside its training range, or (with an envelope)
    farther than its threshold from every stored training sample."""
    X = np.asarray(X, dtype=np.float64)
    out = np.any((X < model.sat_lo) | (X > model.sat_hi) | ~np.isfinite(X), axis=1)
    if envelope is not None:
        out |= envelope.far(X)   # distance > threshold, the k-d tree stopping at the threshold
    return out


def plot_coverage(model, runs: Mapping[str, np.ndarray], path, envelope=None, title: str = "",
                  max_points: int = 20000) -> None:
    """runs: label -> the run's inputs [n, n_inputs] (feature units, dampnet.envelope.coverage's
    quarter_car_inputs / fullcar_inputs); at most max_points steps of each are drawn."""
    import matplotlib

    matplotlib.use("Agg")  # files only, no display (as dampnet.sim.plots; not imported: it imports this)
    import matplotlib.pyplot as plt

    pairs = _pair_axes(model)
    fig, axes = plt.subplots(1, len(pairs), figsize=(5.5 * len(pairs), 4.6), squeeze=False)
    cloud = None
    if envelope is not None:
        cloud = (envelope.points - envelope.in_ymin) / envelope.in_gain + envelope.in_offset
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, (i, j) in zip(axes[0], pairs):
        if cloud is not None:
            ax.plot(cloud[:, i], cloud[:, j], ".", ms=1.5, color="0.65", label="training data (envelope)",
                    rasterized=True, zorder=3)
        lo, hi = model.sat_lo, model.sat_hi
        ax.plot([lo[i], hi[i], hi[i], lo[i], lo[i]], [lo[j], lo[j], hi[j], hi[j], lo[j]], "--", lw=0.8,
                color="0.1", label="training ranges", zorder=4)
        for k, (label, X) in enumerate(runs.items()):
            X = np.asarray(X, dtype=np.float64)
            step = max(1, X.shape[0] // max_points)
            Xs = X[::step]
            c = colors[k % len(colors)]
            ax.plot(Xs[:, i], Xs[:, j], lw=0.5, color=c, alpha=0.8, label=label)
            out = outside_mask(model, Xs, envelope)
            if out.any():
                ax.plot(Xs[out, i], Xs[out, j], ".", ms=2.5, color=c)
        ax.set_xlabel(f"{model.features[i]} [{model.units[i]}]")
        ax.set_ylabel(f"{model.features[j]} [{model.units[j]}]")
        ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=7, loc="best")
    note = "" if envelope is not None else " (no envelope file: training ranges only)"
    fig.suptitle((title or "coverage") + note + "; dots on a run: outside the envelope", fontsize=9)
    save_figure(fig, path, 110)
