"""Does a model behave as a damper between and around its data? Finite differences of the
model's force at the motion of its training tests (metrics.json "structure").

- velocity: a damper's force rises with velocity. `velocity_falling_share` is the share of the
  training rows where F(v + h) < F(v - h), h 1 % of the velocity range (every other input held).
- control: between two tested control levels a model should neither bend away from both levels'
  forces nor reverse. `control_bend_nrmse` is the RMS, over rows and adjacent level pairs, of
  F(mid-level) - (F(lower) + F(upper)) / 2, over the force range (the control prior,
  dampnet.training.control_prior, drives it towards 0); `control_reversal_share` the share of
  rows and pairs where the force does not lie between the two levels' (beyond 0.1 % of the range).

The physics terms depend on displacement only, so the network alone decides both.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from dampnet.features import control_columns, control_levels, feature_matrix, velocity_column
from dampnet.model import MlpModel
from dampnet.reference import mlp_forward

#: rows evaluated at most (an even stride over the tests' samples)
MAX_ROWS = 4000
#: the finite-difference step, as a share of the velocity range
STEP_SHARE = 0.01
#: a difference within this share of the force range counts as no change
FLAT_SHARE = 1e-3


def structure(model: MlpModel, tests: Sequence[Any]) -> dict[str, Any]:
    """The checks above on `tests` (the training tests); keys absent when a check does not apply
    (no velocity input; fewer than two control levels)."""
    X = feature_matrix(list(tests), model.features, model.feature_params,
                       model.meta.get("data", {}).get("acceleration_window_s"))
    stride = max(1, len(X) // MAX_ROWS)
    X = X[::stride]
    f0 = mlp_forward(model, X)
    span = float(np.ptp(f0)) or 1.0
    out: dict[str, Any] = {"rows": len(X)}
    j = velocity_column(model.features)
    if j is not None:
        h = STEP_SHARE * float(model.sat_hi[j] - model.sat_lo[j])
        up, down = X.copy(), X.copy()
        up[:, j] += h
        down[:, j] -= h
        out["velocity_falling_share"] = float(np.mean(mlp_forward(model, up) - mlp_forward(model, down)
                                                      < -FLAT_SHARE * span))
    cols = control_columns(model.features)
    values = control_levels(X, cols)
    if len(values) >= 2:
        bends, reversals = [], []
        for lo, hi in zip(values[:-1], values[1:]):
            f = []
            for u in (lo, (lo + hi) / 2, hi):
                Xu = X.copy()
                Xu[:, cols] = u
                f.append(mlp_forward(model, Xu))
            bends.append(f[1] - (f[0] + f[2]) / 2)
            below, above = np.minimum(f[0], f[2]), np.maximum(f[0], f[2])
            reversals.append((f[1] < below - FLAT_SHARE * span) | (f[1] > above + FLAT_SHARE * span))
        out["control_bend_nrmse"] = float(np.sqrt(np.mean(np.concatenate(bends) ** 2)) / span)
        out["control_reversal_share"] = float(np.mean(np.concatenate(reversals)))
        out["control_levels"] = [round(float(v), 6) for v in values[:, 0]]
    return out
