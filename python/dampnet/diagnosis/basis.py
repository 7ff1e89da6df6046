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

HINGES = np.linspace(-0.8, 0.8, 9)
SIGN_WIDTHS = (0.002, 0.01, 0.05)
STRIBECK_WIDTHS = (0.02, 0.06)


def velocity_basis(zv: np.ndarray) -> np.ndarray:
    cols = ([zv] + [np.maximum(zv - k, 0.0) for k in HINGES] + [np.tanh(zv / e) for e in SIGN_WIDTHS]
            + [np.sign(zv) * np.exp(-(zv / e) ** 2) for e in STRIBECK_WIDTHS])
    return np.stack(cols, axis=1)


def baseline_basis(z: np.ndarray, features: list[str]) -> np.ndarray:
    """Baseline columns [rows, p] from normalised model inputs z [rows, k]."""
    n = z.shape[0]
    cols = [np.ones((n, 1))]
    others = [j for j, f in enumerate(features) if f != "velocity"]
    if "velocity" in features:
        V = velocity_basis(z[:, features.index("velocity")])
        cols.append(V)
    else:
        V = None
    for j in others:
        g = z[:, j:j + 1]
        cols += [g, g * g]
        if V is not None:
            cols += [V * g, V * g * g]
            if features[j] in ("voltage", "current"):  # the control's effect is strongly nonlinear
                cols += [V * np.maximum(g - k, 0.0) for k in (-0.5, 0.0, 0.5)]
    for a in range(len(others)):
        for b in range(a + 1, len(others)):
            cols.append(z[:, others[a]:others[a] + 1] * z[:, others[b]:others[b] + 1])
    return np.hstack(cols)
