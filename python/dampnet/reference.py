"""The one numpy forward of an MlpModel: the C++ kernel's function in float64.

What dn_mlp_forward does (cpp/include/dampnet/dampnet.h, mlp.hpp `prepare_inputs`), in order:

  * NaN input        -> the centre of its saturation range, (sat_lo + sat_hi) / 2
                        (the kernel's DN_W_NONFINITE_INPUT);
  * below sat_lo / above sat_hi, -Inf / +Inf included -> clamped to the limit
                        (DN_W_SATURATED);
  * mapminmax to [in_ymin, ...], hidden layer(s) (tanh or logistic), linear output,
    mapminmax inverse;
  * a non-finite output (only possible with weights near the float range, which
    dn_mlp_create refuses) -> out_offset (the kernel's DN_E_NONFINITE_OUTPUT).

So the output is finite for every input. Used by the diagnosis (dampnet.diagnosis.context),
the Python reference loop (dampnet.sim.quarter_car.reference_loop.NeuralLoopDamper) and the latency
benchmark's numpy candidate. It agrees with the kernel's double path and with
dampnet.training.torch_forward to rounding (tests/python/test_reference_forward.py: 1e-9
relative to the output range). Physics terms are not included (dampnet.predict adds them).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from dampnet.model import MlpModel


def _logistic(z: np.ndarray) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-z))


def forward_of(model: MlpModel) -> Callable[[np.ndarray], np.ndarray]:
    """A forward function x [..., n_inputs] (feature units) -> force [...] [N], with copies of
    the model's arrays taken now (later edits to the model do not change it)."""
    lo, hi = model.sat_lo.copy(), model.sat_hi.copy()
    mid = 0.5 * (lo + hi)
    off, gain, ymin = model.in_offset.copy(), model.in_gain.copy(), float(model.in_ymin)
    w1t, b1 = model.w1.T.copy(), model.b1.copy()
    w2t = None if model.w2 is None else model.w2.T.copy()
    b2 = None if model.b2 is None else model.b2.copy()
    w_out, b_out = model.w_out.copy(), float(model.b_out)
    out_ymin, out_gain, out_offset = float(model.out_ymin), float(model.out_gain), float(model.out_offset)
    act = np.tanh if model.activation == "tanh" else _logistic
    n_in = model.n_inputs

    def forward(x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        if x.shape[-1:] != (n_in,):
            raise ValueError(f"x: expected {n_in} inputs in the last axis, got shape {x.shape}")
        x = np.minimum(np.maximum(np.where(x != x, mid, x), lo), hi)  # NaN first: min/max keep it
        a = act(((x - off) * gain + ymin) @ w1t + b1)
        if w2t is not None:
            a = act(a @ w2t + b2)
        y = (a @ w_out + b_out - out_ymin) / out_gain + out_offset
        return np.where(np.isfinite(y), y, out_offset)

    return forward


def mlp_forward(model: MlpModel, x: np.ndarray) -> np.ndarray:
    """The network's output [N] for inputs x [..., n_inputs] in feature units (no physics terms)."""
    return forward_of(model)(x)
