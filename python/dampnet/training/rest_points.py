"""The rest points: training rows at which the damper is at rest (thesis §5, after Burnett et al.).

ceil(fraction * n_train) extra training rows are added with every kinematic feature at its
registry `at_rest` value (0 for velocity and acceleration) while the non-kinematic inputs
(voltage, current, temperature, displacement) keep the values of randomly drawn training rows:
a damper at rest is at rest at *any* valid voltage, and 0 V is itself a valid command, so "zero
input" cannot mean all-zero features. Without a feature that has an at-rest value (e.g. voltage
only) no rows are added. They join the training set only; validation and test stay measured.

Their target (the training option rest_target, `dampnet train --rest-target`) is by default the
damper's own force at rest ("estimated"): a gas-charged damper pushes its gas force at rest (the
synthetic rig's -273 N; any monotube's preload), which rows at 0 N contradict. "zero" is the
thesis's 0 N; "none" adds no rest points. The estimate is recorded whenever rest points are added
(model.meta["rest_force"], `dampnet train`'s summary). The estimate measured better than 0 N
(bench/LOG.md, "Issue 33's table with the estimated force at rest", seeds 0-9, median held-out
NRMSE over the lookup table's: 5x8 and 6x8 plans 0.41x against 0.50x and 0.53x; the thesis plan
0.48x / 0.37x / 0.63x against 0.59x / 0.50x / 0.75x with 2.25 / 1 / 4 V held out; the quick plan
the same). The force at rest is estimated from the
training rows near v = 0 by the least-squares fit
    F = b0 + b2 sign(v) + (b+ + sum_k d+_k z_k) max(v, 0) + (b- + sum_k d-_k z_k) min(v, 0) + sum_k c_k z_k
over the rows with |v| <= LOW_SPEED_FRACTION of the largest |v|, z_k being every other input
(acceleration, control, displacement, ...): each side of v = 0 a line of its own slope (rebound
and compression valves differ), b0 the midpoint of their intercepts, so the seal friction's step
(b2) averages out; each rest row's target is the fit at its own inputs (v = 0, the kinematic
inputs at rest, the others copied), so a gas spring's force follows the copied displacement and
an offset that differs with the control follows the control. With fewer than
MIN_ROWS rows on either side of v = 0, or without a velocity input, the target is 0 N, as the
thesis's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from dampnet.features import FEATURES, velocity_column

#: the rest points' targets fit() offers: the estimate below (the default), the thesis's 0 N, or
#: no rest points at all
REST_TARGETS = ("estimated", "zero", "none")
#: the rows near rest: |v| up to this fraction of the training rows' largest |v|
LOW_SPEED_FRACTION = 0.05
#: at least this many rows on each side of v = 0 for an estimate; else 0 N
MIN_ROWS = 20


@dataclass(frozen=True)
class RestForce:
    """The rest points' target force and how it was found (model.meta["rest_force"]).

    `targets(Z)` gives each rest row's force [N]; `force_N` is their mean over the rows it was
    first asked for (0 N when not estimated)."""

    force_N: float
    source: str            # "estimated" or why it is 0 N
    rows: int = 0          # the low-speed rows of the estimate
    friction_N: float = 0.0  # half the step at v = 0 (b2) [N], for the record
    velocity: int | None = None       # the velocity column
    coef: tuple[float, ...] = ()      # the fit's coefficients over design()'s columns

    def targets(self, Z: np.ndarray) -> np.ndarray:
        if not self.coef:
            return np.full(len(Z), self.force_N)
        return design(np.asarray(Z, dtype=np.float64), self.velocity) @ np.asarray(self.coef)

    def meta(self) -> dict:
        return {"force_N": round(self.force_N, 3), "source": self.source, "rows": self.rows,
                "friction_N": round(self.friction_N, 3)}


def design(X: np.ndarray, j: int) -> np.ndarray:
    """The fit's columns: 1, sign(v), max(v, 0), min(v, 0), every other input z, and each side's
    slope times each z (the low-speed damping changes with the control: without these its change
    would leak into z's own coefficient and so into the force at rest)."""
    v = X[:, j]
    others = np.delete(X, j, axis=1)
    up, down = np.maximum(v, 0.0)[:, None], np.minimum(v, 0.0)[:, None]
    return np.column_stack([np.ones(len(v)), np.sign(v), up, down, others, up * others, down * others])


def rest_force(X_train: np.ndarray, y_train: np.ndarray, features: Sequence[str],
               Z: np.ndarray | None = None) -> RestForce:
    """The damper's force at rest estimated from the training rows (see the module docstring);
    force_N is the mean target over the rest rows `Z` (none given: over the training rows with
    v = 0 put in)."""
    j = velocity_column(features)
    if j is None:
        return RestForce(0.0, "0 N: no velocity input")
    X_train = np.asarray(X_train, dtype=np.float64)
    v = X_train[:, j]
    y = np.asarray(y_train, dtype=np.float64)
    top = float(np.max(np.abs(v))) if len(v) else 0.0
    near = np.abs(v) <= LOW_SPEED_FRACTION * top
    n_pos, n_neg = int(np.sum(near & (v > 0))), int(np.sum(near & (v < 0)))
    if top <= 0 or min(n_pos, n_neg) < MIN_ROWS:
        return RestForce(0.0, f"0 N: fewer than {MIN_ROWS} training rows on each side of v = 0 within "
                              f"{LOW_SPEED_FRACTION:g} of the largest speed ({n_neg} below, {n_pos} above)")
    A = design(X_train[near], j)
    # columns scaled to unit RMS so that lstsq's rank cut treats inputs of every unit alike
    norm = np.sqrt(np.mean(A * A, axis=0))
    norm[norm == 0] = 1.0
    coef = np.linalg.lstsq(A / norm, y[near], rcond=None)[0] / norm
    if Z is None:
        Z = X_train.copy()
        Z[:, j] = 0.0
    mean = float(np.mean(design(np.asarray(Z, dtype=np.float64), j) @ coef)) if len(Z) else float(coef[0])
    return RestForce(mean, "estimated", int(near.sum()), float(coef[1]), j, tuple(float(c) for c in coef))


def rest_points(X_train: np.ndarray, features: Sequence[str], fraction: float,
                rng: np.random.Generator) -> np.ndarray:
    """The rest rows' inputs (see the module docstring); [0, k] if none apply."""
    rest = [FEATURES[f].at_rest if f in FEATURES else None for f in features]
    if fraction <= 0 or all(v is None for v in rest) or len(X_train) == 0:
        return np.empty((0, len(features)))
    n = math.ceil(fraction * len(X_train))
    rows = X_train[rng.integers(0, len(X_train), size=n)].copy()
    for j, v in enumerate(rest):
        if v is not None:
            rows[:, j] = v
    return rows
