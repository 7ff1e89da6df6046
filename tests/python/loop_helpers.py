"""Shared pieces of the loop tests: random MLP models, a numpy forward pass and the damper
inverse's allowed force residual."""

from __future__ import annotations

import numpy as np

from dampnet.features import FEATURES
from dampnet.model import MlpModel
from dampnet.reference import mlp_forward

# training ranges of the measured channels (input units), wide enough for the loop tests; a
# derived feature (a registered state, dampnet.features) takes its source's range or, without
# one, [-1, 1]: a feature added by dampnet.h's recipe needs no line here (issue 52)
BASE_RANGES = {
    "velocity": (-2.0, 2.0), "acceleration": (-200.0, 200.0), "displacement": (-0.1, 0.1),
    "voltage": (0.0, 5.0), "current": (0.0, 1.2), "temperature": (-20.0, 120.0),
}


def feature_range(name: str) -> tuple[float, float]:
    if name in BASE_RANGES:
        return BASE_RANGES[name]
    source = getattr(getattr(FEATURES[name], "state", None), "source", None)
    return feature_range(source) if source else (-1.0, 1.0)


class _Ranges(dict):
    def __missing__(self, name):
        return feature_range(name)


class _Units(dict):
    def __missing__(self, name):
        return FEATURES[name].unit


#: RANGES[f], UNITS[f] for every registered feature (the runtime's and the registry's)
RANGES = _Ranges()
UNITS = _Units()


def random_model(features, hidden=12, seed=0, terms=(), feature_params=None, force_range=4000.0,
                 activation="tanh"):
    rng = np.random.default_rng(seed)
    n = len(features)
    lo = np.array([RANGES[f][0] for f in features])
    hi = np.array([RANGES[f][1] for f in features])
    return MlpModel(w1=rng.normal(0, 1.0, (hidden, n)), b1=rng.normal(0, 0.5, hidden),
                    w_out=rng.normal(0, 1.0, hidden) / np.sqrt(hidden), b_out=0.05,
                    in_offset=lo, in_gain=2.0 / (hi - lo), out_offset=-force_range / 2,
                    out_gain=2.0 / force_range, sat_lo=lo, sat_hi=hi, features=list(features),
                    units=[UNITS[f] for f in features], activation=activation, terms=list(terms),
                    feature_params=dict(feature_params or {}))


def numpy_forward(model: MlpModel, x: np.ndarray) -> np.ndarray:
    """The MLP in numpy, float64 (dampnet.reference, checked against torch and the kernel in
    tests/python/test_reference_forward.py); rows [n, n_inputs] -> force [n] [N]."""
    return mlp_forward(model, np.atleast_2d(x))


def inverse_allowance(damper, u: np.ndarray, motion: dict) -> np.ndarray:
    """The force residual [N] Damper.inverse's contract allows at its control u [n] (dn_types.h):
    the control within DN_INVERSE_TOL_REL of the control range of the root, so its force within
    that times |dF/du| of the demand; dF/du a central difference over 1e-6 of the range through
    Damper.forces at the motion (arrays [n] or scalars: every quantity but u)."""
    from dampnet import _core

    lo, hi = damper.control_range()
    u = np.asarray(u, dtype=float)
    up, dn = np.minimum(u + 1e-6 * (hi - lo), hi), np.maximum(u - 1e-6 * (hi - lo), lo)
    slope = np.abs(damper.forces(u=up, **motion)[0] - damper.forces(u=dn, **motion)[0]) / (up - dn)
    return _core.DN_INVERSE_TOL_REL * (hi - lo) * slope
