"""The control-interpolation prior: between the tested control levels the force follows the
smooth curve through the levels' forces at the same motion (what a lookup table assumes, with a
straight line; here the natural cubic spline through every level, a straight line for two).

Why: a dyno plan tests a few control levels (voltages or currents). Between them the data say
nothing, and a network fitted to two or three levels bends there wherever its seed puts it:
on the rig's quick plan (0 and 5 V trained, 2.25 V held out) plain training gave a held-out
NRMSE of 0.11-1.7 over seeds against the lookup table's 0.029 (bench/LOG.md, "Few dyno
tests"). The prior adds soft residual rows to the least-squares problem,

    r_prior = s * (f(k, u_m) - sum_l w_l(u_m) f(k, u_l)),  u_m = u_lo + lam (u_hi - u_lo),

at motion rows k drawn from the training rows (every input but the control kept), a gap
(u_lo, u_hi) between adjacent training levels u_l and lam in [0.1, 0.9]; w_l(u) are the natural
cubic spline's cardinal functions (the spline through values F_l at the levels is sum_l w_l F_l).
f is the network's scaled output, so the rows are linear in the output scaling. `weight` is the
prior's share against the data: the prior rows' summed squares count `weight` times as much, per
row, as the data rows' (s = sqrt(weight * n_data / n_points)). With two levels the reference is
the straight line and the model becomes the lookup table's interpolation of what it learned at
each level; with more, the spline follows the valve's curvature across levels, which a straight
line between adjacent levels would flatten (bench/LOG.md "Few dyno tests": 5 x 8 plan, seeds
0-3, median 0.0061 against 0.0075 with straight lines, measured with a prototype of these rows).

The control columns are the features the runtime reads from the control
(dampnet.features.control_columns: field u or u_lag, e.g. voltage and voltage_lag); each takes
the level's value (a lag is at its steady state at a held level). The levels are found in the
training rows (dampnet.features.control_levels: clusters of the control's values, each the
columns' mean over it), not taken from the tests' nominal levels: a measured control carries the
driver's offset (-0.0078 V for 0 V on the thesis data), and a test may step among levels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import torch

from dampnet.training.net import DTYPE, Layout

#: prior points per training row, at most (with L levels, 1/L: the work per point grows with L)
POINTS_PER_ROW = 0.25


@dataclass
class PriorRows:
    """The prior's rows: scaled inputs `xs` [L+1, M, n_in] (the point between levels, then the
    same motion at every training level), their coefficients `coef` [L+1, M] (1 for the point, -w_l
    for level l: w the natural cubic spline's weights through the levels at the point) and the
    scale s: r = s * sum_k coef_k f(xs_k) (Layout.combination)."""

    xs: torch.Tensor
    coef: torch.Tensor
    scale: float

    def __len__(self) -> int:
        return int(self.xs.shape[1])

    @property
    def x_mid(self) -> torch.Tensor:
        """The points between levels [M, n_in]."""
        return self.xs[0]

    @property
    def x_level(self) -> torch.Tensor:
        """The same motion at every training level [L, M, n_in]."""
        return self.xs[1:]

    @property
    def w(self) -> torch.Tensor:
        """The spline's weights of each level at each point [M, L]."""
        return -self.coef[1:].T

    def residual(self, layout: Layout, x: torch.Tensor) -> torch.Tensor:
        """r_prior [M], differentiable in the weights x."""
        return self.scale * layout.combination(x, self.xs, self.coef)

    def residual_jacobian(self, layout: Layout, x: torch.Tensor,
                          out: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """(r_prior [M], its Jacobian [M, n_params]) by the network's hand-written backprop; the
        Jacobian is the transposed view of `out` [n_params, M] when given (MlpProblem's buffer)."""
        r, jac = layout.combination_jacobian(x, self.xs, self.coef, out=out)
        return self.scale * r, jac.mul_(self.scale)


def spline_weights(levels: np.ndarray, at: np.ndarray) -> np.ndarray:
    """[len(at), L]: the natural cubic spline through values at `levels` (sorted, L >= 2),
    evaluated at `at`, is these weights times the values (a straight line for two levels)."""
    if len(levels) == 2:
        lam = (at - levels[0]) / (levels[1] - levels[0])
        return np.stack([1 - lam, lam], axis=1)
    from scipy.interpolate import CubicSpline

    return CubicSpline(levels, np.eye(len(levels)), bc_type="natural")(at)


def prior_rows(xs: torch.Tensor, columns: Sequence[int], level_scaled: np.ndarray, weight: float,
               rng: np.random.Generator) -> PriorRows | None:
    """The prior's rows for scaled training inputs `xs` [N, n_in] (data rows only), the control
    `columns` and each level's scaled value per column `level_scaled` [L, C] (sorted by level);
    None when the prior is off (weight 0, no control input, fewer than two levels)."""
    n, n_levels = int(xs.shape[0]), len(level_scaled)
    if weight <= 0 or not columns or n_levels < 2 or n == 0:
        return None
    m = max(1, int(math.ceil(min(POINTS_PER_ROW, 1.0 / n_levels) * n)))
    k = rng.integers(0, n, size=m)
    gap = rng.integers(0, n_levels - 1, size=m)
    lam = 0.1 + 0.8 * rng.random(m)
    lo, hi = level_scaled[gap], level_scaled[gap + 1]  # [M, C]
    base = xs[torch.as_tensor(k)]
    cols = list(columns)
    x_level = base.unsqueeze(0).repeat(n_levels, 1, 1)
    x_level[:, :, cols] = torch.as_tensor(level_scaled, dtype=DTYPE).unsqueeze(1)
    x_mid = base.clone()
    x_mid[:, cols] = torch.as_tensor(lo + lam[:, None] * (hi - lo), dtype=DTYPE)
    # the reference along the first control column (the others are its lags: the same values)
    t = level_scaled[:, 0]
    w = torch.as_tensor(spline_weights(t, t[gap] + lam * (t[gap + 1] - t[gap])), dtype=DTYPE)
    return PriorRows(torch.cat([x_mid.unsqueeze(0), x_level]), torch.cat([torch.ones(1, m, dtype=DTYPE), -w.T]),
                     math.sqrt(weight * n / m))
