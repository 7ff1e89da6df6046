"""What each full-vehicle test measures, from a run's arrays (FullCar.simulate's, in SI).

  bsst   the transmissibility of the body (heave at the CG per road height; the pitch mode:
         pitch per road height) and of the wheels, an H1 estimate over 1/48-octave bands of the
         whole record's Fourier transforms; its body-mode and wheel-hop peaks (frequency,
         gain), the same of the linear model (dampnet.sim.full_car.linear) with the run's
         equivalent viscous damping beside them; body vertical acceleration RMS and peak
  dlc    lateral acceleration, roll angle and rate, yaw rate, side-slip (peak and RMS, in
         deg and deg/s where angles), steering, cones hit (ISO 3888-1: the test is passed when
         none is), the smallest cone clearance (negative: how deep the footprint went over a
         cone), the time the car takes to settle after the exit gate
  road   body acceleration RMS and its ISO 2631-1 Wk-weighted RMS, roll and pitch rate RMS,
         dynamic tyre load RMS per wheel

Each takes (arrays, maneuver, the run's full-car params); which one a test uses is its entry in
dampnet.recipes.maneuvers.
"""

from __future__ import annotations

import numpy as np
import scipy.signal

from dampnet.sim.full_car.maneuvers import OVERHANG_FRONT_M, OVERHANG_REAR_M, Maneuver
from dampnet.sim.full_car.params import cg_to_axles
from dampnet.sim.full_car.runs import CORNERS
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


#: the transmissibility's bands per octave, and the split between the body modes and wheel hop [Hz]
BANDS_PER_OCTAVE = 48
BODY_WHEEL_SPLIT_HZ = 4.0
MIN_BINS = 1  # a band spans at least this many of the record's Fourier bins


def transmissibility(x: np.ndarray, y: np.ndarray, dt: float, f0: float, f1: float,
                     bands_per_octave: int = BANDS_PER_OCTAVE) -> tuple[np.ndarray, np.ndarray]:
    """The frequency response y / x of a sweep run [y's unit per x's] at band centres [Hz] (each
    band's |X|^2-weighted mean frequency: a one-bin band's estimate is exact at its bin)
    within [f0, f1]: H1 = sum Y X* / sum |X|^2 over the record's Fourier bins in each band
    (1/bands_per_octave octave, at least MIN_BINS bins; the
    whole record: the sweep's input and the response both start at rest; the response to the
    sweep's last cycles rings on past the record's end only at the top frequency)."""
    n = len(x)
    X, Y = np.fft.rfft(x), np.fft.rfft(y)
    f = np.fft.rfftfreq(n, dt)
    df = 1.0 / (n * dt)
    edges = [f0]
    while edges[-1] < f1:   # 1/bands_per_octave octave, at least MIN_BINS bins
        edges.append(min(f1, max(edges[-1] * 2.0 ** (1.0 / bands_per_octave), edges[-1] + MIN_BINS * df)))
    centres, H = [], []
    for lo, hi in zip(edges[:-1], edges[1:]):
        m = (f >= lo) & (f < hi)
        sxx = np.sum(np.abs(X[m]) ** 2)
        if not m.any() or sxx == 0:
            continue
        centres.append(np.sum(f[m] * np.abs(X[m]) ** 2) / sxx)   # the band's |X|^2-weighted frequency
        H.append(np.sum(Y[m] * np.conj(X[m])) / sxx)
    return np.array(centres), np.array(H)


def _peak(f: np.ndarray, g: np.ndarray, lo: float, hi: float) -> tuple[float | None, float | None]:
    """(frequency [Hz], gain) of the largest |g| within [lo, hi], refined by a parabola in log f;
    (None, None) when the sweep did not cover [lo, hi]."""
    m = np.flatnonzero((f >= lo) & (f <= hi))
    if m.size == 0:
        return None, None
    k = m[int(np.argmax(np.abs(g[m])))]
    a = np.abs(g)
    if 0 < k < len(f) - 1 and k - 1 in m and k + 1 in m:
        l0, l1, l2 = np.log(f[k - 1 : k + 2])
        y0, y1, y2 = a[k - 1 : k + 2]
        den = (y0 - 2 * y1 + y2)
        if den < 0 and abs(l2 - l0) > 0:
            d = 0.5 * (y0 - y2) / den  # in units of one band (the bands are equal in log f)
            return float(np.exp(l1 + d * (l2 - l0) / 2)), float(y1 - 0.25 * (y0 - y2) * d)
    return float(f[k]), float(a[k])


def equivalent_damping(res: dict, f_static: float = 0.0) -> float:
    """The run's equivalent viscous damping [N s/m]: the least-squares c of F - f_static = c v
    over the four corners' damper forces and velocities."""
    F, v = np.asarray(res["force"]) - f_static, np.asarray(res["v"])
    vv = float(np.sum(v * v))
    return float(np.sum(F * v) / vv) if vv > 0 else 0.0


def sweep_element(res: dict, man: Maneuver, freqs: np.ndarray, params: dict,
                  half_band_oct: float = 1 / 24, cycles: float = 3.0) -> np.ndarray:
    """[len(freqs), 2]: each corner's damper as an equivalent linear element, F - f_static =
    k (x - x_static) + c v (dynamic stiffness [N/m]: the force in phase with the stroke, an
    acceleration term's -w^2 b included; damping [N s/m]; least squares over the four corners),
    fitted over the part of a sweep run when the sweep's frequency was within half_band_oct
    octaves of each of freqs [Hz], or within the octaves it sweeps in `cycles` cycles there (the sweep's law f(t) = f0 2^(rate (t - pre)); man.meta of
    dampnet.sim.roads.sine_sweep): a nonlinear damper's equivalent linearisation at each
    frequency (its describing function). A linear damper: (0, c) at all."""
    meta = man.meta
    t = np.arange(man.road.shape[0]) * man.dt
    ts = t - meta.get("pre_s", 0.0)
    f_t = np.where((ts >= 0) & (ts <= meta.get("sweep_s", np.inf)),
                   meta.get("f0_hz", 0.5) * 2.0 ** (meta.get("rate_octave_s", 0.1) * ts), np.nan)
    F = np.asarray(res["force"]) - params.get("f_static_f", 0.0)
    R = np.stack([np.asarray(res["x"]) - params.get("x_static_f", 0.0), np.asarray(res["v"])], axis=2)
    scale = np.sqrt(np.mean(R**2, axis=(0, 1))) + 1e-300  # columns of equal size: a conditioned fit
    R = R / scale
    RR = np.einsum("nci,ncj->nij", R, R)
    RF = np.einsum("nci,nc->ni", R, F)
    order = np.argsort(np.where(np.isfinite(f_t), f_t, np.inf))
    fs = f_t[order]
    cRR = np.concatenate([np.zeros((1, 2, 2)), np.cumsum(RR[order], axis=0)])
    cRF = np.concatenate([np.zeros((1, 2)), np.cumsum(RF[order], axis=0)])
    freqs = np.asarray(freqs, dtype=float)
    half = np.maximum(half_band_oct, meta.get("rate_octave_s", 0.1) * cycles / freqs)
    lo = np.searchsorted(fs, freqs * 2.0 ** -half)
    hi = np.searchsorted(fs, freqs * 2.0 ** half)
    out = np.zeros((len(freqs), 2))
    for j, (a, b) in enumerate(zip(lo, hi)):
        A, y = cRR[b] - cRR[a], cRF[b] - cRF[a]
        if b > a:
            out[j] = np.linalg.lstsq(A, y, rcond=1e-12)[0] / scale
    return out


def bsst_response(res: dict, man: Maneuver, params: dict) -> dict:
    """The sweep's transmissibilities (see the module comment): {"f_hz", "body", "wheel" (complex
    arrays), "body_unit", "f_lin_hz", "body_lin", "wheel_lin" (the linear model's, at each
    frequency with the dampers' equivalent linear element there: sweep_element), "element"
    ([len(f_lin_hz), 2]: k [N/m], c [N s/m]), "c_equivalent_n_s_m" (over the whole run)}."""
    from dampnet.sim.full_car import linear

    mode = man.meta.get("mode", "heave")
    f0, f1 = man.meta.get("f0_hz", 0.5), man.meta.get("f1_hz", 20.0)
    x = man.road[:, 0]
    body = column(res, "z" if mode == "heave" else "theta")
    sign = linear.ROAD_PATTERNS[mode]
    wheel = np.mean([column(res, f"z_us_{c}") * sign[i] for i, c in enumerate(CORNERS)], axis=0)
    f, hb = transmissibility(x, body, man.dt, f0, f1)
    _, hw = transmissibility(x, wheel, man.dt, f0, f1)
    fs = params.get("f_static_f", 0.0)
    c_eq = equivalent_damping(res, fs)
    fl = f0 * 2.0 ** (np.arange(0, np.log2(f1 / f0) * 100 + 1) / 100)  # 1/100 octave
    el = sweep_element(res, man, fl, params)
    bl, wl = np.zeros(fl.size, complex), np.zeros(fl.size, complex)
    for j, (fj, (kj, cj)) in enumerate(zip(fl, el)):
        lin = linear.road_response(np.array([fj]), params, cj, mode, stiffness=kj)
        bl[j], wl[j] = lin["z" if mode == "heave" else "theta"][0], lin["wheel"][0]
    return {"f_hz": f, "body": hb, "wheel": hw, "body_unit": "m/m" if mode == "heave" else "rad/m",
            "f_lin_hz": fl, "body_lin": bl, "wheel_lin": wl, "element": el, "c_equivalent_n_s_m": c_eq}


def bsst_metrics(res: dict, man: Maneuver, params: dict | None = None) -> dict:
    acc = res["acc_z"]
    # body_peak_gain: heave at the CG per road height [m/m], or (mode pitch) pitch per road height [rad/m]
    out = {"acc_rms_m_s2": rms(acc), "acc_peak_m_s2": float(np.max(np.abs(acc))),
           "pitch_acc_rms_rad_s2": rms(res["acc_theta"]),
           "tyre_load_min_n": float(np.min(res["tyre_load"]))}
    r = bsst_response(res, man, params or {})
    split = BODY_WHEEL_SPLIT_HZ
    for key, (f, h), (fl, hl) in (("body", (r["f_hz"], r["body"]), (r["f_lin_hz"], r["body_lin"])),
                                  ("wheel_hop", (r["f_hz"], r["wheel"]), (r["f_lin_hz"], r["wheel_lin"]))):
        lo, hi = (0.0, split) if key == "body" else (split, np.inf)
        out[f"{key}_peak_hz"], out[f"{key}_peak_gain"] = _peak(f, h, lo, hi)
        out[f"{key}_peak_hz_linear"], out[f"{key}_peak_gain_linear"] = _peak(fl, hl, lo, hi)
        for i, (name, unit) in enumerate((("stiffness", "n_m"), ("damping", "n_s_m"))):
            out[f"{key}_equivalent_{name}_{unit}"] = (None if out[f"{key}_peak_hz"] is None else float(
                np.interp(out[f"{key}_peak_hz"], r["f_lin_hz"], r["element"][:, i])))
    out["c_equivalent_n_s_m"] = r["c_equivalent_n_s_m"]
    return out


def cone_clearance(res: dict, man: Maneuver, params: dict) -> np.ndarray:
    """Per cone (man.meta['cones']) the smallest distance [m] between it and the vehicle's
    footprint over the run: a rectangle of the overall width, from the rear overhang behind the
    rear axle to the front overhang ahead of the front axle, at the CG's position and heading.
    Negative: the cone was inside the footprint (hit), by that depth to the nearest edge."""
    cones = np.asarray(man.meta["cones"])
    X = column(res, "x_pos") + man.meta.get("start_x_m", 0.0)
    Y, psi = column(res, "y_pos"), column(res, "psi")
    a_h, b_h = cg_to_axles(params)  # X, Y are the whole car's CG
    front, rear = a_h + OVERHANG_FRONT_M, b_h + OVERHANG_REAR_M
    half = man.meta["vehicle_width_m"] / 2
    out = np.full(len(cones), np.inf)
    c, s = np.cos(psi), np.sin(psi)
    for i, (cx, cy) in enumerate(cones):
        near = np.abs(X - cx) < front + rear + 5.0
        if not np.any(near):
            continue
        dx, dy = cx - X[near], cy - Y[near]
        xb = dx * c[near] + dy * s[near]
        yb = np.abs(-dx * s[near] + dy * c[near])
        ox = np.maximum(np.maximum(xb - front, -rear - xb), 0.0)
        oy = np.maximum(yb - half, 0.0)
        inside = (ox == 0) & (oy == 0)
        d = np.where(inside, -np.minimum(np.minimum(front - xb, xb + rear), half - yb), np.hypot(ox, oy))
        out[i] = float(np.min(d))
    return out


def cones_hit(res: dict, man: Maneuver, params: dict) -> list[int]:
    """Indices of the cones the vehicle's footprint passed over (cone_clearance <= 0)."""
    return [int(i) for i in np.flatnonzero(cone_clearance(res, man, params) <= 0.0)]


#: a side-slip beyond this [deg]: the car spun (no driver recovers it in a lane change)
LOST_CONTROL_SIDE_SLIP_DEG = 15.0
#: the car has settled after the exit gate once |a_y| stays below this [m/s^2] ...
SETTLED_A_Y_M_S2 = 0.3
#: ... and |yaw rate| below this [deg/s]
SETTLED_YAW_RATE_DEG_S = 1.0


def settle_time(res: dict, man: Maneuver) -> float:
    """Seconds from the CG passing the exit gate (the exit lane's end) until |a_y| and |yaw rate|
    stay below SETTLED_A_Y_M_S2 and SETTLED_YAW_RATE_DEG_S to the run's end; inf when they do
    not (the run too short)."""
    X = column(res, "x_pos") + man.meta.get("start_x_m", 0.0)
    t = np.asarray(res["t"]) if "t" in res else np.arange(len(X)) * man.dt
    gate = int(np.searchsorted(X, man.meta["lanes"][-1]["x1"]))
    if gate >= len(X):
        return float("inf")
    moving = (np.abs(res["a_y"]) >= SETTLED_A_Y_M_S2) | (np.abs(np.degrees(column(res, "r"))) >= SETTLED_YAW_RATE_DEG_S)
    after = np.flatnonzero(moving[gate:])
    if after.size == 0:
        return 0.0
    last = gate + after[-1] + 1
    return float(t[last] - t[gate]) if last < len(X) else float("inf")


def dlc_metrics(res: dict, man: Maneuver, params: dict) -> dict:
    deg = np.degrees
    out = {}
    for key, arr, unit in (("a_y", res["a_y"], "m_s2"), ("roll", deg(column(res, "phi")), "deg"),
                           ("roll_rate", deg(column(res, "p")), "deg_s"),
                           ("yaw_rate", deg(column(res, "r")), "deg_s"),
                           ("side_slip", deg(res["beta"]), "deg"), ("steer", deg(res["steer"]), "deg")):
        out[f"{key}_peak_{unit}"] = float(np.max(np.abs(arr)))
        out[f"{key}_rms_{unit}"] = rms(arr)
    clear = cone_clearance(res, man, params)
    out["cones_hit"] = int(np.sum(clear <= 0.0))
    out["cones"] = len(man.meta["cones"])
    out["passed"] = out["cones_hit"] == 0
    out["clearance_min_m"] = float(np.min(clear))
    out["settle_after_exit_s"] = settle_time(res, man)
    out["lost_control"] = out["side_slip_peak_deg"] > LOST_CONTROL_SIDE_SLIP_DEG
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
