"""The velocity-monotone prior: a damper's force rises with velocity, at any acceleration and
control level inside the envelope, so the network is asked to as well.

Why: the data constrain the network only along the tests' paths. Between them, and between the
control levels, nothing stops a fit from letting the force fall as velocity rises, which no
passive or semi-active damper does (the orifice, the shims, the seal friction and the oil's
lag all rise with velocity). Measured before this prior (issue 33, rig quick plan and 5 x 8
plan, seeds 0-2): the force fell with velocity at up to 0.9 % of the training samples and up
to 0.4 % between the levels, by up to 36 N over 1 % of the velocity range
(`dampnet.evaluation.structure` measures the same thing on every trained model).

The prior adds one soft residual row per point k,

    r_mono = s * max(0, f(x_k - h e_v) - f(x_k + h e_v) + c),

at inputs x_k: every training row as it is (its own control level), and as many again drawn from
the training rows with the control columns set to a value drawn uniformly between the lowest and
highest training level (the other inputs kept: the motion is the tests'); e_v is the velocity
column, h = STEP (scaled units: 1 % of the velocity range, the step `evaluation.structure`
checks with), f the network's scaled output and c = MARGIN a small rise asked for (0.1 % of the
force range over the step: the rig's damper rises by 0.5 % or more there, its laminar flow
alone; without it the force still fell by up to 13 N between the rows the prior saw). Both sets
are needed: measured on the quick plan (seed 1), points drawn between the levels alone left the
force falling at 0.4 % of the rows at the 5 V level itself, where no drawn point lies. A row is zero where the force rises,
so the prior leaves a monotone fit as it is and costs two forward passes per point there (a
small share of an epoch: the data rows' Jacobian costs about the parameter count in forward
passes); only violated rows carry a Jacobian, and residual_jacobian returns those alone.
`weight` is its share against the data as the control prior's is (s = sqrt(weight * n_data /
n_points)): the prior's mean square counts `weight` times as much as the data's (with the drawn
points, 2 n_data of them, each counts weight / 2 times a data row). Since only violations count,
the weight to give it is large (RECOMMENDED_WEIGHT).

Why it is off by default (dampnet.training.settings.OPTIONS; issue 33, bench/LOG.md "Few dyno
tests"): where the data are dense they hold the network monotone already, and the prior only
costs. On the thesis plan (2.25 V held out, seeds 0 and 1) the force fell with velocity at none of
the training samples without it; with weight 100 the held-out NRMSE rose from 0.0037 / 0.0045 to
0.0042 / 0.0049 (2.88x / 3.52x the noise floor to 3.2x / 3.89x) and a training took 2-3x as long
(more epochs before early stopping, more work per epoch). On sparse plans it holds the structure
at no cost in accuracy (quick plan, seeds 0-8: held-out NRMSE 0.0310-0.0338, at the interpolation
floor 0.0316; 5 x 8, seeds 0-9: median 0.0064 with it, 0.0067 without) but trains 2-3x as long. `dampnet train` says when the force
falls with velocity anywhere in the training samples and names --monotone-prior.

Its Jacobian is piecewise the difference of two forward Jacobians (Layout.combination_jacobian;
checked against torch autograd in tests/python/test_monotone_prior.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import torch

from dampnet.training.net import DTYPE, Layout

#: the rise asked for over the step 2h, in scaled output units ([-1, 1] over the force range): 0.1 % of it
MARGIN = 0.002
#: prior points per training row with the control drawn between the levels (besides every row at its own)
DRAWN_PER_ROW = 1.0
#: the weight to give the prior when it is wanted (only violated rows count, so a large one)
RECOMMENDED_WEIGHT = 100.0
#: the velocity step each side, in scaled input units ([-1, 1] over the training range): 1 % of it
STEP = 0.02


@dataclass
class MonotoneRows:
    """The prior's rows: scaled inputs a step below (`x_lo`) and above (`x_hi`) in velocity
    [M, n_in], and the scale s; r = s * max(0, f(x_lo) - f(x_hi) + MARGIN)."""

    x_lo: torch.Tensor
    x_hi: torch.Tensor
    scale: float

    def __len__(self) -> int:
        return int(self.x_lo.shape[0])

    def residual(self, layout: Layout, x: torch.Tensor) -> torch.Tensor:
        """r_mono [M], differentiable in the weights x."""
        return self.scale * torch.relu(layout.forward(x, self.x_lo) - layout.forward(x, self.x_hi) + MARGIN)

    def residual_jacobian(self, layout: Layout, x: torch.Tensor,
                          out: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """(r, J) of the violated rows only (r > 0), by the network's hand-written backprop: the
        others are zero rows, which add nothing to r.r, J'r or J'J (all the algorithms use), and
        most rows are zero once the fit is monotone. J is the transposed view of the first columns
        of `out` [n_params, M] when given (MlpProblem's buffer)."""
        drop = layout.forward(x, self.x_lo) - layout.forward(x, self.x_hi) + MARGIN
        active = torch.nonzero(drop > 0).flatten()
        if not len(active):
            return drop[:0], torch.zeros(0, layout.n_params, dtype=DTYPE)
        pair = torch.stack([self.x_lo[active], self.x_hi[active]])
        coef = torch.tensor([[1.0], [-1.0]], dtype=DTYPE).expand(2, len(active))
        _, jac = layout.combination_jacobian(x, pair, coef, out=None if out is None else out[:, :len(active)])
        return self.scale * drop[active], jac.mul_(self.scale)


def monotone_rows(xs: torch.Tensor, velocity: int, control_columns: Sequence[int],
                  control_range: tuple[np.ndarray, np.ndarray] | None, weight: float,
                  rng: np.random.Generator) -> MonotoneRows | None:
    """The prior's rows for scaled training inputs `xs` [N, n_in] (data rows only), the velocity
    column, and the control columns with their scaled values at the lowest and highest training
    level ([C] each; None: the rows keep their own control; a lag column moves with its control,
    as at a held level); None when the prior is off (weight 0, no rows)."""
    n = int(xs.shape[0])
    if weight <= 0 or n == 0:
        return None
    base = xs.clone()
    if control_columns and control_range is not None:
        m = max(1, int(math.ceil(DRAWN_PER_ROW * n)))
        drawn = xs[torch.as_tensor(rng.integers(0, n, size=m))].clone()
        lo, hi = (np.asarray(a, dtype=np.float64) for a in control_range)
        lam = rng.random(m)[:, None]
        drawn[:, list(control_columns)] = torch.as_tensor(lo + lam * (hi - lo), dtype=DTYPE)
        base = torch.cat([base, drawn])
    x_lo, x_hi = base.clone(), base
    x_lo[:, velocity] -= STEP
    x_hi[:, velocity] += STEP
    return MonotoneRows(x_lo, x_hi, math.sqrt(weight * n / len(base)))
