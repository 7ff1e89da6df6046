"""Which way should the valve term's control act: on the force axis (today) or on the velocity axis?
(issue 54, the noise floor: a lead for the next change of the term, not a product feature.)

The rig's valve opens a bypass in parallel with the bleed: the flow area below the blow-off knee is
A0(u) = A_bleed + u A_bypass (dampnet/rig/truth.py), so the bleed's force is c_b v^2 with c_b ~ 1 / A0^2,
the shim stack still cracks at the same pressure (the knee at one force at every control) and the knee
velocity grows with A0. That is the valve law with its velocity axis scaled, F(v, u) ~ g(v / a(u)),
a(u) = A0(u) / A0(0). Today's term scales the force axis instead, F = s(u) g(v): its knee stays at
one velocity, and its force moves.

This script fits both forms to the rig's noise-free hydraulic force (dampnet.rig.truth.hydraulic_force
at the reference temperature, no lag, no friction or gas) at the (velocity, voltage) samples of a
plan, by bounded least squares, and prints the residuals:

  force axis     today's term, its own fit (dampnet.terms._fit_valve: 10 parameters)
  velocity axis  the same law at v / a(u), a(u) = (1 + h_num u) / (1 + h_den u), s(u) = 1
                 (10 parameters: today's with g_num, g_den acting on the velocity)
  both axes      s(u) g(v / a(u)) (12 parameters)

Each form beside a free viscous term c v (the truth's laminar loss R_lam Q, which no valve law has:
projected out of the residual, as `_fit_valve`'s A columns).

  python bench/experiments/valve_axis.py [--plan thesis|quick] [--every 40] [--figure PNG]

About 1-3 minutes on 2 cores (the thesis plan).
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np


def truth_samples(plan: str, every: int):
    """(v [m/s], voltage [V], the rig's static hydraulic force [N]) at a plan's samples."""
    from dampnet.rig import generate
    from dampnet.rig.truth import TruthParams, controller_current, hydraulic_force, valve_opening

    p = TruthParams()
    ds = generate(plan, seed=0)
    v = np.concatenate([t.channels["velocity"] for t in ds.tests])[::every]
    # each test's nominal voltage (the recorded channel carries the sensor's noise)
    u = np.concatenate([np.full(t.time.size, float(t.control_nominal)) for t in ds.tests])[::every]
    f = hydraulic_force(v, valve_opening(controller_current(u, p), p), p.temperature_ref_c, p)
    keep = np.abs(v) > 1e-5
    return v[keep], u[keep], f[keep]


def axis_force(p10: np.ndarray, h: np.ndarray, v: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The valve law (dampnet.terms' numpy mirror) at v / a(u), a(u) = (1 + h0 u) / (1 + h1 u)."""
    from dampnet.terms import _valve

    a = (1 + h[0] * u) / (1 + h[1] * u)
    return _valve(np.asarray(p10, float), {"v": v / a, "u": u})


def fit_axis(v, u, f, p_start: np.ndarray, force_gain: bool, project):
    """Least squares of the velocity-axis form from today's fit (and a few a(u) guesses); project:
    the residual's part outside the free linear columns (as _fit_valve's A)."""
    from scipy.optimize import least_squares

    from dampnet.terms import VALVE_K_D_MAX

    n = 12 if force_gain else 10
    lower = np.array([1e-6, 0, 0, 1e-6, 0, 0, 0, 0, 0, 0, 0, 0][:n], float)
    upper = np.array([np.inf] * 8 + [VALVE_K_D_MAX] * 2 + [np.inf] * 2)[:n]

    def unpack(q):
        p10 = np.array(q[:10], float)
        if force_gain:
            return p10, q[10:12]
        h = p10[6:8].copy()
        p10[6:8] = 0.0  # s(u) = 1: the control acts on the velocity alone
        return p10, h

    def resid(q):
        p10, h = unpack(q)
        return project(axis_force(p10, h, v, u) - f)

    best = None
    for h0 in (0.3, 1.0, 3.0):
        q0 = np.array(p_start, float)
        q0[6:8] = (0.0, 0.0) if force_gain else (h0, 0.0)
        if force_gain:
            q0 = np.concatenate([q0, [h0, 0.0]])
        sol = least_squares(resid, np.clip(q0, lower, upper), bounds=(lower, upper), method="trf",
                            x_scale="jac", max_nfev=300)
        if best is None or sol.cost < best.cost:
            best = sol
    return best.x, resid(best.x)


def summary(name, r, v, u, f, seconds):
    levels = np.unique(np.round(u, 3))
    per = {f"{lv:g}": round(float(np.sqrt(np.mean(r[np.round(u, 3) == lv] ** 2))), 1) for lv in levels}
    return {"form": name, "rms_n": round(float(np.sqrt(np.mean(r ** 2))), 2),
            "rms_over_force_rms": round(float(np.sqrt(np.mean(r ** 2)) / np.sqrt(np.mean(f ** 2))), 4),
            "max_abs_n": round(float(np.max(np.abs(r))), 1), "rms_per_voltage_n": per,
            "seconds": round(seconds, 1)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--plan", default="thesis", help="the rig's plan (thesis, quick or a plan file)")
    ap.add_argument("--figure", help="also draw the truth and both one-axis fits at three voltages here (PNG)")
    ap.add_argument("--every", type=int, default=40, help="every n-th sample (default 40: 61,000 of the thesis plan's)")
    a = ap.parse_args()
    from dampnet.terms import _fit_valve, _valve

    v, u, f = truth_samples(a.plan, a.every)
    print(json.dumps({"plan": a.plan, "samples": int(v.size), "force_rms_n": round(float(np.sqrt(np.mean(f ** 2))), 1)}))
    t0 = time.perf_counter()
    A = v[:, None]  # the free viscous column
    Q, _ = np.linalg.qr(A)
    project = lambda e: e - Q @ (Q.T @ e)  # noqa: E731
    p_today = np.array(_fit_valve(v, u, f, A=A))
    r_today = project(_valve(p_today, {"v": v, "u": u}) - f)
    print(json.dumps({**summary("force axis (today)", r_today, v, u, f, time.perf_counter() - t0),
                      "params": [round(x, 6) for x in p_today]}), flush=True)
    fits = {}
    for name, gain in (("velocity axis", False), ("both axes", True)):
        t0 = time.perf_counter()
        q, r = fit_axis(v, u, f, p_today, gain, project)
        fits[name] = q
        print(json.dumps({**summary(name, r, v, u, f, time.perf_counter() - t0),
                          "params": [round(float(x), 6) for x in q]}), flush=True)
    if a.figure:
        draw(a.figure, v, u, f, p_today, fits["velocity axis"], project)


def draw(path, v, u, f, p_today, q_axis, project) -> None:
    """Force against speed per direction at three voltages: the truth and both one-axis fits, each
    with its own least-squares viscous term c v (the column projected out of its residual)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dampnet.terms import _valve

    p10 = np.array(q_axis[:10], float)
    h = p10[6:8].copy()
    p10[6:8] = 0.0
    def with_viscous(fit):  # the fit plus its own least-squares c v
        return fit + ((f - fit) - project(f - fit))

    f_today = with_viscous(_valve(p_today, {"v": v, "u": u}))
    f_axis = with_viscous(axis_force(p10, h, v, u))
    levels = [lv for lv in (0.0, 2.25, 5.0) if np.any(np.isclose(u, lv))]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.4), sharey=False)
    for ax, sign, title in ((axes[0], 1, "rebound (v > 0)"), (axes[1], -1, "compression (v < 0)")):
        for k, lv in enumerate(levels):
            sel = np.isclose(u, lv) & (np.sign(v) == sign)
            o = np.argsort(np.abs(v[sel]))
            w = np.abs(v[sel])[o]
            col = f"C{k}"
            ax.plot(w, sign * f[sel][o], "-", color=col, lw=2.5, alpha=0.35, label=f"rig truth, {lv:g} V")
            ax.plot(w, sign * f_today[sel][o], "--", color=col, lw=1.2, label=f"control on the force (today), {lv:g} V")
            ax.plot(w, sign * f_axis[sel][o], ":", color=col, lw=1.6, label=f"control on the velocity, {lv:g} V")
        ax.set_xscale("log")
        ax.set_xlim(1e-3, None)
        ax.set_xlabel("|velocity| [m/s]")
        ax.set_ylabel("|force| [N] (hydraulic, static)")
        ax.set_title(title)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, loc="upper left")
    fig.suptitle("The valve term's control on the force axis (today) or the velocity axis: fits to the rig's hydraulics")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
