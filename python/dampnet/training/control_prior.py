"""The control-interpolation prior: between two tested control levels the force is the
straight-line mix of the two levels' forces at the same motion (what a lookup table assumes).

Why: a dyno plan tests a few control levels (voltages or currents). Between them the data say
nothing, and a network fitted to two or three levels bends there wherever its seed puts it:
on the rig's quick plan (0 and 5 V trained, 2.25 V held out) plain training gave a held-out
NRMSE of 0.11-1.7 over seeds against the lookup table's 0.029 (bench/RESULTS.md, "Few dyno
tests"). The prior adds soft residual rows to the least-squares problem,

    r_prior = s * (f(k, u_m) - (1 - lam) f(k, u_lo) - lam f(k, u_hi)),  u_m = u_lo + lam (u_hi - u_lo),

at motion rows k drawn from the training rows (every input but the control kept), a gap
(u_lo, u_hi) between adjacent training levels and lam in [0.1, 0.9]. f is the network's scaled
output, so the rows are linear in the output scaling. `weight` is the prior's share against the
data: the prior rows' summed squares count `weight` times as much, per row, as the data rows'
(s = sqrt(weight * n_data / n_points)). With many levels the adjacent levels lie close and the
straight line between them is close to any smooth truth, so the prior costs little accuracy; with
two it makes the model the lookup table's interpolation of what it learned at each level.

The control columns are the features the runtime reads from the control
(dampnet.features.control_columns: field u or u_lag, e.g. voltage and voltage_lag); each takes the level's value (a lag is at
its steady state in a constant-level test). The levels are the tests' nominal control levels;
each level's value in a column is the column's mean over that level's rows (a measured control
channel carries the driver's offset, e.g. -0.0078 V for 0 V on the thesis data).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import torch

from dampnet.features import control_columns  # noqa: F401  (re-exported: the prior's columns)
from dampnet.training.net import DTYPE, Layout
from dampnet.training.settings import OPTIONS

#: default weight of the prior (dampnet train --control-prior; 0 turns it off; its one home is the
#: option's Setting): chosen on the rig's quick and 5 x 8 plans (bench/RESULTS.md, "Few dyno tests").
DEFAULT_WEIGHT = OPTIONS["control_prior"].default
#: prior points per training row
POINTS_PER_ROW = 0.25
def level_values(X: np.ndarray, levels: np.ndarray, columns: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """(the distinct nominal levels, sorted [L]; each level's mean value in each control column [L, C])."""
    levels = np.asarray(levels, dtype=np.float64)
    nominal = np.unique(levels[np.isfinite(levels)])
    values = np.array([[X[levels == lv, j].mean() for j in columns] for lv in nominal]).reshape(len(nominal),
                                                                                                len(columns))
    return nominal, values


@dataclass
class PriorRows:
    """The prior's inputs (scaled, [M, n_in] each) and mixing weights lam [M]; `scale` is s."""

    x_lo: torch.Tensor
    x_hi: torch.Tensor
    x_mid: torch.Tensor
    lam: torch.Tensor
    scale: float

    def __len__(self) -> int:
        return int(self.lam.shape[0])

    def residual(self, layout: Layout, x: torch.Tensor) -> torch.Tensor:
        """r_prior [M], differentiable in the weights x."""
        f = layout.forward
        return self.scale * (f(x, self.x_mid) - (1 - self.lam) * f(x, self.x_lo) - self.lam * f(x, self.x_hi))

    def residual_jacobian(self, layout: Layout, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(r_prior [M], its Jacobian [M, n_params]) by the network's hand-written backprop."""
        y_mid, j = layout.jacobian(x, self.x_mid)
        y_lo, j_lo = layout.jacobian(x, self.x_lo)
        y_hi, j_hi = layout.jacobian(x, self.x_hi)
        lam = self.lam.unsqueeze(1)
        jac = (j - (1 - lam) * j_lo - lam * j_hi).mul_(self.scale)
        r = self.scale * (y_mid - (1 - self.lam) * y_lo - self.lam * y_hi)
        return r, jac


def prior_rows(xs: torch.Tensor, columns: Sequence[int], level_scaled: np.ndarray, weight: float,
               rng: np.random.Generator, points_per_row: float = POINTS_PER_ROW) -> PriorRows | None:
    """The prior's rows for scaled training inputs `xs` [N, n_in] (data rows only), the control
    `columns` and each level's scaled value per column `level_scaled` [L, C]; None when the prior
    is off (weight 0, no control input, fewer than two levels)."""
    n = int(xs.shape[0])
    if weight <= 0 or not columns or len(level_scaled) < 2 or n == 0:
        return None
    m = max(1, int(math.ceil(points_per_row * n)))
    k = rng.integers(0, n, size=m)
    gap = rng.integers(0, len(level_scaled) - 1, size=m)
    lam = 0.1 + 0.8 * rng.random(m)
    lo, hi = level_scaled[gap], level_scaled[gap + 1]  # [M, C]
    base = xs[torch.as_tensor(k)].clone()
    x_lo, x_hi, x_mid = base.clone(), base.clone(), base
    cols = list(columns)
    x_lo[:, cols] = torch.as_tensor(lo, dtype=DTYPE)
    x_hi[:, cols] = torch.as_tensor(hi, dtype=DTYPE)
    x_mid[:, cols] = torch.as_tensor(lo + lam[:, None] * (hi - lo), dtype=DTYPE)
    return PriorRows(x_lo, x_hi, x_mid, torch.as_tensor(lam, dtype=DTYPE), math.sqrt(weight * n / m))
