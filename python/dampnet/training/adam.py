"""Adam (Kingma & Ba 2015) via torch.optim.Adam, for comparison with the second-order methods.

One epoch is one pass over the training set in mini-batches of `batch_size`
samples (None: the whole set, i.e. one full-batch step per epoch). The
learning rate decays by `lr_decay` per epoch (1.0: constant). Alternatively
`cosine_epochs=N` anneals it from `lr` to `lr_min` along a half cosine over
N epochs (then holds `lr_min`); it cannot be combined with `lr_decay`.
Both schedules are off by default, so the defaults are plain Adam.
"""

from __future__ import annotations

import math

import torch

from dampnet.training.settings import check_settings, defaults

DEFAULTS = defaults("adam")


class Adam:
    """Adam on `problem.loss_grad(x, idx)` (MSE of a batch); `generator` seeds the shuffling."""

    name = "adam"

    def __init__(self, problem, x0: torch.Tensor, generator: torch.Generator | None = None,
                 **settings):
        self.settings = check_settings(self.name, settings)
        self.problem = problem
        self.generator = generator or torch.Generator().manual_seed(0)
        self._w = x0.detach().clone().requires_grad_(True)
        s = self.settings
        self.opt = torch.optim.Adam([self._w], lr=s["lr"], betas=tuple(s["betas"]), eps=s["eps"])
        if s["cosine_epochs"] is None:
            self.sched = torch.optim.lr_scheduler.ExponentialLR(self.opt, gamma=s["lr_decay"])
        else:
            n, lr0, lr_min = int(s["cosine_epochs"]), s["lr"], s["lr_min"]  # checked: n >= 1, lr_decay 1

            def factor(epoch):
                f = min(epoch, n) / n
                return (lr_min + 0.5 * (lr0 - lr_min) * (1 + math.cos(math.pi * f))) / lr0

            self.sched = torch.optim.lr_scheduler.LambdaLR(self.opt, factor)

    @property
    def x(self) -> torch.Tensor:
        return self._w.detach()

    def step(self) -> dict:
        p, bs = self.problem, self.settings["batch_size"]
        n = p.n_train
        if bs is None or bs >= n:
            batches = [None]
        else:
            perm = torch.randperm(n, generator=self.generator)
            batches = [perm[i:i + bs] for i in range(0, n, bs)]
        for idx in batches:
            _, g = p.loss_grad(self._w.detach(), idx)
            self._w.grad = g
            self.opt.step()
        self.sched.step()
        return {"train": p.loss(self.x), "lr": self.opt.param_groups[0]["lr"]}
