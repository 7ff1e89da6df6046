"""What the training algorithms minimise: the network's squared error on the training set.

The algorithms see only this interface (so they can also be checked on
linear least squares and quadratics with known answers, see tests):

  n_params, n_train
  residual(x)            -> r [n_train] (= output - target, scaled units)
  residual_jacobian(x)   -> (r, J) with J = dr/dx [n_train, n_params]
  loss_grad(x, idx=None) -> (mean squared error, its gradient)   (SCG; Adam on batches idx)
  val_mse(x)             -> validation MSE, or None without a validation set

With priors (dampnet.training.control_prior, dampnet.training.monotone_prior: anything with
len() (its most rows), residual(layout, x) and residual_jacobian(layout, x, out), writing its
Jacobian into the [n_params, rows] buffer `out`) their rows follow the data rows in r and J,
in the order given, and loss/loss_grad add their squares over n_train: the objective is the
data's squared error plus the priors'. n_train counts the data rows only (BR's evidence and the
reported MSE use it). A prior's residual_jacobian may leave out rows that are zero there (the
monotone prior's satisfied rows): the algorithms use only r.r, J'r and J'J, so residual(x) and
residual_jacobian(x) may differ in length, never in r.r.
"""

from __future__ import annotations

import torch

from typing import Any, Sequence

from dampnet.training.net import DTYPE, Layout


class MlpProblem:
    """Squared error of an MLP (flat weights x) on scaled training/validation data."""

    def __init__(self, layout: Layout, x_train: torch.Tensor, t_train: torch.Tensor,
                 x_val: torch.Tensor | None = None, t_val: torch.Tensor | None = None,
                 prior: Any = None):
        self.layout = layout
        # None, one prior's rows, or several (None entries dropped)
        self.priors: list[Any] = [p for p in (prior if isinstance(prior, Sequence) else [prior]) if p is not None]
        self.xs, self.t = x_train.to(DTYPE), t_train.to(DTYPE)
        self.xv = None if x_val is None or len(x_val) == 0 else x_val.to(DTYPE)
        self.tv = None if self.xv is None else t_val.to(DTYPE)
        self.n_params = layout.n_params
        self.n_train = int(self.xs.shape[0])
        self._jbuf: torch.Tensor | None = None  # reused [P, rows] Jacobian storage (see Layout.jacobian)

    def residual(self, x: torch.Tensor) -> torch.Tensor:
        with torch.no_grad():
            r = self.layout.forward(x, self.xs) - self.t
            return torch.cat([r, *(p.residual(self.layout, x) for p in self.priors)]) if self.priors else r

    def residual_jacobian(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        # one [P, N + every prior's rows] buffer: the data's and each prior's Jacobian are written
        # into consecutive columns, so J is a view and never copied (a cat of the thesis plan's
        # data Jacobian moved 80 MB an epoch)
        n = self.n_train
        if self._jbuf is None:
            self._jbuf = torch.empty(self.n_params, n + sum(len(p) for p in self.priors), dtype=DTYPE)
        with torch.no_grad():
            y, _ = self.layout.jacobian(x, self.xs, out=self._jbuf[:, :n])
            r, used = [y - self.t], n
            for p in self.priors:  # a prior may return fewer rows than it has (the monotone prior)
                rp, jp = p.residual_jacobian(self.layout, x, out=self._jbuf[:, used:used + len(p)])
                r.append(rp)
                used += len(rp)
        return torch.cat(r) if self.priors else r[0], self._jbuf[:, :used].T

    def loss(self, x: torch.Tensor) -> float:
        r = self.residual(x)
        return float(r @ r) / self.n_train

    def loss_grad(self, x: torch.Tensor, idx: torch.Tensor | None = None) -> tuple[float, torch.Tensor]:
        """MSE and its gradient (autograd), over the training set or the samples idx."""
        xs, t = (self.xs, self.t) if idx is None else (self.xs[idx], self.t[idx])
        xg = x.detach().clone().requires_grad_(True)
        r = self.layout.forward(xg, xs) - t
        e = (r @ r) / len(t)
        for p in self.priors:  # the whole prior on every batch, as one share of the objective
            rp = p.residual(self.layout, xg)
            e = e + (rp @ rp) / self.n_train
        (g,) = torch.autograd.grad(e, xg)
        return float(e.detach()), g

    def val_mse(self, x: torch.Tensor) -> float | None:
        if self.xv is None:
            return None
        with torch.no_grad():
            r = self.layout.forward(x, self.xv) - self.tv
        return float(r @ r) / len(r)
