"""Issue 55 item 3: semi-active control through the damper's inverse, measured against the ideal.

    python bench/control_study.py [--model default] [--classes B C D] [--speeds 40 80 120]
                                  [--no-full-car] [--out bench/control_study_results.json]
                                  [--plot bench/control_study.png] [--force]

Runs dampnet.recipes.control_study (its docstring says what each column is) and prints
the markdown tables bench/RESULTS.md holds. About a minute on two cores.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from dampnet.outputs import OutputError, atomic_write_bytes, atomic_write_text, check_output_files
from dampnet.sim.dampers import load_spec
from dampnet.recipes import control_study as cs


def _f(x, fmt="{:.3f}"):
    return "-" if x is None else fmt.format(x)


def tables(res: dict) -> list[str]:
    qc = res["quarter_car"]
    out = ["Quarter car, Wk-weighted body acceleration RMS [m/s^2] (law through the inverse / in range unfiltered / "
           "ideal semi-active / ideal active), and the law's comfort gain over passive low as a share of the ideal "
           "semi-active's:", "",
           "| road, km/h | passive low | passive high | skyhook_continuous | " + " | ".join(cs.FORCE_LAWS) + " |",
           "|---" * (4 + len(cs.FORCE_LAWS)) + "|"]
    for key, r in qc.items():
        cells = [key.replace("_", ", "), _f(r["passive_low"]["wk_rms_m_s2"]), _f(r["passive_high"]["wk_rms_m_s2"]),
                 _f(r["skyhook_continuous"]["wk_rms_m_s2"])]
        for law in cs.FORCE_LAWS:
            w = r[law]
            cells.append(" / ".join(_f(w[k]["wk_rms_m_s2"]) for k in ("model", "in_range_unfiltered",
                                                                       "ideal_semi_active", "ideal_active"))
                         + f" (gain {_f(w.get('gain_share'), '{:.2f}')})")
        out.append("| " + " | ".join(cells) + " |")
    out += ["", "Force tracking through the inverse: RMS error relative to the demand's RMS where reachable, with "
            "the registry's 5 ms command filter (and without it), and the share of demanding steps out of reach:", "",
            "| road, km/h | " + " | ".join(cs.FORCE_LAWS) + " |", "|---" * (1 + len(cs.FORCE_LAWS)) + "|"]
    for key, r in qc.items():
        out.append("| " + key.replace("_", ", ") + " | " + " | ".join(
            f"{_f(r[law]['model']['tracking_rel'], '{:.0%}')} ({_f(r[law]['in_range_unfiltered']['tracking_rel'], '{:.0%}')})"
            f" err, {_f(r[law]['model']['saturated_share'], '{:.0%}')} out of reach" for law in cs.FORCE_LAWS) + " |")
    out += ["", "Suspension travel RMS [mm] and dynamic tyre load RMS [N], law through the inverse:", "",
            "| road, km/h | passive low | skyhook_continuous | " + " | ".join(cs.FORCE_LAWS) + " |",
            "|---" * (3 + len(cs.FORCE_LAWS)) + "|"]
    for key, r in qc.items():
        tt = lambda m: f"{1e3 * m['travel_rms_m']:.1f} / {m['tyre_load_rms_n']:.0f}"  # noqa: E731
        out.append("| " + key.replace("_", ", ") + " | " + tt(r["passive_low"]) + " | " + tt(r["skyhook_continuous"])
                   + " | " + " | ".join(tt(r[law]["model"]) for law in cs.FORCE_LAWS) + " |")
    if res["full_car"]:
        first = next(iter(res["full_car"].values()))
        out += ["", "Full car, road manoeuvre (two correlated tracks): heave Wk RMS [m/s^2] / roll rate RMS [deg/s] / "
                "pitch rate RMS [deg/s]:", "", "| road, km/h | " + " | ".join(first) + " |",
                "|---" * (1 + len(first)) + "|"]
        for key, rows in res["full_car"].items():
            out.append("| " + key.replace("_", ", ") + " | " + " | ".join(
                f"{m['heave_wk_rms_m_s2']:.3f} / {m['roll_rate_rms_deg_s']:.2f} / {m['pitch_rate_rms_deg_s']:.2f}"
                for m in rows.values()) + " |")
    return out


def plot(res: dict, path: Path, overwrite: bool = False) -> None:
    """Wk RMS relative to passive low, per road class (a panel each) against speed: each law through
    the inverse (solid) beside its ideal semi-active damper (dashed), and skyhook_continuous."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    qc = res["quarter_car"]
    classes = sorted({k.split("_")[0] for k in qc})
    fig, axes = plt.subplots(1, len(classes), figsize=(4.2 * len(classes), 3.8), sharey=True, squeeze=False)
    colors = dict(zip(cs.FORCE_LAWS, ("C0", "C1", "C2", "C3")))
    for ax, c in zip(axes[0], classes):
        keys = [k for k in qc if k.startswith(c + "_")]
        sp = [qc[k]["speed_kmh"] for k in keys]
        low = [qc[k]["passive_low"]["wk_rms_m_s2"] for k in keys]
        rel = lambda vals: [v / lo for v, lo in zip(vals, low)]  # noqa: E731
        ax.axhline(1.0, color="k", lw=1, label="passive low")
        ax.plot(sp, rel([qc[k]["skyhook_continuous"]["wk_rms_m_s2"] for k in keys]), "k:", marker="s",
                label="skyhook_continuous")
        for law in cs.FORCE_LAWS:
            ax.plot(sp, rel([qc[k][law]["model"]["wk_rms_m_s2"] for k in keys]), "-", marker="o", color=colors[law],
                    label=f"{law} (through the inverse)")
            ax.plot(sp, rel([qc[k][law]["ideal_semi_active"]["wk_rms_m_s2"] for k in keys]), "--", marker="x",
                    color=colors[law], label=f"{law}, ideal semi-active")
        ax.set_title(f"ISO 8608 class {c}")
        ax.set_xlabel("speed [km/h]")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("Wk body acceleration RMS / passive low [-]")
    axes[0][-1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    fig.suptitle("Quarter car, default model: the force laws through the damper's inverse against the ideal")
    fig.tight_layout()
    atomic_write_bytes(path, lambda f: fig.savefig(f, format="png", dpi=110), overwrite=overwrite)
    plt.close(fig)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--model", default="default")
    p.add_argument("--classes", nargs="+", default=list(cs.ROAD_CLASSES))
    p.add_argument("--speeds", nargs="+", type=float, default=list(cs.SPEEDS_KMH))
    p.add_argument("--no-full-car", action="store_true")
    p.add_argument("--out", default=None, help="write the study as JSON here")
    p.add_argument("--plot", default=None, help="draw the quarter car's comfort against the ideal here (PNG)")
    p.add_argument("--force", action="store_true", help="replace --out and --plot when they exist (regular files only)")
    a = p.parse_args(argv)
    try:  # every output checked before the study runs
        check_output_files({"--out": a.out, "--plot": a.plot}, force=a.force)
    except OutputError as e:
        print(f"control_study: error: {e}", file=sys.stderr)
        return 2
    t0 = time.time()
    res = cs.run(load_spec(a.model), a.classes, a.speeds, full_car=not a.no_full_car,
                 progress=lambda s: print(f"  {s}", file=sys.stderr))
    res["seconds"] = time.time() - t0
    if a.out:
        atomic_write_text(Path(a.out), json.dumps(res, indent=1), overwrite=a.force)
    if a.plot:
        plot(res, Path(a.plot), overwrite=a.force)
    print("\n".join(tables(res)))
    print(f"\n({res['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
