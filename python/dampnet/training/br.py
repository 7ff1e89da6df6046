"""Bayesian regularisation (MacKay 1992; Foresee & Hagan 1997; MATLAB trainbr) on top of LM.

Minimises F = beta*E_D + alpha*E_W with E_D = sum of squared errors and
E_W = sum of squared weights. After each accepted LM step the evidence
framework re-estimates the hyperparameters with the Gauss-Newton Hessian
H = 2(beta JᵀJ + alpha I):
  gamma = P - 2 alpha tr(H⁻¹) = P - alpha tr((beta JᵀJ + alpha I)⁻¹)
  alpha = gamma / (2 E_W),  beta = (N - gamma) / (2 E_D)
gamma is the effective number of parameters the data determine.
"""

from __future__ import annotations

import torch

from dampnet.training.lm import damping_trials, gram
from dampnet.training.loop import Converged
from dampnet.training.settings import check_settings, defaults

DEFAULTS = defaults("br")


class BayesianRegularization:
    """One trainbr epoch per step(); `gamma`, `alpha`, `beta` are the current hyperparameters."""

    name = "br"

    def __init__(self, problem, x0: torch.Tensor, **settings):
        self.settings = check_settings(self.name, settings)
        self.problem = problem
        self.x = x0.clone()
        self.mu = float(self.settings["mu"])
        P, N = problem.n_params, problem.n_train
        r = problem.residual(self.x)
        sse, ssx = float(r @ r), float(self.x @ self.x)
        # MATLAB's start: every parameter counted as determined.
        self.gamma = float(P)
        self.beta = 1.0 if sse == 0 else (N - self.gamma) / (2 * sse)
        if self.beta <= 0:
            self.beta = 1.0
        self.alpha = 1.0 if ssx == 0 else self.gamma / (2 * ssx)

    def step(self) -> dict:
        s, p = self.settings, self.problem
        r, J = p.residual_jacobian(self.x)
        sse, ssx = float(r @ r), float(self.x @ self.x)
        perf = self.beta * sse + self.alpha * ssx
        jj = gram(J)
        g = self.beta * (J.T @ r) + self.alpha * self.x  # half the gradient of F
        grad_norm = 2.0 * float(g.norm()) / p.n_train
        if grad_norm < s["min_grad"]:
            raise Converged(f"gradient {grad_norm:.3g} below min_grad {s['min_grad']:g}")
        bjj = self.beta * jj
        for mu in damping_trials(self, "objective"):
            a = bjj.clone()
            a.diagonal().add_(mu + self.alpha)
            L, info = torch.linalg.cholesky_ex(a)
            if int(info) == 0:
                x2 = self.x - torch.cholesky_solve(g.unsqueeze(1), L).squeeze(1)
                r2 = p.residual(x2)
                sse2, ssx2 = float(r2 @ r2), float(x2 @ x2)
                if self.beta * sse2 + self.alpha * ssx2 < perf:
                    self.x = x2
                    self.mu = max(self.mu * s["mu_dec"], 1e-20)
                    self._update_hyper(bjj, sse2, ssx2)
                    return {"train": sse2 / p.n_train, "mu": self.mu, "gamma": self.gamma,
                            "alpha": self.alpha, "beta": self.beta}

    def _update_hyper(self, bjj: torch.Tensor, sse: float, ssx: float) -> None:
        """Evidence re-estimation (as trainbr: Hessian from this epoch's Jacobian)."""
        P, N = self.problem.n_params, self.problem.n_train
        a = bjj.clone()
        a.diagonal().add_(self.alpha)
        L, info = torch.linalg.cholesky_ex(a)
        if int(info) != 0:
            return
        # tr(A⁻¹) = ||L⁻¹||_F² for A = L Lᵀ.
        eye = torch.eye(P, dtype=a.dtype)
        linv = torch.linalg.solve_triangular(L, eye, upper=False)
        self.gamma = P - self.alpha * float((linv * linv).sum())
        self.alpha = 1.0 if ssx == 0 else self.gamma / (2 * ssx)
        self.beta = 1.0 if sse == 0 else (N - self.gamma) / (2 * sse)

    def stats(self) -> dict:
        return {"gamma": self.gamma, "alpha": self.alpha, "beta": self.beta,
                "n_params": self.problem.n_params}
