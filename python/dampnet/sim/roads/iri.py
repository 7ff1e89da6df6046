"""International Roughness Index (IRI) of a longitudinal profile, per ASTM E1926 (Sayers' algorithm).

The Golden Car: a quarter car with parameters normalised by the sprung mass,
k1 = kt/ms = 653 s^-2, k2 = ks/ms = 63.3 s^-2, mu = mu/ms = 0.15,
c = cs/ms = 6.0 s^-1, driven at 80 km/h over the profile. Because the model
is linear, it is driven by the profile *slope* and its states are slopes
(zs', zs'/dt, zu', zu'/dt per metre); the IRI is the mean of |zu' - zs'|, the
accumulated suspension stroke per distance travelled, in m/km.

Steps (ASTM E1926 section 8, with the World Bank TP-46 program):

1. Smoothing: a 250 mm moving average, applied as the slope over the base
   length: with k = max(1, round(0.25/dx)) samples, the input is
   s_i = (y_{i+k} - y_i) / (k dx), i = 0 .. n-k-1.
2. Initialisation: zs' = zu' = (y(11 m) - y(0)) / 11 (the slope of the first
   11 m), rates zero (a profile shorter than 11 m is refused).
3. Exact discretisation of the continuous model with the input held over
   each step dt = dx / V: x_{i+1} = ST x_i + PR s_i with ST = expm(A dt),
   PR = A^-1 (ST - I) B (zero-order hold on the smoothed slope).
4. IRI = mean_i |x3 - x1| (after each step) x 1000 [m/km]; per segment, the
   mean over the steps whose midpoint lies in that segment (the filter runs
   continuously over the whole profile, so segments after the first need
   no re-initialisation).

Accuracy: on sinusoids (wavelength 1-30 m) this agrees with the analytic
steady-state IRI (Golden Car transfer function x moving-average response x
2/pi) to better than 0.5 % (tests/python/test_iri.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from dampnet.sim.roads.profiles import Road, RoadError

GOLDEN_CAR = dict(k1=653.0, k2=63.3, mu=0.15, c=6.0)
IRI_SPEED_M_S = 80.0 / 3.6
BASE_LENGTH_M = 0.25
INIT_LENGTH_M = 11.0


def golden_car_matrices(gc: dict = GOLDEN_CAR):
    """Continuous state-space (A, B) of the Golden Car; state (zs, zs_dot, zu, zu_dot), input road."""
    k1, k2, mu, c = gc["k1"], gc["k2"], gc["mu"], gc["c"]
    a = np.array([[0.0, 1.0, 0.0, 0.0],
                  [-k2, -c, k2, c],
                  [0.0, 0.0, 0.0, 1.0],
                  [k2 / mu, c / mu, -(k1 + k2) / mu, -c / mu]])
    b = np.array([0.0, 0.0, 0.0, k1 / mu])
    return a, b


def golden_car_response(freq_hz, gc: dict = GOLDEN_CAR) -> np.ndarray:
    """Complex transfer function (zu - zs) / road at frequency [Hz] (analytic, for checks)."""
    k1, k2, mu, c = gc["k1"], gc["k2"], gc["mu"], gc["c"]
    s = 2j * np.pi * np.asarray(freq_hz, dtype=np.float64)
    # (s^2 + c s + k2) zs = (c s + k2) zu ;  (mu s^2 + c s + k2 + k1) zu = (c s + k2) zs + k1 y
    ps = s * s + c * s + k2
    hu = k1 / (mu * s * s + c * s + k2 + k1 - (c * s + k2) ** 2 / ps)
    hs = (c * s + k2) / ps * hu
    return hu - hs


def discretise(dx: float, speed: float = IRI_SPEED_M_S, gc: dict = GOLDEN_CAR):
    """(ST, PR) for a profile step dx [m] at `speed` [m/s] (zero-order hold on the input)."""
    a, b = golden_car_matrices(gc)
    from scipy.linalg import expm  # here, not at import: `dampnet --help` stays free of scipy

    dt = dx / speed
    st = expm(a * dt)
    pr = np.linalg.solve(a, (st - np.eye(4)) @ b)
    return st, pr


@dataclass
class IriResult:
    """IRI [m/km] of a profile: overall and per segment (start_m, end_m, iri_m_km)."""

    overall: float
    segments: list = field(default_factory=list)
    dx_m: float = 0.0
    length_m: float = 0.0
    resampled: bool = False

    def to_dict(self) -> dict:
        return dict(overall=self.overall,
                    segments=[dict(start_m=a, end_m=b, iri_m_km=v) for a, b, v in self.segments],
                    dx_m=self.dx_m, length_m=self.length_m, resampled=self.resampled,
                    method="ASTM E1926 Golden Car, 80 km/h, 0.25 m moving average, 11 m initialisation, "
                           "exact (expm) discretisation")


def _uniform(road: Road):
    x, y = road.x, road.z
    d = np.diff(x)
    dx = float(np.median(d))
    if np.max(np.abs(d - dx)) <= 0.01 * dx:
        return x, y, dx, False
    n = int(math.floor((x[-1] - x[0]) / dx + 1e-9)) + 1
    xu = x[0] + np.arange(n) * dx
    return xu, np.interp(xu, x, y), dx, True


def iri_steps(elevation, dx: float, gc: dict = GOLDEN_CAR, speed: float = IRI_SPEED_M_S):
    """Per-step rectified slope |zu' - zs'| [m/m] of a uniformly sampled profile (step i covers [x_i, x_i+dx])."""
    y = np.asarray(elevation, dtype=np.float64)
    if not np.all(np.isfinite(y)):
        raise RoadError(f"profile has a non-finite elevation at index {int(np.flatnonzero(~np.isfinite(y))[0])}")
    dx = float(dx)
    if not (math.isfinite(dx) and dx > 0):
        raise RoadError(f"profile spacing must be positive, got {dx}")
    if dx > BASE_LENGTH_M * 1.5:
        raise RoadError(f"profile spacing {dx} m is too coarse for IRI (ASTM E1926 needs <= 0.3 m)")
    k = max(1, int(round(BASE_LENGTH_M / dx)))
    n_init = int(round(INIT_LENGTH_M / dx))
    if y.size <= max(n_init, k + 1):
        raise RoadError(f"profile of {(y.size - 1) * dx:.3f} m is shorter than the 11 m IRI "
                        f"initialisation length")
    slope = (y[k:] - y[:-k]) / (k * dx)
    st, pr = discretise(dx, speed, gc)
    x0 = (y[n_init] - y[0]) / (n_init * dx)
    # The recursion x_{i+1} = ST x_i + PR s_i in ST's modal coordinates (distinct eigenvalues):
    # one first-order complex recursion per mode, run by lfilter.
    from scipy.signal import lfilter

    lam, vec = np.linalg.eig(st)
    g = np.linalg.solve(vec, pr.astype(np.complex128))
    q0 = np.linalg.solve(vec, np.array([x0, 0.0, x0, 0.0], dtype=np.complex128))
    rel = np.zeros(slope.size)
    for j in range(4):
        qj = lfilter([g[j]], [1.0, -lam[j]], slope.astype(np.complex128), zi=[lam[j] * q0[j]])[0]
        rel += np.real((vec[2, j] - vec[0, j]) * qj)
    return np.abs(rel), k


def iri(profile, dx: float | None = None, segment_m: float | None = None,
        gc: dict = GOLDEN_CAR, speed: float = IRI_SPEED_M_S) -> IriResult:
    """IRI [m/km] of a Road (spatial) or an elevation array with spacing dx; per segment if segment_m."""
    if isinstance(profile, Road):
        if profile.kind != "spatial":
            raise RoadError(f"IRI needs a distance profile, road {profile.name!r} is a time history")
        x, y, dx, resampled = _uniform(profile)
    else:
        if dx is None:
            raise RoadError("give the profile spacing dx [m] with an elevation array")
        y = np.asarray(profile, dtype=np.float64)
        x = np.arange(y.size) * float(dx)
        resampled = False
    rs, k = iri_steps(y, dx, gc, speed)
    overall = 1000.0 * float(np.mean(rs))
    segments = []
    if segment_m is not None:
        seg = float(segment_m)
        if not (math.isfinite(seg) and seg > 0):
            raise RoadError(f"segment length must be positive, got {segment_m}")
        mid = x[:rs.size] + 0.5 * dx - x[0]
        idx = np.floor(mid / seg).astype(int)
        for j in range(int(idx.max()) + 1):
            sel = idx == j
            if np.any(sel):
                a = x[0] + j * seg
                b = min(a + seg, x[0] + (rs.size) * dx)
                segments.append((float(a), float(b), 1000.0 * float(np.mean(rs[sel]))))
    return IriResult(overall=overall, segments=segments, dx_m=float(dx),
                     length_m=float(x[-1] - x[0]), resampled=resampled)
