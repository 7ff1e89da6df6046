"""An independent float64 forward pass of an MlpModel in torch (a reference for the C++ kernel).

It follows the runtime contract of dampnet.h: clamp each input to
[sat_lo, sat_hi] (NaN -> centre of the range), mapminmax-scale, hidden
layers, linear output, unscale. It shares no code with the training
forward pass (dampnet.training.net) or with the C++ kernel.
"""

from __future__ import annotations

import numpy as np
import torch

from dampnet.model import MlpModel


def torch_forward(model: MlpModel, X: np.ndarray) -> np.ndarray:
    """Output (force [N]) for inputs X [n, n_inputs] in feature units, float64.

    Physics terms (hybrid models) are not evaluated: a model with terms
    raises ValueError rather than returning the network part silently.
    """
    if model.terms:
        raise ValueError("torch_forward evaluates the MLP only; this model has physics terms "
                         f"({[t.get('kind') for t in model.terms]})")
    t = lambda a: torch.as_tensor(np.asarray(a, dtype=np.float64))  # noqa: E731
    x = t(np.atleast_2d(X))
    if x.shape[1] != model.n_inputs:
        raise ValueError(f"X: expected {model.n_inputs} columns ({', '.join(model.features)}), "
                         f"got {x.shape[1]}")
    lo, hi = t(model.sat_lo), t(model.sat_hi)
    x = torch.where(torch.isnan(x), (lo + hi) / 2, x)
    x = torch.minimum(torch.maximum(x, lo), hi)
    a = (x - t(model.in_offset)) * t(model.in_gain) + model.in_ymin
    f = torch.tanh if model.activation == "tanh" else torch.sigmoid
    a = f(a @ t(model.w1).T + t(model.b1))
    if model.w2 is not None:
        a = f(a @ t(model.w2).T + t(model.b2))
    ys = a @ t(model.w_out) + model.b_out
    return ((ys - model.out_ymin) / model.out_gain + model.out_offset).numpy()
