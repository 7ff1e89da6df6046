"""Shared pieces of the loop tests: random MLP models and a numpy forward pass."""

from __future__ import annotations

import numpy as np

from dampnet.model import MlpModel
from dampnet.reference import mlp_forward

# training ranges per feature (input units), wide enough for the loop tests
RANGES = {
    "velocity": (-2.0, 2.0), "acceleration": (-200.0, 200.0), "displacement": (-0.1, 0.1),
    "voltage": (0.0, 5.0), "current": (0.0, 1.2), "voltage_lag": (0.0, 5.0),
    "current_lag": (0.0, 1.2), "temperature": (-20.0, 120.0), "velocity_lag": (-2.0, 2.0),
    "friction_state": (-1.0, 1.0),
}
UNITS = {"velocity": "m/s", "acceleration": "m/s^2", "displacement": "m", "voltage": "V",
         "current": "A", "voltage_lag": "V", "current_lag": "A", "temperature": "degC",
         "velocity_lag": "m/s", "friction_state": "1"}


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
