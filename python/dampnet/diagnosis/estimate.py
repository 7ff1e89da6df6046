"""Parameters of an effect from data alone (for `dampnet train --add EFFECT` without a diagnosis).

A lag's time constant is the one at which a smooth function of (velocity, acceleration,
lagged input) fits the measured force best (the baseline basis of dampnet.diagnosis.basis).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import lapack

from dampnet.diagnosis.basis import baseline_basis
from dampnet.features import first_order_lag

GRID_S = tuple(np.exp(np.linspace(np.log(0.001), np.log(1.0), 25)))


def _tau_rows(tests, channel: str, rows_per_test: int = 400) -> list[list[tuple[np.ndarray, np.ndarray]]]:
    """Per grid tau, per test: (Z rows [velocity-or-lagged, acceleration, control-or-lagged], force)."""
    from dampnet.data.preprocess import acceleration_of

    fixed = []
    for t in tests:
        n = len(t)
        rows = np.arange(0, n, max(1, n // rows_per_test))
        a = t.channels["acceleration"] if "acceleration" in t.channels else acceleration_of(t)
        fixed.append((rows, a))
    out = []
    for tau in GRID_S:
        per_test = []
        for t, (rows, a) in zip(tests, fixed):
            lagged = first_order_lag(t.channels[channel], t.dt, tau)
            cols = [t.channels["velocity"], a, lagged] if channel != "velocity" else [lagged, a, t.control]
            per_test.append((np.stack([c[rows] for c in cols], axis=1), t.channels["force"][rows]))
        out.append(per_test)
    return out


def _r_factor(a: np.ndarray) -> np.ndarray:
    """R of the QR decomposition of `a`, as numpy's qr(a, mode="r") gives it to rounding. LAPACK's
    geqrt (recursive panels) takes 2.0 ms where numpy's geqrf takes 4.7 on a group's 3200 x 83 rows:
    these factorisations were most of lag_with_spread's time."""
    k = min(a.shape)
    if k == 0:
        return np.linalg.qr(a, mode="r")
    r, _, info = lapack.dgeqrt(min(16, k), a)
    if info != 0:
        raise np.linalg.LinAlgError(f"geqrt failed (info {info})")
    return np.triu(r[:k])


def _group_factors(per_test, group_of: list[int], n_groups: int) -> tuple[list[np.ndarray], list[int]]:
    """Per group, the triangular factor R of the QR decomposition of its rows' [baseline basis |
    force], the inputs scaled to [-1, 1] over every test given (one scaling for all groups, so that
    the rows of any union of groups have the stacked factors' R), and each group's row count."""
    Z = np.vstack([z for z, _ in per_test])
    y = np.concatenate([f for _, f in per_test])
    lo, hi = Z.min(0), Z.max(0)
    z = 2 * (Z - lo) / np.where(hi > lo, hi - lo, 1) - 1
    A = np.hstack([baseline_basis(z, ["velocity", "acceleration", "control"]), y[:, None]])
    owner = np.concatenate([np.full(len(f), group_of[i]) for i, (_, f) in enumerate(per_test)])
    parts = [A[owner == g] for g in range(n_groups)]
    return [_r_factor(a) for a in parts], [len(a) for a in parts]


def _sse(factors: list[np.ndarray], rows: int) -> float:
    """The least-squares residual sum of squares of the force (the last column) on the basis
    columns, over `rows` rows whose R factors are given, as numpy's lstsq on the rows computes it:
    the stacked factors' R = [[Rx, r], [0, rho]] has the rows' singular values in Rx, so the basis
    fit is lstsq(Rx, r) with lstsq's own cut-off (eps x max(rows, columns) of the largest singular
    value), and the SSE is rho^2 plus what that fit leaves of r. Without the cut-off a basis with
    dependent columns (a constant input makes them) fits round-off: 1 % of the SSE on the quick plan."""
    stacked = np.vstack(factors)
    R = _r_factor(stacked) if stacked.shape[0] > stacked.shape[1] else stacked
    p = R.shape[1] - 1
    Rx, r = R[:p, :p], R[:p, p]
    rho2 = float(R[p, p] ** 2) if R.shape[0] > p else 0.0
    beta, *_ = np.linalg.lstsq(Rx, r, rcond=np.finfo(float).eps * max(rows, p))
    return rho2 + float(np.sum((r - Rx @ beta) ** 2))


def _best_tau_of(factors_by_tau, keep) -> float:
    """The grid tau at which the baseline basis of the kept groups' rows fits the force best."""
    keep = list(keep)
    sse = [_sse([f[k] for k in keep], sum(n[k] for k in keep)) for f, n in factors_by_tau]
    return float(GRID_S[int(np.argmin(sse))])


def _best_tau(ds, channel: str, rows_per_test: int = 400) -> float:
    tests = list(ds.tests)
    factors = [_group_factors(pt, [0] * len(tests), 1) for pt in _tau_rows(tests, channel, rows_per_test)]
    return _best_tau_of(factors, [0])


def lag_with_spread(tests, channel: str, groups: int = 5) -> tuple[float, float | None]:
    """(tau [s], its spread [s]: the jackknife over `groups` groups of tests, at least half the
    grid's step; None with < 2 groups). Each fit stacks the groups' QR factors (one basis per grid
    tau, scaled over all the tests), not a new least-squares problem on the rows: issue 51 measured
    42 s of a 72 s thesis-plan diagnosis in the six lstsq fits per tau this replaced."""
    tests = list(tests)
    g = max(1, min(groups, len(tests)))
    group_of = [i % g for i in range(len(tests))]
    factors = [_group_factors(pt, group_of, g) for pt in _tau_rows(tests, channel)]
    tau = _best_tau_of(factors, range(g))
    if g < 2:
        return tau, None
    loo = np.log([_best_tau_of(factors, [j for j in range(g) if j != k]) for k in range(g)])
    spread_log = float(np.sqrt((g - 1) / g * np.sum((loo - loo.mean()) ** 2)))
    half_step = 0.5 * float(np.log(GRID_S[1] / GRID_S[0]))  # the grid's own resolution
    return tau, float(tau * max(spread_log, half_step))  # relative, on the log grid


def estimate_parameters(effect_id: str, ds) -> dict:
    """{"tau_s": ...} for valve_lag and compressibility; {} for effects that need none."""
    if effect_id == "valve_lag":
        return {"tau_s": _best_tau(ds, ds.tests[0].control_name)}
    if effect_id == "compressibility":
        return {"tau_s": _best_tau(ds, "velocity")}
    return {}
