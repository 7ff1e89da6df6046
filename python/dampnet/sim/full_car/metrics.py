"""What each full-vehicle test measures, from a run's arrays (FullCar.simulate's, in SI).

  bsst   body vertical acceleration (at the CG): RMS, peak, its spectrum (Welch)
  dlc    lateral acceleration, roll angle and rate, yaw rate, side-slip (peak and RMS, in
         deg and deg/s where angles), steering, cones hit (ISO 3888-1: the test is passed when
         none is)
  road   body acceleration RMS and its ISO 2631-1 Wk-weighted RMS, roll and pitch rate RMS,
         dynamic tyre load RMS per wheel

Each takes (arrays, maneuver, the run's full-car params); which one a test uses is its entry in
dampnet.recipes.maneuvers.
"""

from __future__ import annotations

import numpy as np
import scipy.signal

from dampnet.sim.full_car.maneuvers import OVERHANG_FRONT_M, OVERHANG_REAR_M, Maneuver
from dampnet.sim.ride import rms, wk_weighted


def column(res: dict, name: str) -> np.ndarray:
    """A state column of a run by its FULLCAR_STATE_NAMES name."""
    from dampnet import _core

    return res["state"][:, _core.FULLCAR_STATE_NAMES.index(name)]


def spectrum(x: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Amplitude spectral density [unit/sqrt(Hz)] by Welch's method (4 s Hann segments)."""
    nper = min(len(x), int(round(4.0 / dt)))
    f, p = scipy.signal.welch(x, fs=1.0 / dt, nperseg=nper)
    return f, np.sqrt(p)


def bsst_metrics(res: dict, man: Maneuver, params: dict | None = None) -> dict:
    acc = res["acc_z"]
    return {"acc_rms_m_s2": rms(acc), "acc_peak_m_s2": float(np.max(np.abs(acc))),
            "pitch_acc_rms_rad_s2": rms(res["acc_theta"]),
            "tyre_load_min_n": float(np.min(res["tyre_load"]))}


def cones_hit(res: dict, man: Maneuver, params: dict) -> list[int]:
    """Indices of the cones (man.meta['cones']) the vehicle's footprint passed over: a rectangle
    of the overall width, from the rear overhang behind the rear axle to the front overhang
    ahead of the front axle, at the CG's position and heading."""
    cones = np.asarray(man.meta["cones"])
    X = column(res, "x_pos") + man.meta.get("start_x_m", 0.0)
    Y, psi = column(res, "y_pos"), column(res, "psi")
    front, rear = params["a"] + OVERHANG_FRONT_M, params["b"] + OVERHANG_REAR_M
    half = man.meta["vehicle_width_m"] / 2
    hit = []
    c, s = np.cos(psi), np.sin(psi)
    for i, (cx, cy) in enumerate(cones):
        near = np.abs(X - cx) < front + rear
        if not np.any(near):
            continue
        dx, dy = cx - X[near], cy - Y[near]
        xb = dx * c[near] + dy * s[near]
        yb = -dx * s[near] + dy * c[near]
        if np.any((xb <= front) & (xb >= -rear) & (np.abs(yb) <= half)):
            hit.append(i)
    return hit


def dlc_metrics(res: dict, man: Maneuver, params: dict) -> dict:
    deg = np.degrees
    out = {}
    for key, arr, unit in (("a_y", res["a_y"], "m_s2"), ("roll", deg(column(res, "phi")), "deg"),
                           ("roll_rate", deg(column(res, "p")), "deg_s"),
                           ("yaw_rate", deg(column(res, "r")), "deg_s"),
                           ("side_slip", deg(res["beta"]), "deg"), ("steer", deg(res["steer"]), "deg")):
        out[f"{key}_peak_{unit}"] = float(np.max(np.abs(arr)))
        out[f"{key}_rms_{unit}"] = rms(arr)
    hit = cones_hit(res, man, params)
    out["cones_hit"] = len(hit)
    out["cones"] = len(man.meta["cones"])
    out["passed"] = not hit
    out["tyre_load_min_n"] = float(np.min(res["tyre_load"]))
    return out


def road_metrics(res: dict, man: Maneuver, params: dict | None = None) -> dict:
    acc = res["acc_z"]
    load = res["tyre_load"]
    return {"acc_rms_m_s2": rms(acc), "acc_wk_rms_m_s2": rms(wk_weighted(acc, 1.0 / man.dt)),
            "roll_rate_rms_deg_s": rms(np.degrees(column(res, "p"))),
            "pitch_rate_rms_deg_s": rms(np.degrees(column(res, "q"))),
            "tyre_load_dyn_rms_n": [rms(load[:, i] - np.mean(load[:, i])) for i in range(4)],
            "tyre_load_min_n": float(np.min(load))}
