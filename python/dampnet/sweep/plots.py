"""Plots of a sweep's main sensitivities (matplotlib, PNG): one panel per varied parameter.

Each panel shows the objective of every ok cell against the parameter's values (dots) and its
mean per value (line), or for a number with many values (random draws) the least-squares line; panels in the order of the summary's sensitivity (largest spread first),
at most MAX_PANELS.
"""

from __future__ import annotations

from pathlib import Path

from dampnet.figures import save_figure

MAX_PANELS = 8


def sensitivity_png(df, kind: str, objective: str, sens: list[dict], path: Path) -> bool:
    """Write the PNG of `kind`'s sensitivities; False (nothing written) when nothing varies."""
    panels = sens[:MAX_PANELS]
    if not panels:
        return False
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    ok = df[(df["kind"] == kind) & (df["status"] == "ok")]
    ncol = min(4, len(panels))
    nrow = (len(panels) + ncol - 1) // ncol
    fig, axes = plt.subplots(nrow, ncol, figsize=(3.6 * ncol, 3.4 * nrow), squeeze=False)
    for ax, s in zip(axes.flat, panels):
        name = s["parameter"]
        if "slope" in s:                        # a number with many values (random draws): a scatter
            sub = ok[[name, objective]].dropna()
            x = sub[name].astype(float).to_numpy()
            ax.plot(x, sub[objective], ".", alpha=0.6)
            xs = np.array(s["range"])
            ax.plot(xs, sub[objective].mean() + s["slope"] * (xs - x.mean()), "-", color="tab:red",
                    label="least squares")
        else:
            labels = [lv["value"] for lv in s["levels"]]
            numeric = _numeric(labels)
            order = np.argsort(numeric) if numeric is not None else np.arange(len(labels))
            labels = [labels[i] for i in order]
            pos = {v: i for i, v in enumerate(labels)}
            sub = ok[[name, objective]].dropna()
            xs = np.array([pos[str(v)] for v in sub[name]], dtype=float)
            jitter = (np.arange(xs.size) % 5 - 2) * 0.04
            ax.plot(xs + jitter, sub[objective], ".", alpha=0.6, color="tab:blue")
            means = {lv["value"]: lv["mean"] for lv in s["levels"]}
            ax.plot(range(len(labels)), [means[v] for v in labels], "-o", color="tab:red", label="mean")
            ax.set_xticks(range(len(labels)))
            ax.set_xticklabels(labels, rotation=30 if max(len(v) for v in labels) > 6 else 0,
                               ha="right" if max(len(v) for v in labels) > 6 else "center", fontsize=8)
        ax.set_xlabel(name)
        ax.set_ylabel(objective)
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[len(panels):]:
        ax.set_visible(False)
    fig.suptitle(f"{kind}: {objective} by parameter ({len(ok)} ok cells)")
    save_figure(fig, path, 90, format="png")
    return True


def _numeric(labels: list[str]):
    try:
        return [float(v) for v in labels]
    except ValueError:
        return None
