"""The epoch loop shared by every algorithm: validation early stopping, history, progress.

An algorithm is an object with `x` (current weights, a float64 tensor),
`name`, `settings` (dict), `step() -> dict` (one epoch; the dict holds at
least 'train', the training MSE after the step) and optionally `stats()`
(final extra numbers, e.g. BR's effective number of parameters). `step`
raises `Converged(reason)` when the algorithm's own criterion stops it.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Callable

import torch


class Converged(Exception):
    """Raised by an algorithm's step() with the reason it cannot or need not go on."""


@dataclass
class RunResult:
    x: torch.Tensor  # weights returned: best validation epoch, or the last one
    history: list[dict[str, Any]] = field(default_factory=list)
    epochs: int = 0
    best_epoch: int = 0
    stop_reason: str = ""
    time_s: float = 0.0


def run(algo, problem, *, max_epochs: int, max_fail: int | None = 6,
        progress: Callable[[dict], Any] | None = None, goal: float = 0.0) -> RunResult:
    """Run epochs until max_epochs, goal, the algorithm's own stop, or validation failure.

    Validation stopping (MATLAB's max_fail): when the validation MSE has not
    improved for `max_fail` consecutive epochs, stop and return the weights of
    the best validation epoch. max_fail=None monitors validation but never
    stops on it (and returns the last weights). `progress(record)` is called
    after each epoch; returning True stops training ('stopped by caller').
    """
    t0 = time.perf_counter()
    val0 = problem.val_mse(algo.x)
    history = [{"epoch": 0, "train": problem.loss(algo.x), "val": val0, "time_s": 0.0}]
    best_val, best_x, best_epoch, fails = (math.inf if val0 is None else val0), algo.x.clone(), 0, 0
    reason, epoch = f"reached max_epochs ({max_epochs})", 0
    for epoch in range(1, max_epochs + 1):
        try:
            rec = algo.step()
        except Converged as e:
            epoch -= 1
            reason = str(e)
            break
        val = problem.val_mse(algo.x)
        rec = {"epoch": epoch, **rec, "val": val, "time_s": time.perf_counter() - t0}
        history.append(rec)
        if val is not None and val < best_val:
            best_val, best_x, best_epoch, fails = val, algo.x.clone(), epoch, 0
        elif val is not None and val > best_val:
            fails += 1  # as MATLAB: an equal value is neither a gain nor a failure
        if progress is not None and progress(rec):
            reason = "stopped by caller"
            break
        if not math.isfinite(rec["train"]):
            reason = "training error became non-finite"
            break
        if rec["train"] <= goal:
            reason = f"reached goal (train MSE <= {goal})"
            break
        if max_fail is not None and val is not None and fails >= max_fail:
            reason = f"validation error rose for {max_fail} epochs (max_fail)"
            break
    use_best = max_fail is not None and val0 is not None
    x = best_x if use_best else algo.x.clone()
    return RunResult(x=x, history=history, epochs=epoch, best_epoch=best_epoch if use_best else epoch,
                     stop_reason=reason, time_s=time.perf_counter() - t0)
