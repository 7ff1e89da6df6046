"""Levenberg-Marquardt (Hagan & Menhaj 1994; MATLAB trainlm) on a least-squares problem.

Each epoch: one residual vector r and Jacobian J = dr/dx at x, then trial
steps dx = -(JᵀJ + mu I)⁻¹ Jᵀr solved by Cholesky. A trial that lowers the
sum of squared errors is taken and mu shrinks by mu_dec; otherwise mu grows
by mu_inc and the trial is repeated, until mu exceeds mu_max (or has grown
MAX_MU_INCREASES times in the epoch: a bound no setting can lift).
"""

from __future__ import annotations

import torch

from dampnet.training.loop import Converged
from dampnet.training.settings import MAX_MU_INCREASES, check_settings, defaults

DEFAULTS = defaults("lm")


def gram(J: torch.Tensor) -> torch.Tensor:
    """JᵀJ [P, P] for a Jacobian J [N, P] (float64, on the CPU).

    numpy's matmul of a matrix with its own transpose calls BLAS syrk, which computes one triangle:
    half the work of the general product torch calls (one thread, the thesis plan's 151-weight
    Jacobians: 24.8 against 46.5 ms at 100 Hz, 59.5 against 108.5 at 200 Hz, bench/epoch_cost.py).
    numpy's BLAS runs on fit's thread count (fit._training_threads)."""
    a = J.detach().T.numpy()  # [P, N]: the problem's Jacobian buffer itself, no copy
    return torch.from_numpy(a @ a.T)


def damped_solve(jj: torch.Tensor, rhs: torch.Tensor, diag: float) -> torch.Tensor | None:
    """Solve (jj + diag I) dx = rhs by Cholesky; None if not positive definite."""
    a = jj.clone()
    a.diagonal().add_(diag)
    L, info = torch.linalg.cholesky_ex(a)
    if int(info) != 0:
        return None
    return torch.cholesky_solve(rhs.unsqueeze(1), L).squeeze(1)


def damping_trials(algo, what: str):
    """The damping values to try in one epoch of LM or BR: algo.mu, then algo.mu * mu_inc after
    each rejected trial (the caller returns on an accepted one). Converged when mu exceeds mu_max
    or after MAX_MU_INCREASES increases: so an epoch ends whatever the settings."""
    s = algo.settings
    for _ in range(MAX_MU_INCREASES + 1):
        if not algo.mu <= s["mu_max"]:
            raise Converged(f"mu exceeded mu_max {s['mu_max']:g} (no step lowers the {what})")
        yield algo.mu
        algo.mu *= s["mu_inc"]
    raise Converged(f"mu was raised {MAX_MU_INCREASES} times in one epoch (mu_inc {s['mu_inc']:g}) and no step "
                    f"lowered the {what}")


class LevenbergMarquardt:
    """One LM epoch per step(); settings as MATLAB trainlm (see DEFAULTS).

    min_grad applies to the gradient of the training MSE, 2 Jᵀr / N.
    """

    name = "lm"

    def __init__(self, problem, x0: torch.Tensor, **settings):
        self.settings = check_settings(self.name, settings)
        self.problem = problem
        self.x = x0.clone()
        self.mu = float(self.settings["mu"])

    def step(self) -> dict:
        s, p = self.settings, self.problem
        r, J = p.residual_jacobian(self.x)
        sse = float(r @ r)
        g = J.T @ r
        jj = gram(J)
        grad_norm = 2.0 * float(g.norm()) / p.n_train
        if grad_norm < s["min_grad"]:
            raise Converged(f"gradient {grad_norm:.3g} below min_grad {s['min_grad']:g}")
        for mu in damping_trials(self, "error"):
            dx = damped_solve(jj, g, mu)
            if dx is not None:
                x2 = self.x - dx
                r2 = p.residual(x2)
                sse2 = float(r2 @ r2)
                if sse2 < sse:
                    self.x = x2
                    self.mu = max(self.mu * s["mu_dec"], 1e-20)
                    return {"train": sse2 / p.n_train, "mu": self.mu, "grad": grad_norm}
