"""Plots of full-vehicle runs (PNG, matplotlib Agg): several runs of one test overlaid
(label -> run, as dampnet.sim.full_car.runs.run returns); which one a test draws is its entry
in dampnet.recipes.maneuvers."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dampnet.sim.full_car.metrics import column, spectrum
from dampnet.sim.plots import _pyplot


def plot_bsst(runs: dict, path: str | Path, title: str = "Bounce sine sweep") -> None:
    """Body vertical acceleration over time and its amplitude spectrum."""
    plt = _pyplot()
    fig, ax = plt.subplots(2, 1, figsize=(9, 6.5))
    for label, r in runs.items():
        a = r["arrays"]
        ax[0].plot(a["t"], a["acc_z"], lw=0.5, label=label)
        f, s = spectrum(a["acc_z"], r["params"]["dt"])
        ax[1].loglog(f[1:], s[1:], lw=0.8, label=label)
    ax[0].set_xlabel("time [s] (sweep 0.5 → 20 Hz)")
    ax[0].set_ylabel("body vertical acc. [m/s²]")
    ax[1].set_xlabel("frequency [Hz]")
    ax[1].set_ylabel("acc. spectrum [m/s²/√Hz]")
    ax[1].set_xlim(0.5, 25)
    for x in ax:
        x.legend(fontsize=8)
        x.grid(alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_dlc(runs: dict, path: str | Path, title: str = "ISO 3888-1 double lane change") -> None:
    """The path among the cones (hit cones marked), lateral acceleration, roll, yaw rate."""
    plt = _pyplot()
    fig = plt.figure(figsize=(10, 8))
    top = fig.add_subplot(3, 1, 1)
    first = next(iter(runs.values()))
    man = first["maneuver"]
    cones = np.asarray(man["cones"])
    top.plot(cones[:, 0], cones[:, 1], "^", color="tab:orange", ms=5, label="cones")
    for label, r in runs.items():
        x = column(r["arrays"], "x_pos") + man["start_x_m"]
        top.plot(x, column(r["arrays"], "y_pos"), lw=1.0,
                 label=f"{label} ({r['metrics']['cones_hit']} cones hit)")
    top.set_xlim(-20, cones[:, 0].max() + 20)
    top.set_xlabel("x [m]")
    top.set_ylabel("y [m]")
    top.legend(fontsize=7, ncol=2)
    ax1 = fig.add_subplot(3, 1, 2)
    ax2 = fig.add_subplot(3, 1, 3, sharex=ax1)
    for label, r in runs.items():
        a = r["arrays"]
        ax1.plot(a["t"], a["a_y"], lw=0.8, label=label)
        ax2.plot(a["t"], np.degrees(column(a, "phi")), lw=0.8, label=f"roll {label}")
        ax2.plot(a["t"], np.degrees(column(a, "r")), lw=0.8, ls="--", label=f"yaw rate {label}")
    ax1.set_ylabel("lateral acc. [m/s²]")
    ax2.set_ylabel("roll [deg] / yaw rate [deg/s]")
    ax2.set_xlabel("time [s]")
    for x in (ax1, ax2):
        x.grid(alpha=0.3)
        x.legend(fontsize=7, ncol=2)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_road(runs: dict, path: str | Path, title: str = "Rough road") -> None:
    """Body vertical acceleration and roll rate over time."""
    plt = _pyplot()
    fig, ax = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for label, r in runs.items():
        a = r["arrays"]
        ax[0].plot(a["t"], a["acc_z"], lw=0.5, label=label)
        ax[1].plot(a["t"], np.degrees(column(a, "p")), lw=0.5, label=label)
    ax[0].set_ylabel("body vertical acc. [m/s²]")
    ax[1].set_ylabel("roll rate [deg/s]")
    ax[1].set_xlabel("time [s]")
    for x in ax:
        x.legend(fontsize=8)
        x.grid(alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
