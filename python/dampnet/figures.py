"""Saving a matplotlib figure, the one way dampnet's plots do it: laid out once, drawn once, closed."""

from __future__ import annotations

from pathlib import Path


def save_figure(fig, path, dpi: int, tight: bool = True, **savefig_kw) -> Path:
    """tight_layout the figure (not for one made with its own layout, e.g. layout="constrained"),
    savefig it to `path` at `dpi` (savefig_kw: e.g. format) and close it. tight_layout leaves a
    placeholder layout engine, for which savefig draws the whole figure a second time before
    printing it: it is removed, the same pixels in one draw."""
    import matplotlib.pyplot as plt

    if tight:
        fig.tight_layout()
        fig.set_layout_engine(None)
    fig.savefig(path, dpi=dpi, **savefig_kw)
    plt.close(fig)
    return Path(path)
