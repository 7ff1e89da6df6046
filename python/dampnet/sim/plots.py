"""Plots of quarter-car runs and of a study (PNG, matplotlib with the Agg backend)."""

from __future__ import annotations

from pathlib import Path

from dampnet.figures import save_figure


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_run(run: dict, path, title: str = "") -> None:
    """Time histories of one run (road, sprung displacement, sprung acceleration, travel) as PNG."""
    plt = _pyplot()
    a = run["arrays"]
    fig, ax = plt.subplots(4, 1, figsize=(9, 8), sharex=True)
    ax[0].plot(a["t"], a["z_r"] * 1e3, lw=0.7)
    ax[0].set_ylabel("road [mm]")
    ax[1].plot(a["t"], a["z_s"] * 1e3, lw=0.7)
    ax[1].set_ylabel("sprung disp. [mm]")
    ax[2].plot(a["t"], a["acc_s"], lw=0.7)
    ax[2].set_ylabel("sprung acc. [m/s²]")
    ax[3].plot(a["t"], (a["z_s"] - a["z_us"]) * 1e3, lw=0.7)
    ax[3].set_ylabel("travel [mm]")
    ax[3].set_xlabel("time [s]")
    fig.suptitle(title or run.get("damper", ""))
    save_figure(fig, path, 110)


def plot_overlay(runs: dict, path, title: str, key: str = "acc_s", ylabel: str = "sprung acc. [m/s²]") -> None:
    """One channel of several runs (name -> run) on one axis, as PNG."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(9, 3.5))
    for name, r in runs.items():
        ax.plot(r["arrays"]["t"], r["arrays"][key], lw=0.7, label=name)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend()
    save_figure(fig, path, 110)


def plot_transmissibility(runs: dict, path, title: str = "Transmissibility z_s / z_r") -> None:
    """The transmissibility of several sweep runs (name -> run) on log axes, as PNG."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    for name, r in runs.items():
        tr = r["transmissibility"]
        ax.loglog(tr["f_hz"], tr["magnitude"], lw=0.8, label=name)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("|z_s / z_r|")
    ax.set_title(title)
    ax.grid(True, which="both", lw=0.3)
    ax.legend()
    save_figure(fig, path, 110)


def write_plots(res: dict, out_dir) -> list:
    """Plots of a study run with keep_runs=True: overlays per case and transmissibility."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    runs = res.get("_runs", {})
    for section, cases in runs.items():
        for case, by_model in cases.items():
            p = out / f"{section}_{case}.png"
            plot_overlay(by_model, p, f"{section} {case}")
            written.append(p)
            if section == "sine_sweep":
                p = out / f"transmissibility_{case}.png"
                plot_transmissibility(by_model, p, f"Transmissibility, {case} damping")
                written.append(p)
    written += write_coverage_plots(res, out)
    return written


def write_coverage_plots(res: dict, out_dir) -> list:
    """coverage_<model>.png for each neural model of a study run with keep_runs=True: the damper
    inputs of each section's first case over the model's training data (dampnet.envelope.plot)."""
    from dampnet.envelope.coverage import quarter_car_inputs
    from dampnet.envelope.plot import plot_coverage

    written = []
    runs, specs = res.get("_runs", {}), res.get("_specs", {})
    for name, spec in specs.items():
        if spec.kind not in ("neural", "hybrid"):
            continue
        traj = {}
        for section, cases in runs.items():
            for case, by_model in cases.items():
                if name in by_model and "coverage" in by_model[name]:
                    traj[f"{section} {case}"] = quarter_car_inputs(spec.obj, by_model[name]["arrays"])
                    break
        if traj:
            p = Path(out_dir) / f"coverage_{name}.png"
            plot_coverage(spec.obj, traj, p, spec.meta.get("envelope"), f"{name}: damper inputs of the study's runs")
            written.append(p)
    return written
