"""Levenberg-Marquardt (Hagan & Menhaj 1994; MATLAB trainlm) on a least-squares problem.

Each epoch: one residual vector r and Jacobian J = dr/dx at x, then trial
steps dx = -(JᵀJ + mu I)⁻¹ Jᵀr solved by Cholesky. A trial that lowers the
sum of squared errors is taken and mu shrinks by mu_dec; otherwise mu grows
by mu_inc and the trial is repeated, until mu exceeds mu_max.
"""

from __future__ import annotations

import torch

from dampnet.training.loop import Converged

DEFAULTS = {"mu": 1e-3, "mu_dec": 0.1, "mu_inc": 10.0, "mu_max": 1e10, "min_grad": 1e-7}


def damped_solve(jj: torch.Tensor, rhs: torch.Tensor, diag: float) -> torch.Tensor | None:
    """Solve (jj + diag I) dx = rhs by Cholesky; None if not positive definite."""
    a = jj.clone()
    a.diagonal().add_(diag)
    L, info = torch.linalg.cholesky_ex(a)
    if int(info) != 0:
        return None
    return torch.cholesky_solve(rhs.unsqueeze(1), L).squeeze(1)


class LevenbergMarquardt:
    """One LM epoch per step(); settings as MATLAB trainlm (see DEFAULTS).

    min_grad applies to the gradient of the training MSE, 2 Jᵀr / N.
    """

    name = "lm"

    def __init__(self, problem, x0: torch.Tensor, **settings):
        unknown = set(settings) - set(DEFAULTS)
        if unknown:
            raise ValueError(f"lm: unknown settings {sorted(unknown)} (known: {sorted(DEFAULTS)})")
        self.settings = {**DEFAULTS, **settings}
        self.problem = problem
        self.x = x0.clone()
        self.mu = float(self.settings["mu"])

    def step(self) -> dict:
        s, p = self.settings, self.problem
        r, J = p.residual_jacobian(self.x)
        sse = float(r @ r)
        g = J.T @ r
        jj = J.T @ J
        grad_norm = 2.0 * float(g.norm()) / p.n_train
        if grad_norm < s["min_grad"]:
            raise Converged(f"gradient {grad_norm:.3g} below min_grad {s['min_grad']:g}")
        while self.mu <= s["mu_max"]:
            dx = damped_solve(jj, g, self.mu)
            if dx is not None:
                x2 = self.x - dx
                r2 = p.residual(x2)
                sse2 = float(r2 @ r2)
                if sse2 < sse:
                    self.x = x2
                    self.mu = max(self.mu * s["mu_dec"], 1e-20)
                    return {"train": sse2 / p.n_train, "mu": self.mu, "grad": grad_norm}
            self.mu *= s["mu_inc"]
        raise Converged(f"mu exceeded mu_max {s['mu_max']:g} (no step lowers the error)")
