"""Parameters of an effect from data alone (for `dampnet train --add EFFECT` without a diagnosis).

A lag's time constant is the one at which a smooth function of (velocity, acceleration,
lagged input) fits the measured force best (the baseline basis of dampnet.diagnosis.basis).
"""

from __future__ import annotations

import numpy as np

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


def _best_tau_of(rows_by_tau, keep) -> float:
    """The grid tau at which the baseline basis of the kept tests' rows fits the force best."""
    best = None
    for tau, per_test in zip(GRID_S, rows_by_tau):
        Z = np.vstack([per_test[i][0] for i in keep])
        y = np.concatenate([per_test[i][1] for i in keep])
        lo, hi = Z.min(0), Z.max(0)
        z = 2 * (Z - lo) / np.where(hi > lo, hi - lo, 1) - 1
        X = baseline_basis(z, ["velocity", "acceleration", "control"])
        beta, *_ = np.linalg.lstsq(X, y, rcond=None)
        sse = float(np.sum((y - X @ beta) ** 2))
        if best is None or sse < best[0]:
            best = (sse, tau)
    return float(best[1])


def _best_tau(ds, channel: str, rows_per_test: int = 400) -> float:
    return _best_tau_of(_tau_rows(ds.tests, channel, rows_per_test), range(len(ds.tests)))


def lag_with_spread(tests, channel: str, groups: int = 5) -> tuple[float, float | None]:
    """(tau [s], its spread [s]: the jackknife over `groups` groups of tests, at least half the
    grid's step; None with < 2 groups)."""
    tests = list(tests)
    rows = _tau_rows(tests, channel)  # the lagged channels once, shared by every fit below
    tau = _best_tau_of(rows, range(len(tests)))
    g = min(groups, len(tests))
    if g < 2:
        return tau, None
    loo = np.log([_best_tau_of(rows, [i for i in range(len(tests)) if i % g != k]) for k in range(g)])
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
