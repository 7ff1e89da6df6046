"""Semi-active control through the damper's inverse, measured against the ideal (issue 55 item 3).

On ISO 8608 roads (classes B, C, D; 40, 80, 120 km/h; one seed, ROAD_LENGTH_M each) the quarter
car runs, through the runtime's loop (`dampnet.sim.quarter_car.runs.simulate`), every law of
FORCE_LAWS on the damper model (its demanded force through the model's inverse) beside:
  passive_low, passive_high   the damper held at its own soft / hard setting
  skyhook_continuous          today's linear map of the wanted damping to a control
  ideal semi-active           the same law on an ideal damper: a lookup table whose force is its
                              control (F = u for any velocity, IDEAL_F_MAX_N either way), so the
                              inverse is exact and the force is the law's demand clipped to the
                              dissipative range (F v > 0, else 0), perfectly tracked, held over
                              each step as any command is
  ideal active                the same law's demand unclipped (an unconstrained force actuator in
                              place of the damper): the law is a linear state feedback, so the car
                              is linear and is integrated exactly (scipy.signal.lsim) over the
                              same road (check: the analytic RMS from the road's PSD and the
                              car's frequency response, `ideal_active_analytic`)
Reported per case: ISO 2631-1 Wk-weighted body acceleration RMS [m/s^2], suspension travel RMS
[m], dynamic tyre load RMS [N]; for each law through the inverse, its comfort gain over passive
low as a share of the ideal semi-active's (gain_share; target >= 0.9), and skyhook_continuous's
against skyhook_force's ideal semi-active (gain_share: today's linear map, measured beside the
inverse), the force-tracking error (RMS of
force - demand over the steps with a reachable demand, relative to the demand's RMS there) and
the share of demanding steps whose demand is out of the damper's reach at that motion.
The full car (`full_car_rows`): the road manoeuvre (two correlated tracks) at the same roads and
speeds, each vehicle damping setting: heave (Wk) acceleration, roll and pitch rate RMS.
The command: `dampnet study MODEL --control` (`text_tables`: what it prints and writes into
study.txt; `plot`: control_vs_ideal.png; bench/RESULTS.md holds the default model's).
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

from dampnet.figures import save_figure
from dampnet.sim.vehicle import Controller, Vehicle

ROAD_CLASSES = ("B", "C", "D")
SPEEDS_KMH = (40.0, 80.0, 120.0)
ROAD_LENGTH_M = 200.0
FORCE_LAWS = ("skyhook_force", "groundhook_force", "hybrid_force", "clipped_optimal")
BASELINES = ("passive_low", "passive_high", "skyhook_continuous")
#: the ideal damper's force range [N] either way (any demand of the quarter car is far inside)
IDEAL_F_MAX_N = 1e5
#: a comfort gain (passive low's Wk RMS minus the ideal's) below this share of passive low's is
#: reported as none (the ideal semi-active law gains nothing over passive low there)
MIN_IDEAL_GAIN = 0.005


def ideal_spec(f_max: float = IDEAL_F_MAX_N):
    """The ideal semi-active damper: a lookup table F(v, u) = u [N] for every velocity."""
    from dampnet.evaluation.lookup import LookupTable
    from dampnet.sim.dampers import lookup_spec

    u = np.array([-f_max, f_max])
    return lookup_spec(LookupTable(np.array([-10.0, 10.0]), u, np.column_stack([u, u])), name="ideal")


def ideal_controller(law: Controller, f_max: float = IDEAL_F_MAX_N) -> Controller:
    """`law` (its gains) on the ideal damper: the control is the force, 0 N without a demand
    (u_soft), limited to +-f_max, unfiltered (the ideal tracks at once)."""
    return dataclasses.replace(law, u_soft=0.0, u_hard=f_max, u_passive=0.0, u_min=-f_max, u_max=f_max, u_tau_s=0.0)


def feedback_row(ctrl: Controller) -> np.ndarray:
    """The law's unclipped demand as a state feedback F_d = K x [N], x = [travel z_s - z_us [m],
    v_s [m/s], tyre deflection z_us - z_r [m], v_us [m/s]]: the linear view of the runtime's
    formulas (dn_xmacro.h) the ideal active car needs; where the runtime's clip passes the demand
    (and hybrid_force's two parts both dissipate) K x is the runtime's _core.force_demand
    (tests/python/test_control_study.py)."""
    sky = np.array([0.0, ctrl.c_sky, 0.0, 0.0])
    gnd = np.array([0.0, 0.0, 0.0, -ctrl.c_gnd])
    return {"skyhook_force": sky, "groundhook_force": gnd,
            "hybrid_force": ctrl.alpha * sky + (1.0 - ctrl.alpha) * gnd,
            "clipped_optimal": np.array([ctrl.k_travel, ctrl.k_vs, ctrl.k_tyre, ctrl.k_vus])}[ctrl.kind]


def demand(ctrl: Controller, a: dict) -> np.ndarray:
    """The law's demanded damper force [N] at each step of a run's arrays, as the loop computed it
    (the runtime's force_demand: clipped to F v > 0, else 0)."""
    from dampnet import _core

    return _core.force_demand(ctrl.core_dict(), a["v_s"], a["v_us"], a["z_s"] - a["z_us"], a["z_us"] - a["z_r"])


def linear_car(veh: Vehicle, k_row: np.ndarray):
    """(A, E) of the linear quarter car under F = K x: x' = A x + E z_r' (lqr_design's model)."""
    from dampnet.sim.calibration import lqr_design

    A, B, *_ = lqr_design(veh)
    return A + B @ k_row[None, :], np.array([0.0, 0.0, -1.0, 0.0])


def ideal_active(veh: Vehicle, ctrl: Controller, t: np.ndarray, z_r: np.ndarray, v_r: np.ndarray) -> dict:
    """The law's demand as an unconstrained actuator's force on the linear quarter car over the
    road (z_r [m], v_r [m/s] at times t [s]): ride_metrics of the exact (zero-order-hold on the
    road rate) solution, and its force."""
    from scipy.signal import lsim

    from dampnet.sim.ride import ride_metrics

    k = feedback_row(ctrl)
    A, E = linear_car(veh, k)
    C = np.eye(4)
    _, _, x = lsim((A, E[:, None], C, np.zeros((4, 1))), v_r, t, X0=np.zeros(4), interp=False)
    force = x @ k
    acc = (-veh.k_s * x[:, 0] - force) / veh.m_s
    zr = z_r - z_r[0]
    zu = zr + x[:, 2]
    zs = zu + x[:, 0]
    m = ride_metrics(t, zs, zu, zr, acc, veh.k_t, veh.m_s, veh.m_us)
    return {"metrics": m, "force": force}


def ideal_active_analytic(veh: Vehicle, ctrl: Controller, road_gd_n0: float, speed_m_s: float,
                          n_band: tuple[float, float], wk: bool = True) -> float:
    """The ideal active car's body acceleration RMS [m/s^2] (Wk-weighted when wk) from the ISO
    8608 displacement PSD Gd(n) = Gd(n0) (n / n0)^-2 [m^3] over the spatial band n_band [cycles/m]
    at speed_m_s: sqrt(integral |H_a(f)|^2 G(f) df), H_a the road-to-acceleration response."""
    from dampnet.sim.ride import wk_analog
    from dampnet.sim.roads.profiles import iso_psd

    k = feedback_row(ctrl)
    A, E = linear_car(veh, k)
    f = np.geomspace(n_band[0] * speed_m_s, n_band[1] * speed_m_s, 20001)
    gz = iso_psd(f / speed_m_s, road_gd_n0) / speed_m_s                      # z_r PSD [m^2/Hz]
    s = 2j * np.pi * f
    # x = (sI - A)^-1 E z_r' and z_r' = s z_r
    h = np.array([np.linalg.solve(si * np.eye(4) - A, E * si) for si in s])   # [n, 4] per z_r
    acc = (-veh.k_s * h[:, 0] - h @ k) / veh.m_s
    if wk:
        acc = acc * wk_analog(f)
    return float(np.sqrt(np.trapezoid(np.abs(acc) ** 2 * gz, f)))


def _tracked(damper, motion: dict, fd: np.ndarray, force: np.ndarray, f_static: float):
    """(demanding steps, those in reach, force - (f_static + demand) there, the demand there) of a
    run's steps: a demand is in reach where f_static + demand lies between the damper's forces at
    its two control limits at that step's motion (x, v, a, temperature and its states)."""
    lo, hi = damper.control_range()
    f_lo, f_hi = (damper.forces(u=np.full(fd.size, u), **motion)[0] for u in (lo, hi))
    want = f_static + fd
    asks = fd != 0
    reach = asks & (want >= np.minimum(f_lo, f_hi)) & (want <= np.maximum(f_lo, f_hi))
    return asks, reach, force[reach] - want[reach], fd[reach]


def _tracking_metrics(n_asks: int, n_reach: int, err: np.ndarray, fd: np.ndarray) -> dict:
    rms = lambda x: float(np.sqrt(np.mean(x ** 2))) if len(x) else float("nan")  # noqa: E731
    return {"saturated_share": float(1.0 - n_reach / max(n_asks, 1)), "tracking_rms_n": rms(err),
            "tracking_rel": rms(err) / rms(fd) if len(fd) else None}


def tracking(spec, ctrl: Controller, res: dict) -> dict:
    """Force tracking of a law through the inverse: over the steps with a demand, the share out
    of reach (outside [F(u_min), F(u_max)] at that step's motion); over those within reach, the
    RMS of force - (f_static + demand) [N] and that relative to the demand's RMS."""
    from dampnet import _core
    from dampnet.sim.dampers import runtime_damper

    a = res["arrays"]
    motion = {q: a[q] for q in ("x", "v", "a", "temperature", *_core.DAMPER_STATES) if q in a}
    asks, reach, err, fd = _tracked(runtime_damper(spec).damper, motion, demand(ctrl, a), a["force"], res["f_static_n"])
    return {"demand_share": float(asks.mean()), **_tracking_metrics(int(asks.sum()), int(reach.sum()), err, fd)}


def full_car_tracking(spec, res: dict) -> dict:
    """Force tracking of a full-car run whose corners track forces (`maneuvers.run`'s result), over
    its four corners together as `tracking` measures the quarter car's."""
    from dampnet import _core
    from dampnet.sim.dampers import runtime_damper
    from dampnet.sim.full_car.runs import CORNERS

    a, p = res["arrays"], res["params"]
    names = list(_core.FULLCAR_STATE_NAMES)
    col = lambda name: a["state"][:, names.index(name)]  # noqa: E731
    damper = runtime_damper(spec).damper
    ctrl = Controller(**res["controller"]).core_dict()
    n_asks = n_reach = 0
    errs, fds = [], []
    for i, corner in enumerate(CORNERS):
        v_us, x = col(f"v_us_{corner}"), a["x"][:, i]
        fd = _core.force_demand(ctrl, a["v"][:, i] + v_us, v_us, x - p["x_static_f" if i < 2 else "x_static_r"],
                                col(f"z_us_{corner}") - col(f"z_r_{corner}"))
        motion = {"x": x, "v": a["v"][:, i], "a": a["a"][:, i], "temperature": col(f"temperature_{corner}"),
                  **{q: col(f"{q}_{corner}") for q in _core.DAMPER_STATES}}
        asks, reach, err, fd_in = _tracked(damper, motion, fd, a["force"][:, i], res["f_static_n"])
        n_asks, n_reach = n_asks + int(asks.sum()), n_reach + int(reach.sum())
        errs.append(err)
        fds.append(fd_in)
    return _tracking_metrics(n_asks, n_reach, np.concatenate(errs), np.concatenate(fds))


def _metrics(m: dict) -> dict:
    return {"wk_rms_m_s2": m["acc_wk_rms_m_s2"], "travel_rms_m": m["travel_rms_m"], "tyre_load_rms_n": m["tyre_load_rms_n"]}


def quarter_car_case(spec, road_class: str, speed_kmh: float, *, laws=FORCE_LAWS, baselines=BASELINES,
                     seed: int = 0, length_m: float = ROAD_LENGTH_M, vehicle: Vehicle | None = None) -> dict:
    """One road and speed: {"passive_low": metrics, ..., law: {"model": metrics + tracking,
    "ideal_semi_active": metrics, "ideal_active": metrics, "gain_share": ...}}."""
    from dampnet.recipes import control_laws
    from dampnet.recipes import roads as road_recipes
    from dampnet.sim.quarter_car.runs import simulate

    veh = vehicle or Vehicle()
    v = speed_kmh / 3.6
    road = road_recipes.build(f"iso:class={road_class},length_m={length_m:g}", seed=seed, speed_m_s=v)
    out: dict = {"road": road.name, "speed_kmh": speed_kmh}
    for name in baselines:
        ctrl = control_laws.make(name, spec, veh)
        out[name] = _metrics(simulate(spec, road, v, ctrl, veh, law=name)["metrics"])
    ideal = ideal_spec()
    low = out["passive_low"]["wk_rms_m_s2"] if "passive_low" in out else None
    for name in laws:
        ctrl = control_laws.make(name, spec, veh)
        res = simulate(spec, road, v, ctrl, veh, law=name)
        row = {"model": {**_metrics(res["metrics"]), **tracking(spec, ctrl, res)}}
        semi = simulate(ideal, road, v, ideal_controller(ctrl), veh, law=name)
        row["ideal_semi_active"] = _metrics(semi["metrics"])
        a = res["arrays"]
        row["ideal_active"] = _metrics(ideal_active(veh, ctrl, a["t"], a["z_r"], a["v_r"])["metrics"])
        if low is not None:
            row["gain_share"] = gain_share(low, row["model"]["wk_rms_m_s2"], row["ideal_semi_active"]["wk_rms_m_s2"])
        out[name] = row
    if low is not None and "skyhook_continuous" in out and "skyhook_force" in out:
        # today's linear map, against the skyhook law's ideal semi-active damper (the (b))
        out["skyhook_continuous"]["gain_share"] = gain_share(low, out["skyhook_continuous"]["wk_rms_m_s2"],
                                                             out["skyhook_force"]["ideal_semi_active"]["wk_rms_m_s2"])
    return out


def gain_share(low: float, got: float, ideal: float) -> float | None:
    """A law's comfort gain over passive low as a share of the ideal's, from the three Wk RMS
    [m/s^2]; None where the ideal gains under MIN_IDEAL_GAIN of passive low's."""
    best = low - ideal
    return (low - got) / best if best > MIN_IDEAL_GAIN * low else None


def full_car_rows(spec, road_class: str, speed_kmh: float, damping=("low", "high", "skyhook", *FORCE_LAWS),
                  seed: int = 0, dt: float = 1e-3) -> dict:
    """The full car on the road manoeuvre: per damping setting, heave (body) Wk RMS [m/s^2], roll
    and pitch rate RMS [deg/s], the worst wheel's dynamic tyre load RMS [N]; for a force-tracking
    law, its force tracking over the four corners (`full_car_tracking`)."""
    from dampnet.recipes import maneuvers

    man = maneuvers.build("road", dt, {"speed_kmh": speed_kmh, "road": f"iso:class={road_class}", "road_seed": seed})
    out = {}
    for d in damping:
        res = maneuvers.run(spec, man, d)
        m = res["metrics"]
        out[d] = {"heave_wk_rms_m_s2": m["acc_wk_rms_m_s2"], "roll_rate_rms_deg_s": m["roll_rate_rms_deg_s"],
                  "pitch_rate_rms_deg_s": m["pitch_rate_rms_deg_s"], "tyre_load_rms_max_n": max(m["tyre_load_dyn_rms_n"])}
        if d in FORCE_LAWS:
            out[d].update(full_car_tracking(spec, res))
    return out


def check_spec(spec, label: str | None = None) -> None:
    """ValueError unless the runtime can invert `spec`'s damper (its control sets its force: a
    neural model reading voltage or current, a parametric or a table damper)."""
    from dampnet.sim.dampers import runtime_damper

    try:
        runtime_damper(spec).damper.control_range()
    except (ValueError, RuntimeError):
        raise ValueError(f"{label or spec.name}: the control study tracks forces through the damper's inverse, and "
                         f"this damper ({spec.kind}) has no control that sets its force (a neural model reading "
                         "voltage or current, a parametric or a table damper has)") from None


def run(spec, classes=ROAD_CLASSES, speeds=SPEEDS_KMH, *, full_car: bool = True, seed: int = 0,
        label: str | None = None, progress: Callable[[str], None] | None = None) -> dict:
    """The study of the damper `spec` (dampnet.sim.dampers.DamperSpec): {"model": `label` (default
    the spec's name), "quarter_car": {"B_40": case, ...}, "full_car": {"B_40": rows, ...}}."""
    check_spec(spec, label)
    out: dict = {"model": label or spec.name, "quarter_car": {}, "full_car": {}}
    for c in classes:
        for s in speeds:
            key = f"{c}_{s:g}"
            if progress:
                progress(f"quarter car, ISO {c}, {s:g} km/h")
            out["quarter_car"][key] = quarter_car_case(spec, c, s, seed=seed)
            if full_car:
                if progress:
                    progress(f"full car, ISO {c}, {s:g} km/h")
                out["full_car"][key] = full_car_rows(spec, c, s, seed=seed)
    return out


def _f(x, fmt="{:.3f}") -> str:
    return "-" if x is None else fmt.format(x)


def text_tables(res: dict) -> list[str]:
    """The study's markdown tables (`run`'s result): Wk RMS and comfort gain share, force
    tracking, travel and tyre load, and the full car's rows when it ran."""
    qc = res["quarter_car"]
    out = ["Quarter car, Wk-weighted body acceleration RMS [m/s^2] (law through the inverse / "
           "ideal semi-active / ideal active), and the law's comfort gain over passive low as a share of the ideal "
           "semi-active's (-: the ideal gains under 0.5 %):", "",
           "| road, km/h | passive low | passive high | skyhook_continuous | " + " | ".join(FORCE_LAWS) + " |",
           "|---" * (4 + len(FORCE_LAWS)) + "|"]
    for key, r in qc.items():
        cont = r["skyhook_continuous"]
        cells = [key.replace("_", ", "), _f(r["passive_low"]["wk_rms_m_s2"]), _f(r["passive_high"]["wk_rms_m_s2"]),
                 _f(cont["wk_rms_m_s2"]) + (f" (gain {_f(cont['gain_share'], '{:.2f}')})" if "gain_share" in cont else "")]
        for law in FORCE_LAWS:
            w = r[law]
            cells.append(" / ".join(_f(w[k]["wk_rms_m_s2"]) for k in ("model", "ideal_semi_active", "ideal_active"))
                         + f" (gain {_f(w.get('gain_share'), '{:.2f}')})")
        out.append("| " + " | ".join(cells) + " |")
    out += ["", "Force tracking through the inverse: RMS error relative to the demand's RMS where reachable, with "
            "the law's command filter (none unless the caller sets u_tau_s: dampnet.sim.calibration.FORCE_COMMAND_TAU_S), "
            "and the share of demanding steps out of reach:", "",
            "| road, km/h | " + " | ".join(FORCE_LAWS) + " |", "|---" * (1 + len(FORCE_LAWS)) + "|"]
    for key, r in qc.items():
        out.append("| " + key.replace("_", ", ") + " | " + " | ".join(
            f"{_f(r[law]['model']['tracking_rel'], '{:.1%}')} err, {_f(r[law]['model']['saturated_share'], '{:.0%}')} out of reach" for law in FORCE_LAWS) + " |")
    out += ["", "Suspension travel RMS [mm] and dynamic tyre load RMS [N], law through the inverse:", "",
            "| road, km/h | passive low | skyhook_continuous | " + " | ".join(FORCE_LAWS) + " |",
            "|---" * (3 + len(FORCE_LAWS)) + "|"]
    for key, r in qc.items():
        tt = lambda m: f"{1e3 * m['travel_rms_m']:.1f} / {m['tyre_load_rms_n']:.0f}"  # noqa: E731
        out.append("| " + key.replace("_", ", ") + " | " + tt(r["passive_low"]) + " | " + tt(r["skyhook_continuous"])
                   + " | " + " | ".join(tt(r[law]["model"]) for law in FORCE_LAWS) + " |")
    if res["full_car"]:
        first = next(iter(res["full_car"].values()))
        out += ["", "Full car, road manoeuvre (two correlated tracks): heave Wk RMS [m/s^2] / roll rate RMS [deg/s] / "
                "pitch rate RMS [deg/s]:", "", "| road, km/h | " + " | ".join(first) + " |",
                "|---" * (1 + len(first)) + "|"]
        for key, rows in res["full_car"].items():
            out.append("| " + key.replace("_", ", ") + " | " + " | ".join(
                f"{m['heave_wk_rms_m_s2']:.3f} / {m['roll_rate_rms_deg_s']:.2f} / {m['pitch_rate_rms_deg_s']:.2f}"
                for m in rows.values()) + " |")
        laws = [law for law in FORCE_LAWS if law in first]
        out += ["", "Full car, force tracking over the four corners: RMS error relative to the demand's RMS where "
                "reachable, and the share of demanding corner-steps out of reach:", "",
                "| road, km/h | " + " | ".join(laws) + " |", "|---" * (1 + len(laws)) + "|"]
        for key, rows in res["full_car"].items():
            out.append("| " + key.replace("_", ", ") + " | " + " | ".join(
                f"{_f(rows[law].get('tracking_rel'), '{:.1%}')} err, {_f(rows[law].get('saturated_share'), '{:.0%}')} "
                "out of reach" for law in laws) + " |")
    return out


def headline(res: dict) -> str:
    """One line: per law, its comfort gain share against the ideal semi-active damper over the
    cases where the ideal gains (worst / best), and the target."""
    parts = []
    for law in ("skyhook_continuous", *FORCE_LAWS):
        shares = [r[law]["gain_share"] for r in res["quarter_car"].values()
                  if law in r and r[law].get("gain_share") is not None]
        span = f"{min(shares):.2f}" + (f" to {max(shares):.2f}" if max(shares) > min(shares) else "") if shares else "-"
        parts.append(f"{law} {span}")
    return ("comfort gain over passive low through the inverse (skyhook_continuous: today's linear map, against "
            "skyhook's ideal), as a share of the ideal semi-active damper's (target >= 0.9; -: the ideal gains under "
            "0.5 % on every road): " + ", ".join(parts))


def plot(res: dict, path) -> None:
    """Wk RMS relative to passive low, per road class (a panel each) against speed: each law through
    the inverse (solid) beside its ideal semi-active damper (dashed), and skyhook_continuous; a PNG
    at `path` (written as is: callers stage it)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    qc = res["quarter_car"]
    classes = sorted({k.split("_")[0] for k in qc})
    fig, axes = plt.subplots(1, len(classes), figsize=(4.2 * len(classes) + 2.6, 3.8), sharey=True, squeeze=False)
    colors = dict(zip(FORCE_LAWS, ("C0", "C1", "C2", "C3")))
    for ax, c in zip(axes[0], classes):
        keys = [k for k in qc if k.startswith(c + "_")]
        sp = [qc[k]["speed_kmh"] for k in keys]
        low = [qc[k]["passive_low"]["wk_rms_m_s2"] for k in keys]
        rel = lambda vals: [v / lo for v, lo in zip(vals, low)]  # noqa: E731
        ax.axhline(1.0, color="k", lw=1, label="passive low")
        ax.plot(sp, rel([qc[k]["skyhook_continuous"]["wk_rms_m_s2"] for k in keys]), "k:", marker="s",
                label="skyhook_continuous")
        for law in FORCE_LAWS:
            ax.plot(sp, rel([qc[k][law]["model"]["wk_rms_m_s2"] for k in keys]), "-", marker="o", color=colors[law],
                    label=f"{law} (through the inverse)")
            ax.plot(sp, rel([qc[k][law]["ideal_semi_active"]["wk_rms_m_s2"] for k in keys]), "--", marker="x",
                    color=colors[law], label=f"{law}, ideal semi-active")
        ax.set_title(f"ISO 8608 class {c}")
        ax.set_xlabel("speed [km/h]")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("Wk body acceleration RMS / passive low [-]")
    axes[0][-1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    fig.suptitle(f"Quarter car, {res.get('model', 'the model')}: the force laws through the damper's inverse "
                 "against the ideal")
    save_figure(fig, path, 110, format="png")
