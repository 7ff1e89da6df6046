"""Ride metrics of a quarter-car run: RMS, ISO 2631-1 Wk weighting, peak-to-RMS, travel, tyre load, transmissibility.

ISO 2631-1:1997 Annex A, weighting Wk (vertical, seated, comfort/health),
H(p) = Hh Hl Ht Hs with p = j 2 pi f:

  band limiting  Hh = 1 / (1 + sqrt2 w1/p + (w1/p)^2)           f1 = 0.4 Hz  (high pass)
                 Hl = 1 / (1 + sqrt2 p/w2 + (p/w2)^2)           f2 = 100 Hz  (low pass)
  a-v transition Ht = (1 + p/w3) / (1 + p/(Q4 w4) + (p/w4)^2)  f3 = f4 = 12.5 Hz, Q4 = 0.63
  upward step    Hs = (1 + p/(Q5 w5) + (p/w5)^2) / (1 + p/(Q6 w6) + (p/w6)^2) (w5/w6)^2
                                                                f5 = 2.37 Hz, Q5 = 0.91, f6 = 3.35 Hz, Q6 = 0.91

Digital form: the analog poles and zeros are mapped by the bilinear
transform, each one pre-warped at its own natural frequency
(|r| -> 2 fs tan(|r| / (2 fs))), and the gain set so the digital response
equals the analog one at 5 Hz. The analog response is within 0.3 % of the
standard's Table 3 values (0.1-400 Hz); at fs = 1 kHz the digital one is
within 0.6 % of Table 3 up to 50 Hz, 1.2 % up to 80 Hz and 3.3 % at 100 Hz
(bilinear compression near the band limit; 0.35 % up to 80 Hz at 2 kHz)
(tests/python/test_ride_metrics.py).
Needs fs >= 250 Hz (the 100 Hz band limit must lie well below Nyquist).

Conventions: displacements from static equilibrium (the loop's zero), so
the peak-to-RMS ratio is max|z| / rms(z) without removing a mean; suspension
travel = zs - zu; dynamic tyre load = kt (zu - zr) (the static load excluded),
also reported relative to the static load (ms + mu) g.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import bilinear_zpk, csd, sosfilt, sosfreqz, welch, zpk2sos

G = 9.80665

WK = dict(f1=0.4, f2=100.0, f3=12.5, f4=12.5, q4=0.63, f5=2.37, q5=0.91, f6=3.35, q6=0.91)

#: ISO 2631-1 Table 3, Wk (x1000) at third-octave centre frequencies [Hz].
WK_TABLE = {0.1: 31.2, 0.125: 48.6, 0.16: 79.0, 0.2: 121.0, 0.25: 182.0, 0.315: 263.0, 0.4: 352.0,
            0.5: 418.0, 0.63: 459.0, 0.8: 477.0, 1.0: 482.0, 1.25: 484.0, 1.6: 494.0, 2.0: 531.0,
            2.5: 631.0, 3.15: 804.0, 4.0: 967.0, 5.0: 1039.0, 6.3: 1054.0, 8.0: 1036.0, 10.0: 988.0,
            12.5: 902.0, 16.0: 768.0, 20.0: 636.0, 25.0: 513.0, 31.5: 405.0, 40.0: 314.0, 50.0: 246.0,
            63.0: 186.0, 80.0: 132.0, 100.0: 88.7, 125.0: 54.0, 160.0: 28.5, 200.0: 15.2, 250.0: 7.9,
            315.0: 3.98, 400.0: 1.95}


def wk_analog(freq_hz, p: dict = WK) -> np.ndarray:
    """Complex analog Wk response at frequency [Hz]."""
    s = 2j * np.pi * np.asarray(freq_hz, dtype=np.float64)
    w = {k: 2 * np.pi * v for k, v in p.items() if k.startswith("f")}
    with np.errstate(divide="ignore", invalid="ignore"):
        hh = 1.0 / (1.0 + math.sqrt(2) * w["f1"] / s + (w["f1"] / s) ** 2)
    hh = np.where(s == 0, 0.0, hh)
    hl = 1.0 / (1.0 + math.sqrt(2) * s / w["f2"] + (s / w["f2"]) ** 2)
    ht = (1.0 + s / w["f3"]) / (1.0 + s / (p["q4"] * w["f4"]) + (s / w["f4"]) ** 2)
    hs = ((1.0 + s / (p["q5"] * w["f5"]) + (s / w["f5"]) ** 2)
          / (1.0 + s / (p["q6"] * w["f6"]) + (s / w["f6"]) ** 2) * (w["f5"] / w["f6"]) ** 2)
    return hh * hl * ht * hs


def _analog_zpk(p: dict = WK):
    w = {k: 2 * np.pi * v for k, v in p.items() if k.startswith("f")}
    zeros, poles = [0.0, 0.0], []
    # Hh: s^2 / (s^2 + sqrt2 w1 s + w1^2)
    poles += list(np.roots([1.0, math.sqrt(2) * w["f1"], w["f1"] ** 2]))
    # Hl: w2^2 / (s^2 + sqrt2 w2 s + w2^2)
    poles += list(np.roots([1.0, math.sqrt(2) * w["f2"], w["f2"] ** 2]))
    # Ht: (s + w3) w4^2 / w3 / (s^2 + w4/Q4 s + w4^2)
    zeros += [-w["f3"]]
    poles += list(np.roots([1.0, w["f4"] / p["q4"], w["f4"] ** 2]))
    # Hs: (s^2 + w5/Q5 s + w5^2) / (s^2 + w6/Q6 s + w6^2)
    zeros += list(np.roots([1.0, w["f5"] / p["q5"], w["f5"] ** 2]))
    poles += list(np.roots([1.0, w["f6"] / p["q6"], w["f6"] ** 2]))
    return np.array(zeros, dtype=complex), np.array(poles, dtype=complex)


def wk_sos(fs: float, p: dict = WK) -> np.ndarray:
    """Second-order sections of the digital Wk filter at sample rate fs [Hz] (pre-warped bilinear)."""
    fs = float(fs)
    if not (math.isfinite(fs) and fs >= 250.0):
        raise ValueError(f"Wk weighting needs a sample rate >= 250 Hz (band limit 100 Hz), got {fs}")
    z, pl = _analog_zpk(p)

    def warp(r):
        m = abs(r)
        return r if m == 0 else r * (2 * fs * math.tan(m / (2 * fs))) / m

    zw = np.array([warp(r) for r in z])
    pw = np.array([warp(r) for r in pl])
    zd, pd, _ = bilinear_zpk(zw, pw, 1.0, fs)
    sos = zpk2sos(zd, pd, 1.0)
    f_ref = 5.0
    _, h = sosfreqz(sos, worN=[f_ref], fs=fs)
    sos[0, :3] *= abs(wk_analog(f_ref, p)) / abs(h[0])
    return sos


def wk_weighted(acc, fs: float) -> np.ndarray:
    """Wk-weighted acceleration time history (causal filter, zero initial state)."""
    return sosfilt(wk_sos(fs), np.asarray(acc, dtype=np.float64))


def rms(x) -> float:
    x = np.asarray(x, dtype=np.float64)
    return float(np.sqrt(np.mean(x * x)))


def peak_to_rms(x) -> float:
    """max|x| / rms(x) (x about static equilibrium; 0 for an all-zero signal)."""
    r = rms(x)
    return float(np.max(np.abs(x)) / r) if r > 0 else 0.0


def transmissibility(u, y, fs: float, fmin: float = 0.0, fmax: float | None = None,
                     method: str = "sweep", seg_s: float = 8.0) -> dict:
    """Frequency response y/u: {'f_hz', 'magnitude', 'phase_rad', 'coherence' (welch only)}.

    method 'sweep' (for a sine sweep that starts and ends at rest): the ratio of
    the whole records' Fourier transforms, Y(f)/U(f) (an H1 estimate with one
    rectangular segment; exact for a linear system whose response has died
    out by the end of the record; for a nonlinear damper, the response at the
    frequency being swept). Within 0.6 % of the analytic quarter car over
    0.6-18 Hz for the default sweep. method 'welch' (for random inputs): H1 =
    Puy/Puu with Hann segments of seg_s seconds, and the coherence.
    """
    u = np.asarray(u, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if u.shape != y.shape or u.ndim != 1 or u.size < 8:
        raise ValueError("transmissibility needs two equal-length 1-D records of at least 8 samples")
    fmax = fs / 2 if fmax is None else fmax
    if method == "sweep":
        uf = np.fft.rfft(u)
        yf = np.fft.rfft(y)
        f = np.fft.rfftfreq(u.size, 1.0 / fs)
        puu = np.abs(uf) ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            h = np.conj(uf) * yf / puu
        coh = None
    elif method == "welch":
        nper = min(u.size, int(round(seg_s * fs)))
        f, puu = welch(u, fs=fs, nperseg=nper)
        _, pyy = welch(y, fs=fs, nperseg=nper)
        _, puy = csd(u, y, fs=fs, nperseg=nper)
        with np.errstate(divide="ignore", invalid="ignore"):
            h = puy / puu
            coh = np.real(np.abs(puy) ** 2 / (puu * pyy))
    else:
        raise ValueError(f"method must be 'sweep' or 'welch', got {method!r}")
    sel = (f >= fmin) & (f <= fmax) & (puu > 0)
    out = dict(f_hz=f[sel], magnitude=np.abs(h[sel]), phase_rad=np.angle(h[sel]), method=method)
    if coh is not None:
        out["coherence"] = coh[sel]
    return out


def ride_metrics(t, zs, zu, zr, acc_s, kt: float, ms: float | None = None, mu: float | None = None,
                 wk: bool = True) -> dict:
    """The ride metrics of one run (stable keys, SI units).

    t [s] uniformly spaced; zs, zu, zr [m] sprung, unsprung, road displacement
    from equilibrium; acc_s [m/s^2] sprung acceleration; kt [N/m] tyre stiffness.
    """
    t = np.asarray(t, dtype=np.float64)
    dt = float(t[1] - t[0])
    fs = 1.0 / dt
    zs, zu, zr, acc_s = (np.asarray(a, dtype=np.float64) for a in (zs, zu, zr, acc_s))
    travel = zs - zu
    tyre = kt * (zu - zr)
    out = dict(
        acc_rms_m_s2=rms(acc_s),
        acc_wk_rms_m_s2=rms(wk_weighted(acc_s, fs)) if wk and fs >= 250 else float("nan"),
        acc_peak_m_s2=float(np.max(np.abs(acc_s))),
        disp_rms_m=rms(zs),
        disp_peak_to_rms=peak_to_rms(zs),
        travel_rms_m=rms(travel),
        travel_max_m=float(np.max(np.abs(travel))),
        tyre_load_rms_n=rms(tyre),
        duration_s=float(t[-1] - t[0]),
        dt_s=dt,
    )
    if ms is not None and mu is not None:
        out["tyre_load_rms_rel"] = out["tyre_load_rms_n"] / ((ms + mu) * G)
    return out
