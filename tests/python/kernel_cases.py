"""Seeded random MLP models and inputs, and an independent torch float64 reference."""

from __future__ import annotations

import numpy as np
import torch

from dampnet.model import MlpModel

FORCE_RANGE = 4000.0  # [N] the output scaling of every random model below


def random_model(n_in: int, hidden: tuple[int, ...], activation: str, seed: int) -> MlpModel:
    rng = np.random.default_rng(seed)
    h1 = hidden[0]
    h2 = hidden[1] if len(hidden) > 1 else 0
    lo = rng.uniform(-3, 3, n_in)
    hi = lo + rng.uniform(0.5, 4, n_in)
    return MlpModel(
        w1=rng.normal(0, 1, (h1, n_in)), b1=rng.normal(0, 0.5, h1),
        w2=rng.normal(0, 1 / np.sqrt(h1), (h2, h1)) if h2 else None,
        b2=rng.normal(0, 0.5, h2) if h2 else None,
        w_out=rng.normal(0, 1, h2 or h1), b_out=rng.normal(0, 0.1),
        in_offset=lo, in_gain=2 / (hi - lo), out_offset=-FORCE_RANGE / 2, out_gain=2 / FORCE_RANGE,
        sat_lo=lo, sat_hi=hi, features=[f"x{i}" for i in range(n_in)], units=["1"] * n_in,
        activation=activation)


def random_inputs(model: MlpModel, n: int, seed: int, outside: float = 0.2) -> np.ndarray:
    """Inputs mostly inside the saturation range, a share `outside` beyond it."""
    rng = np.random.default_rng(seed)
    span = model.sat_hi - model.sat_lo
    return model.sat_lo + span * rng.uniform(-outside, 1 + outside, (n, model.n_inputs))


def torch_reference(model: MlpModel, x: np.ndarray) -> np.ndarray:
    """The documented forward pass in torch float64: clamp, mapminmax, layers, inverse scaling."""
    t = torch.as_tensor(x, dtype=torch.float64)
    t = torch.minimum(torch.maximum(t, torch.as_tensor(model.sat_lo)), torch.as_tensor(model.sat_hi))
    t = (t - torch.as_tensor(model.in_offset)) * torch.as_tensor(model.in_gain) + model.in_ymin
    act = torch.nn.Tanh() if model.activation == "tanh" else torch.nn.Sigmoid()
    layers = [(model.w1, model.b1)] + ([(model.w2, model.b2)] if model.w2 is not None else [])
    for w, b in layers:
        lin = torch.nn.Linear(w.shape[1], w.shape[0]).double()
        with torch.no_grad():
            lin.weight.copy_(torch.as_tensor(w))
            lin.bias.copy_(torch.as_tensor(b))
            t = act(lin(t))
    with torch.no_grad():
        ys = t @ torch.as_tensor(model.w_out) + model.b_out
    return ((ys - model.out_ymin) / model.out_gain + model.out_offset).numpy()


# Shapes spanning the supported range: inputs 1..8, one or two hidden layers of 1..64.
SHAPES = [
    (1, (1,), "tanh"), (1, (64,), "sigmoid"), (3, (30,), "tanh"), (3, (30,), "sigmoid"),
    (8, (64,), "tanh"), (8, (1,), "sigmoid"), (2, (5, 3), "tanh"), (4, (17, 9), "sigmoid"),
    (8, (64, 64), "tanh"), (6, (1, 64), "sigmoid"), (5, (64, 1), "tanh"), (7, (33, 12), "tanh"),
]

DOUBLE_TOL = 1e-12 * FORCE_RANGE  # double kernel: 1e-12 relative to the force range
FLOAT_TOL = 1e-5 * FORCE_RANGE    # float kernel: 1e-5 of the force range
