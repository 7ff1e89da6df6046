"""The baseline basis: a flexible function of the model's own inputs.

A candidate effect is scored by what it explains of the residual *beyond* this
basis. The residual of a network that underfits contains functions of its own
inputs (a sharp friction knee near zero velocity, the control's nonlinearity);
that is a capacity problem, not missing physics, so it must not be credited to
any candidate. Columns, on the inputs scaled to [-1, 1] as the network sees them:

  V   velocity basis: v, hinges (v - k)+ at k = -0.8 ... 0.8, tanh(v / e) for
      e = 0.002, 0.01, 0.05 (sharp and soft sign functions: Coulomb friction) and
      sign(v) exp(-(v/s)^2), s = 0.02, 0.06 (a Stribeck peak): friction laws that are
      functions of velocity alone are within reach of a velocity-input model
  for every other input g: g, g^2 and V g, V g^2 (interactions: the control
      changes the force-velocity curve, acceleration its hysteresis)
  pairwise products of the other inputs, and a constant.

Without a velocity input V is the plain linear inputs.
"""

from __future__ import annotations

import numpy as np

from dampnet.features import FEATURES

HINGES = np.linspace(-0.8, 0.8, 9)
SIGN_WIDTHS = (0.002, 0.01, 0.05)
STRIBECK_WIDTHS = (0.02, 0.06)


def velocity_basis(zv: np.ndarray) -> np.ndarray:
    cols = ([zv] + [np.maximum(zv - k, 0.0) for k in HINGES] + [np.tanh(zv / e) for e in SIGN_WIDTHS]
            + [np.sign(zv) * np.exp(-(zv / e) ** 2) for e in STRIBECK_WIDTHS])
    return np.stack(cols, axis=1)


#: the control's hinges: its effect is strongly nonlinear, so V (g - h)+ interactions too
CONTROL_HINGES = (-0.5, 0.0, 0.5)


def _is_control(feature: str) -> bool:
    """The input holds the control as commanded (the feature registry's dn_damper_input.u: voltage, current)."""
    spec = FEATURES.get(feature)
    return spec is not None and spec.field == "u"


def _width(features: list[str], n_v: int) -> int:
    """Number of baseline columns for these features (n_v: velocity basis columns, 0 without)."""
    others = [f for f in features if f != "velocity"]
    per_input = [2 + (2 * n_v + (len(CONTROL_HINGES) * n_v if _is_control(f) else 0) if n_v else 0) for f in others]
    return 1 + n_v + sum(per_input) + len(others) * (len(others) - 1) // 2


def baseline_basis(z: np.ndarray, features: list[str]) -> np.ndarray:
    """Baseline columns [rows, p] from normalised model inputs z [rows, k].

    The blocks are computed into one preallocated array, not stacked from temporaries: at the
    16,000 rows of estimate.lag_with_spread the fresh temporaries' page faults cost as much as
    the arithmetic (15 -> 8 ms a call)."""
    n = z.shape[0]
    others = [j for j, f in enumerate(features) if f != "velocity"]
    V = velocity_basis(z[:, features.index("velocity")]) if "velocity" in features else None
    n_v = 0 if V is None else V.shape[1]
    out = np.empty((n, _width(features, n_v)))
    k = 0

    def block(width: int) -> np.ndarray:
        nonlocal k
        k += width
        return out[:, k - width:k]

    block(1)[:] = 1.0
    if V is not None:
        block(n_v)[:] = V
    for j in others:
        g = z[:, j:j + 1]
        block(1)[:] = g
        np.multiply(g, g, out=block(1))
        if V is not None:
            Vg = np.multiply(V, g, out=block(n_v))
            np.multiply(Vg, g, out=block(n_v))      # V g^2
            if _is_control(features[j]):
                for h in CONTROL_HINGES:
                    np.multiply(V, np.maximum(g - h, 0.0), out=block(n_v))
    for a in range(len(others)):
        for b in range(a + 1, len(others)):
            np.multiply(z[:, others[a]:others[a] + 1], z[:, others[b]:others[b] + 1], out=block(1))
    assert k == out.shape[1]
    return out
