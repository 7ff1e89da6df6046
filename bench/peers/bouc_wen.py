"""The modified Bouc-Wen model of an MR damper (Spencer, Dyke, Sain and Carlson 1997), a peer
model for bench/real_data.py: simulated in numpy, fitted with scipy.optimize.least_squares.

B. F. Spencer Jr., S. J. Dyke, M. K. Sain, J. D. Carlson, "Phenomenological model for
magnetorheological dampers", J. Eng. Mech. 123(3):230-238, 1997 (eq. 7-10):

    F    = c1 ydot + k1 (x - x0)
    zdot = -gamma |xdot - ydot| z |z|^(n-1) - beta (xdot - ydot) |z|^n + A (xdot - ydot)
    ydot = (alpha z + c0 xdot + k0 (x - y)) / (c0 + c1)
    alpha = alpha_a + alpha_b u,  c1 = c1a + c1b u,  c0 = c0a + c0b u
    udot = -eta (u - v)          (v: the commanded voltage; u: the coil's, after the filter)

The 14 parameters (PARAM_NAMES), in SI units here (the paper gives N, cm, s):

    c0a [N s/m], c0b [N s/(m V)], k0 [N/m], c1a [N s/m], c1b [N s/(m V)], k1 [N/m], x0 [m],
    alpha_a [N/m], alpha_b [N/(m V)], gamma [1/m^2], beta [1/m^2], A [-], n [-], eta [1/s]

PAPER holds the 1997 paper's identified values (Table 1, converted: 1 N s/cm = 100 N s/m,
1 N/cm = 100 N/m, 1 cm^-2 = 1e4 m^-2). "V" is the control's own unit: volts in the paper,
amperes for a current-controlled damper (the fit then finds its own alpha_b, c0b, c1b).

Integration (`simulate`): a fixed step, linearly implicit (Rosenbrock-Euler) in the internal
states (y, z), whose fast mode (rate about A alpha / (c0 + c1), 800 1/s with the paper's values
at 1 V, far more for a fitted small c0 + c1) would need sub-millisecond explicit steps; the
measured x, xdot are interpolated linearly between samples and every sample interval is split
into `substeps`. The filter on u is integrated exactly (piecewise-constant v). Vectorised over
"lanes" (a batch of records and parameter sets stepped together), which is what makes the fit's
finite-difference Jacobian cheap.

Fitting (`fit`): least squares of the force on the training records with bounds, from a start
scaled from the paper's values. A constant control per record (as the dyno tests here) does not
identify eta (the filter's state sits at v); the fit then keeps eta at the paper's 190 1/s and
says so in the result (`fixed`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

PARAM_NAMES = ("c0a", "c0b", "k0", "c1a", "c1b", "k1", "x0", "alpha_a", "alpha_b", "gamma", "beta", "A", "n", "eta")
UNITS = {"c0a": "N s/m", "c0b": "N s/(m V)", "k0": "N/m", "c1a": "N s/m", "c1b": "N s/(m V)", "k1": "N/m",
         "x0": "m", "alpha_a": "N/m", "alpha_b": "N/(m V)", "gamma": "1/m^2", "beta": "1/m^2", "A": "-",
         "n": "-", "eta": "1/s"}

#: Spencer et al. 1997, Table 1, in SI units
PAPER = {"c0a": 21.0e2, "c0b": 3.50e2, "k0": 46.9e2, "c1a": 283e2, "c1b": 2.95e2, "k1": 5.00e2, "x0": 14.3e-2,
         "alpha_a": 140e2, "alpha_b": 695e2, "gamma": 363e4, "beta": 363e4, "A": 301.0, "n": 2.0, "eta": 190.0}


def as_array(params) -> np.ndarray:
    """A parameter dict (PARAM_NAMES keys) or array [..., 14] as an array [..., 14]."""
    if isinstance(params, dict):
        missing = [k for k in PARAM_NAMES if k not in params]
        if missing:
            raise ValueError(f"Bouc-Wen parameters: missing {', '.join(missing)}")
        return np.array([float(params[k]) for k in PARAM_NAMES])
    p = np.asarray(params, dtype=np.float64)
    if p.shape[-1] != len(PARAM_NAMES):
        raise ValueError(f"Bouc-Wen parameters: expected {len(PARAM_NAMES)} values, got shape {p.shape}")
    return p


def simulate(params, x, xdot, v, dt, substeps: int = 4, u0=None) -> np.ndarray:
    """Force [N] of the model on records sampled at `dt` [s].

    x [m], xdot [m/s], v (control) arrays of shape [T] or [T, L] (L lanes); params a dict,
    an array [14] (shared) or [L, 14] (one set per lane); dt a scalar or [L]. The states start
    at rest (y = x[0], z = 0), u at u0 (default v[0]: the coil already energised). Returns F [T]
    or [T, L]."""
    x = np.asarray(x, dtype=np.float64)
    single = x.ndim == 1
    x2 = x[:, None] if single else x
    T, L = x2.shape
    xd2 = np.asarray(xdot, dtype=np.float64).reshape(T, -1) * np.ones((1, L))
    v2 = np.asarray(v, dtype=np.float64).reshape(T, -1) * np.ones((1, L))
    p = as_array(params)
    p = np.broadcast_to(p, (L, len(PARAM_NAMES))) if p.ndim == 1 else p
    if p.shape != (L, len(PARAM_NAMES)):
        raise ValueError(f"Bouc-Wen parameters: expected [{L}, {len(PARAM_NAMES)}], got {list(p.shape)}")
    c0a, c0b, k0, c1a, c1b, k1, x0, aa, ab, gam, bet, A, n, eta = (p[:, i] for i in range(len(PARAM_NAMES)))
    h = np.broadcast_to(np.asarray(dt, dtype=np.float64), (L,)) / substeps
    y = x2[0].copy()
    z = np.zeros(L)
    u = v2[0].copy() if u0 is None else np.broadcast_to(np.asarray(u0, dtype=np.float64), (L,)).copy()
    decay = np.exp(-eta * h)
    F = np.empty((T, L))
    nm1 = n - 1.0

    def rates(xk, xdk, uk, y, z):
        alpha = aa + ab * uk
        c0 = c0a + c0b * uk
        c1 = c1a + c1b * uk
        cs = c0 + c1
        yd = (alpha * z + c0 * xdk + k0 * (xk - y)) / cs
        r = xdk - yd
        az = np.abs(z)
        azn1 = az ** nm1
        azn = azn1 * az
        zd = -gam * np.abs(r) * z * azn1 - bet * r * azn + A * r
        return yd, zd, r, alpha, cs, c1, az, azn1, azn

    yd, *_ = rates(x2[0], xd2[0], u, y, z)
    F[0] = (c1a + c1b * u) * yd + k1 * (x2[0] - x0)
    for k in range(1, T):
        xa, xb = x2[k - 1], x2[k]
        va, vb = xd2[k - 1], xd2[k]
        vk = v2[k - 1]
        for s in range(substeps):
            w = (s + 0.5) / substeps  # the midpoint of the substep
            xk = xa + w * (xb - xa)
            xdk = va + w * (vb - va)
            u = vk + (u - vk) * decay
            yd, zd, r, alpha, cs, c1, az, azn1, azn = rates(xk, xdk, u, y, z)
            # Jacobian of (yd, zd) in (y, z)
            j11 = -k0 / cs
            j12 = alpha / cs
            dzr = -gam * np.sign(r) * z * azn1 - bet * azn + A  # d zd / d r
            dzz = -(gam * np.abs(r) + bet * r * np.sign(z)) * n * azn1  # d zd / d z, r held
            j21 = dzr * (k0 / cs)  # d r / d y = k0 / cs
            j22 = dzz + dzr * (-alpha / cs)
            # (I - h J) d = h f
            a11, a12, a21, a22 = 1 - h * j11, -h * j12, -h * j21, 1 - h * j22
            det = a11 * a22 - a12 * a21
            dy = h * (a22 * yd - a12 * zd) / det
            dz = h * (a11 * zd - a21 * yd) / det
            y = y + dy
            z = z + dz
        yd, *_ = rates(xb, vb, u, y, z)
        F[k] = (c1a + c1b * u) * yd + k1 * (xb - x0)
    return F[:, 0] if single else F


# -- fitting -----------------------------------------------------------------------------

FIT_NAMES = PARAM_NAMES[:-1]  # eta is not identified by constant-control records
#: bounds of the fitted parameters, in SI units (generous: the paper's values x 1e-3 .. x 1e3,
#: x0 within +-1 m, A 1..1e4, n 1..4)
_LOW = {"c0a": 1.0, "c0b": 0.0, "k0": 0.0, "c1a": 10.0, "c1b": 0.0, "k1": 0.0, "x0": -1.0, "alpha_a": 0.0,
        "alpha_b": 0.0, "gamma": 0.0, "beta": 0.0, "A": 1.0, "n": 1.0}
_HIGH = {"c0a": 1e7, "c0b": 1e7, "k0": 1e7, "c1a": 1e8, "c1b": 1e8, "k1": 1e6, "x0": 1.0, "alpha_a": 1e8,
         "alpha_b": 1e8, "gamma": 1e10, "beta": 1e10, "A": 1e4, "n": 4.0}


@dataclass
class Record:
    """One record for the fit: x [m], xdot [m/s], v (control), F [N], at dt [s]."""

    x: np.ndarray
    xdot: np.ndarray
    v: np.ndarray
    force: np.ndarray
    dt: float


@dataclass
class FitResult:
    params: dict
    cost_rmse_n: float
    seconds: float
    nfev: int
    fixed: dict = field(default_factory=dict)
    start: dict = field(default_factory=dict)
    message: str = ""


def fit_window(x, xdot, v, force, dt, period_s: float, points_per_period: int = 400, periods: float = 2.0) -> Record:
    """The last `periods` periods of a record, resampled to `points_per_period` points a period
    (linear interpolation): every training record then has the same number of steps, so that all
    of them step together in `fit`. The first period is the warm-up (see `fit`)."""
    t = np.arange(len(x)) * dt
    span = min(periods * period_s, t[-1])
    n = int(round(points_per_period * span / period_s))
    tt = np.linspace(t[-1] - span, t[-1], n + 1)
    return Record(*(np.interp(tt, t, np.asarray(a, dtype=np.float64)) for a in (x, xdot, v, force)),
                  dt=float(tt[1] - tt[0]))


def start_params(records: Sequence[Record]) -> dict:
    """A start from the paper's values, scaled so that its force range matches the data's: the
    damping and stiffness parameters by the ratio of the data's force to the paper's velocity
    scale, the hysteresis shape (gamma, beta, A) by the data's displacement scale."""
    p = dict(PAPER)
    F = np.concatenate([r.force for r in records])
    xd = np.concatenate([r.xdot for r in records])
    xx = np.concatenate([r.x for r in records])
    u = np.concatenate([r.v for r in records])
    umax = max(float(np.max(np.abs(u))), 1e-9)
    # the force of the paper's model at the data's peak velocity and highest control, roughly:
    # alpha z_max + c0 v (z_max = (A / (gamma + beta))^(1/n))
    zmax = (PAPER["A"] / (PAPER["gamma"] + PAPER["beta"])) ** 0.5
    vpk = float(np.percentile(np.abs(xd), 99))
    f_paper = (PAPER["alpha_a"] + PAPER["alpha_b"] * umax) * zmax + (PAPER["c0a"] + PAPER["c0b"] * umax) * vpk
    s = float(np.percentile(np.abs(F), 99)) / max(f_paper, 1e-9)
    for k in ("c0a", "c0b", "k0", "c1a", "c1b", "k1", "alpha_a", "alpha_b"):
        p[k] = PAPER[k] * s
    # the control's unit: the paper's 0-2.25 V onto the data's range
    for k in ("c0b", "c1b", "alpha_b"):
        p[k] = p[k] * 2.25 / umax
    xs = float(np.percentile(np.abs(xx), 99))
    g = (0.01 / max(xs, 1e-6)) ** 2  # the paper's tests: 1.5 cm amplitude
    p["gamma"] = PAPER["gamma"] * g
    p["beta"] = PAPER["beta"] * g
    p["x0"] = 0.0
    p["k1"] = min(p["k1"], 1e5)
    return p


def fit(records: Sequence[Record], start: dict | None = None, max_nfev: int = 60, substeps: int = 2,
        warmup_fraction: float = 0.5, verbose: int = 0) -> FitResult:
    """Fit the 13 parameters other than eta to `records` (see `fit_window`) by bounded least squares
    (scipy.optimize.least_squares, trust-region reflective) of the force [N] on each record's
    last (1 - warmup_fraction) of samples; the Jacobian by forward differences, every column's
    parameter set simulated in one batch. Parameters are scaled by the start's magnitudes."""
    from scipy.optimize import least_squares

    if not records:
        raise ValueError("Bouc-Wen fit: no training records")
    T = len(records[0].x)
    if any(len(r.x) != T for r in records):
        raise ValueError("Bouc-Wen fit: records must have the same length (use fit_window)")
    t0 = time.perf_counter()
    p0 = dict(start or start_params(records))
    X = np.column_stack([r.x for r in records])
    XD = np.column_stack([r.xdot for r in records])
    V = np.column_stack([r.v for r in records])
    Fm = np.column_stack([r.force for r in records])
    dts = np.array([r.dt for r in records])
    first = int(T * warmup_fraction)
    R = len(records)
    idx = [PARAM_NAMES.index(k) for k in FIT_NAMES]
    scale = np.array([max(abs(p0[k]), 1e-3 if k == "x0" else 1e-9) for k in FIT_NAMES])
    if "x0" in FIT_NAMES:
        scale[FIT_NAMES.index("x0")] = 0.1
    lo = np.array([_LOW[k] for k in FIT_NAMES]) / scale
    hi = np.array([_HIGH[k] for k in FIT_NAMES]) / scale
    th0 = np.clip(np.array([p0[k] for k in FIT_NAMES]) / scale, lo, hi)
    base = as_array(p0)

    def full(thetas: np.ndarray) -> np.ndarray:
        P = np.tile(base, (thetas.shape[0], 1))
        P[:, idx] = thetas * scale
        return P

    def residuals_batch(thetas: np.ndarray) -> np.ndarray:
        """[n_sets, R * (T - first)] residuals of several parameter sets, one simulation."""
        m = thetas.shape[0]
        P = np.repeat(full(thetas), R, axis=0)  # lane = set * R + record
        F = simulate(P, np.tile(X, (1, m)), np.tile(XD, (1, m)), np.tile(V, (1, m)), np.tile(dts, m),
                     substeps=substeps)
        e = (F - np.tile(Fm, (1, m)))[first:]
        e = np.where(np.isfinite(e), e, 1e6)
        return e.reshape(e.shape[0], m, R).transpose(1, 2, 0).reshape(m, -1)

    cache = {}

    def fun(th):
        r = residuals_batch(th[None, :])[0]
        cache["th"], cache["r"] = th.copy(), r
        return r

    def jac(th):
        eps = 1e-4 * np.maximum(np.abs(th), 1e-2)
        step = np.where(th + eps > hi, -eps, eps)
        sets = np.vstack([th[None, :], th[None, :] + np.diag(step)])
        r = residuals_batch(sets)
        return ((r[1:] - r[0]) / step[:, None]).T

    res = least_squares(fun, th0, jac=jac, bounds=(lo, hi), method="trf", x_scale="jac", max_nfev=max_nfev,
                        verbose=verbose)
    p = dict(zip(PARAM_NAMES, full(res.x[None, :])[0].tolist()))
    rmse = float(np.sqrt(np.mean(res.fun ** 2)))
    return FitResult(params=p, cost_rmse_n=rmse, seconds=time.perf_counter() - t0, nfev=int(res.nfev),
                     fixed={"eta": p["eta"]}, start=p0, message=str(res.message))
