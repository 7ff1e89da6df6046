"""Plots of full-vehicle runs (PNG, matplotlib Agg): several runs of one test overlaid
(label -> run, as dampnet.sim.full_car.runs.run returns); which one a test draws is its entry
in dampnet.recipes.maneuvers."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dampnet.figures import save_figure
from dampnet.sim.full_car.metrics import column
from dampnet.sim.full_car.params import cg_to_axles
from dampnet.sim.plots import _pyplot


def _outside_spans(ax, r: dict) -> bool:
    """Shade the times a neural damper's inputs were outside its training envelope (any corner;
    the run's arrays["outside"], see runs.outside_mask); True when any was."""
    a = r["arrays"]
    if "outside" not in a:
        return False
    mask = np.asarray(a["outside"], dtype=bool)
    if not mask.any():
        return False
    t = np.asarray(a["t"])
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(int), 0]))
    for k0, k1 in zip(edges[::2], edges[1::2]):
        ax.axvspan(t[k0], t[min(k1, len(t) - 1)], color="tab:red", alpha=0.12, lw=0)
    return True


def plot_bsst(runs: dict, path: str | Path, title: str = "Bounce sine sweep") -> None:
    """The body's transmissibility (heave at the CG per road height; the pitch mode: pitch per
    road height) and the wheels', each run's estimate (metrics.bsst_response) beside the linear
    model's with the run's equivalent viscous damping; the body-mode and wheel-hop peaks marked
    with their frequency and gain; the body's response over time (times outside a neural
    damper's training envelope shaded)."""
    from dampnet.sim.full_car.metrics import bsst_response

    plt = _pyplot()
    fig, ax = plt.subplots(3, 1, figsize=(9, 10), gridspec_kw={"height_ratios": [3, 3, 2]})
    first = next(iter(runs.values()))
    mode = first["maneuver"].get("mode", "heave")
    for n, (label, r) in enumerate(runs.items()):
        man = _man(r)
        resp = bsst_response(r["arrays"], man, r["params"])
        m = r["metrics"]
        col = f"C{n}"
        for k, (key, peak) in enumerate((("body", "body"), ("wheel", "wheel_hop"))):
            ax[k].loglog(resp["f_hz"], np.abs(resp[key]), color=col, lw=1.2, label=label)
            at = (f" (at the peak: c {m[f'{peak}_equivalent_damping_n_s_m']:.0f} N s/m, "
                  f"k {m[f'{peak}_equivalent_stiffness_n_m']:.0f} N/m)" if m[f"{peak}_peak_hz"] is not None else "")
            ax[k].loglog(resp["f_lin_hz"], np.abs(resp[f"{key}_lin"]), color=col, lw=0.9, ls="--",
                         label="linear model, the dampers linearised at each frequency" + at)
            for suffix, mk in (("", "o"), ("_linear", "x")):
                f_pk, g_pk = m[f"{peak}_peak_hz{suffix}"], m[f"{peak}_peak_gain{suffix}"]
                if f_pk is not None:
                    ax[k].plot([f_pk], [g_pk], mk, color=col, ms=7, mfc="none" if mk == "o" else None)
            f_pk, g_pk = m[f"{peak}_peak_hz"], m[f"{peak}_peak_gain"]
            if f_pk is None:
                continue
            what = ("heave" if mode == "heave" else "pitch") if key == "body" else "wheel hop"
            ax[k].text(0.99 if key == "body" else 0.01, 0.97 - 0.08 * n,
                       f"{label}: {what} {f_pk:.2f} Hz, x{g_pk:.3g} (linear {m[f'{peak}_peak_hz_linear']:.2f} Hz, "
                       f"x{m[f'{peak}_peak_gain_linear']:.3g})", transform=ax[k].transAxes, fontsize=8, color=col,
                       ha="right" if key == "body" else "left", va="top")
        a = r["arrays"]
        body = column(a, "z" if mode == "heave" else "theta")
        ax[2].plot(a["t"], body * (1e3 if mode == "heave" else np.degrees(1.0)), lw=0.5, color=col, label=label)
        if _outside_spans(ax[2], r) and n == 0:
            ax[2].plot([], [], color="tab:red", alpha=0.3, lw=6, label="damper inputs outside the training envelope")
    unit = "m/m" if mode == "heave" else "rad/m"
    ax[0].set_ylabel(f"body {'heave at the CG' if mode == 'heave' else 'pitch'} / road [{unit}]")
    ax[1].set_ylabel("wheel / road [m/m]")
    for k in (0, 1):
        ax[k].set_xlabel("frequency [Hz]")
        ax[k].set_xlim(first["maneuver"].get("f0_hz", 0.5), first["maneuver"].get("f1_hz", 20.0))
        ax[k].grid(alpha=0.3, which="both")
        ax[k].legend(fontsize=7, loc="lower left")
    ax[0].set_title("transmissibility (o: peak of the run, x: of the linear model)", fontsize=9)
    ax[2].set_xlabel(f"time [s] (sweep {first['maneuver'].get('f0_hz', 0.5):g} → "
                     f"{first['maneuver'].get('f1_hz', 20.0):g} Hz)")
    ax[2].set_ylabel("body heave [mm]" if mode == "heave" else "body pitch [deg]")
    ax[2].grid(alpha=0.3)
    ax[2].legend(fontsize=7, loc="upper right")
    fig.suptitle(title)
    save_figure(fig, path, 110)


def _man(r: dict):
    """The run's manoeuvre again as a Maneuver (its road from the run's arrays)."""
    from dampnet.sim.full_car.maneuvers import Maneuver

    a = r["arrays"]
    return Maneuver(r.get("test", ""), r["params"]["dt"], np.asarray(a["road"]), np.zeros_like(a["road"]),
                    r["params"]["speed"], meta=dict(r["maneuver"]))


def _footprint(ax, x, y, psi, front, rear, half, **kw):
    c, s = np.cos(psi), np.sin(psi)
    pts = np.array([[front, half], [front, -half], [-rear, -half], [-rear, half], [front, half]])
    ax.plot(x + pts[:, 0] * c - pts[:, 1] * s, y + pts[:, 0] * s + pts[:, 1] * c, **kw)


def plot_dlc(runs: dict, path: str | Path, title: str = "ISO 3888-1 double lane change") -> None:
    """To scale (equal axes, in two halves): the lanes and their cones (hit ones marked), the
    driver's path, each run's CG track and its footprint every 0.5 s; then the thesis's Figure 60
    histories: lateral acceleration, roll, roll rate, yaw rate, side-slip (times outside a
    neural damper's training envelope shaded; the exit gate marked)."""
    from dampnet.sim.full_car.maneuvers import OVERHANG_FRONT_M, OVERHANG_REAR_M
    from dampnet.sim.full_car.metrics import cone_clearance

    plt = _pyplot()
    fig = plt.figure(figsize=(12, 14))
    gs = fig.add_gridspec(7, 1, height_ratios=[0.85, 0.85, 1, 1, 1, 1, 1])
    first = next(iter(runs.values()))
    man = first["maneuver"]
    cones = np.asarray(man["cones"])
    lanes = man["lanes"]
    x_end = lanes[-1]["x1"]
    span = 0.5 * (x_end + 30.0) + 3.0   # two halves of equal length (the same scale), overlapping 6 m
    halves = ((-12.0, -12.0 + span), (x_end + 18.0 - span, x_end + 18.0))
    tops = [fig.add_subplot(gs[k, 0]) for k in (0, 1)]
    hits = {}
    for label, r in runs.items():
        hits[label] = cone_clearance(r["arrays"], _man(r), r["params"]) <= 0.0
    for top, (x0, x1) in zip(tops, halves):
        for sec in lanes:
            if "y_right" in sec:
                for yl in (sec["y_right"], sec["y_left"]):
                    top.plot([sec["x0"], sec["x1"]], [yl, yl], color="0.6", lw=0.8)
                top.fill_between([sec["x0"], sec["x1"]], sec["y_right"], sec["y_left"], color="0.92", lw=0)
        top.plot(cones[:, 0], cones[:, 1], "^", color="tab:orange", ms=5, label="cones")
        if "path_x" in man:
            top.plot(np.asarray(man["path_x"]) + man["start_x_m"], man["path_y"], color="k", lw=0.7, ls=":",
                     label="driver's path")
        for n, (label, r) in enumerate(runs.items()):
            a, p = r["arrays"], r["params"]
            a_h, b_h = cg_to_axles(p)  # x, y are the whole car's CG
            col = f"C{n}"
            x = column(a, "x_pos") + man["start_x_m"]
            y, psi = column(a, "y_pos"), column(a, "psi")
            m = r["metrics"]
            top.plot(x, y, lw=1.0, color=col,
                     label=f"{label}: {m['cones_hit']} cones hit, clearance {100 * m['clearance_min_m']:+.0f} cm")
            every = max(1, int(round(0.5 / p["dt"])))
            for k in range(0, len(x), every):
                if x0 - 5 <= x[k] <= x1 + 5:
                    _footprint(top, x[k], y[k], psi[k], a_h + OVERHANG_FRONT_M, b_h + OVERHANG_REAR_M,
                               man["vehicle_width_m"] / 2, color=col, lw=0.5, alpha=0.7)
            if hits[label].any():
                top.plot(cones[hits[label], 0], cones[hits[label], 1], "x", color="tab:red", ms=9, mew=2,
                         label="hit" if n == 0 else None)
        top.set_xlim(x0, x1)
        top.set_ylim(-2.5, 6.5)
        top.set_aspect("equal")
        top.set_ylabel("y [m]")
        top.grid(alpha=0.25)
    tops[0].legend(fontsize=7, loc="upper left", ncol=2)
    tops[1].set_xlabel("x [m] (0: the entry gate; drawn to scale)")
    quantities = (("lateral acc. [m/s²]", lambda a: a["a_y"]),
                  ("roll [deg]", lambda a: np.degrees(column(a, "phi"))),
                  ("roll rate [deg/s]", lambda a: np.degrees(column(a, "p"))),
                  ("yaw rate [deg/s]", lambda a: np.degrees(column(a, "r"))),
                  ("side-slip [deg]", lambda a: np.degrees(a["beta"])))
    axes = []
    for k, (ylabel, fn) in enumerate(quantities):
        ax = fig.add_subplot(gs[2 + k, 0], sharex=axes[0] if axes else None)
        axes.append(ax)
        shaded = False
        for n, (label, r) in enumerate(runs.items()):
            a = r["arrays"]
            ax.plot(a["t"], fn(a), lw=0.9, color=f"C{n}", label=label)
            shaded = _outside_spans(ax, r) or shaded
            x = column(a, "x_pos") + man["start_x_m"]
            k_exit = int(np.searchsorted(x, x_end))
            if k_exit < len(x) and n == 0:
                ax.axvline(a["t"][k_exit], color="0.4", lw=0.7, ls="--")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
        if k == 0:
            if shaded:
                ax.plot([], [], color="tab:red", alpha=0.3, lw=6, label="damper inputs outside the training envelope")
            ax.plot([], [], color="0.4", lw=0.7, ls="--", label="exit gate")
            ax.legend(fontsize=7, ncol=3, loc="upper right")
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(title)
    save_figure(fig, path, 100)


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
    save_figure(fig, path, 110)
