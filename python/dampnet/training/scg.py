"""Scaled conjugate gradient (Møller 1993, "A scaled conjugate gradient algorithm
for fast supervised learning", Neural Networks 6:525-533; MATLAB trainscg).

Conjugate directions without a line search: the curvature along p is a
finite difference of gradients, s = (E'(w + sigma_k p) - E'(w)) / sigma_k
with sigma_k = sigma / |p|, and a Levenberg-Marquardt-like scale lambda
keeps the local quadratic model positive definite and is adapted from the
comparison parameter Delta (actual vs predicted reduction). Numbered
comments follow the steps of the paper. Constants sigma = 5e-5 and
lambda = 5e-7 are trainscg's defaults.
"""

from __future__ import annotations

import torch

from dampnet.training.loop import Converged
from dampnet.training.settings import check_settings, defaults

DEFAULTS = defaults("scg")


class ScaledConjugateGradient:
    """One SCG iteration per step() on `problem.loss_grad` (any smooth E(x)).

    `restart`: restart with steepest descent every `restart` iterations
    (Møller: N = number of weights, the default when None).
    """

    name = "scg"

    def __init__(self, problem, x0: torch.Tensor, **settings):
        self.settings = check_settings(self.name, settings)
        self.problem = problem
        self.n_restart = self.settings["restart"] or problem.n_params
        # 1. Initial weights, scale, steepest-descent direction.
        self.x = x0.clone()
        self.E, g = problem.loss_grad(self.x)
        self.r = -g
        self.p = self.r.clone()
        self.lam = float(self.settings["lambda"])
        self.lam_bar = 0.0
        self.success = True
        self.k = 1
        self.delta = 0.0

    def step(self) -> dict:
        s, prob = self.settings, self.problem
        if float(self.r.norm()) < s["min_grad"]:
            raise Converged(f"gradient {float(self.r.norm()):.3g} below min_grad {s['min_grad']:g}")
        p, r = self.p, self.r
        p2 = float(p @ p)
        if p2 == 0.0:
            raise Converged("search direction vanished")
        # 2. Second-order information, only after a successful step.
        if self.success:
            sigma_k = s["sigma"] / p2 ** 0.5
            _, g_plus = prob.loss_grad(self.x + sigma_k * p)
            s_k = (g_plus + r) / sigma_k  # E'(w + sigma p) - E'(w), with E'(w) = -r
            self.delta = float(p @ s_k)
        # 3. Scale.
        delta = self.delta + (self.lam - self.lam_bar) * p2
        # 4. Make the Hessian model positive definite.
        if delta <= 0:
            self.lam_bar = 2.0 * (self.lam - delta / p2)
            delta = -delta + self.lam * p2
            self.lam = self.lam_bar
        # 5. Step size.
        mu = float(p @ r)
        alpha = mu / delta
        # 6. Comparison parameter.
        x_new = self.x + alpha * p
        E_new, g_new = prob.loss_grad(x_new)
        Delta = 2.0 * delta * (self.E - E_new) / (mu * mu) if mu != 0 else -1.0
        # 7. Accept or reject.
        if Delta >= 0:
            r_new = -g_new
            self.lam_bar = 0.0
            self.success = True
            if self.k % self.n_restart == 0:
                p_new = r_new.clone()  # restart
            else:
                beta = (float(r_new @ r_new) - float(r_new @ r)) / mu
                p_new = r_new + beta * p
            self.x, self.E, self.r, self.p = x_new, E_new, r_new, p_new
            if Delta >= 0.75:
                self.lam *= 0.25
        else:
            self.lam_bar = self.lam
            self.success = False
        # 8. Raise the scale when the quadratic model predicted poorly.
        if Delta < 0.25:
            self.lam += delta * (1.0 - Delta) / p2
        # 9. Next iteration (the caller's epoch counter).
        self.k += 1
        # Keep delta consistent for a repeated (unsuccessful) iteration: step 3 rescales it.
        self.delta = delta if not self.success else self.delta
        return {"train": self.E, "lambda": self.lam, "accepted": Delta >= 0}
