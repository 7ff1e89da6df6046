"""Derived input features (what the diagnosis adds to a model), registered in the training registry
when dampnet.train.features is imported.

  voltage_lag / current_lag  the control after a first-order lag, time constant
                             feature_params["control_lag_tau_s"] [s] (valve or coil dynamics)
  velocity_lag               the velocity after a first-order lag, time constant
                             feature_params["velocity_lag_tau_s"] [s] (oil compressibility)
  friction_state             the Dahl friction state z in [-1, 1] with pre-sliding length
                             feature_params["friction_presliding_m"] [m] (seal stick-slip)

Each lag is the exact discretisation for an input held over a sample:
y[k] = a y[k-1] + (1 - a) u[k], a = exp(-dt/tau), y[0] = u[0] (steady state at
the first sample); the Dahl state advances by each sample's travel |v| dt.
They are computed on the dyno's full sample rate, where they are the
continuous quantities the loops carry as states with their own exact updates
(cpp/include/dampnet/loop.hpp `motion_lag`, mirrored by
dampnet.ride.pyloop.NeuralLoopDamper): they agree as the sample time goes to 0
(tests/python/test_loop_derived_features.py). Registered only if the name is
not already in the registry (another module may own it).
"""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

from dampnet.train.features import FEATURES, register_feature

#: the Dahl friction state's feature_params key (pre-sliding travel [m])
PRESLIDING_KEY = "friction_presliding_m"

#: feature name -> (source channel, feature_params key, unit)
LAG_FEATURES = {
    "voltage_lag": ("voltage", "control_lag_tau_s", "V"),
    "current_lag": ("current", "control_lag_tau_s", "A"),
    "velocity_lag": ("velocity", "velocity_lag_tau_s", "m/s"),
}


def first_order_lag(x: np.ndarray, dt: float, tau: float) -> np.ndarray:
    """y[k] = a y[k-1] + (1 - a) x[k], a = exp(-dt/tau), y[0] = x[0] (tau <= 0: a copy of x)."""
    x = np.asarray(x, dtype=np.float64)
    if tau <= 0 or x.size == 0:
        return x.copy()
    a = float(np.exp(-dt / tau))
    y, _ = lfilter([1.0 - a], [1.0, -a], x, zi=np.array([a * x[0]]))
    return y


def _lag_getter(channel: str, key: str):
    def get(test, params=None):
        params = params or {}
        if key not in params:
            raise KeyError(f"feature_params[{key!r}]")
        return first_order_lag(test.channels[channel], test.dt, float(params[key]))
    get.channel = channel
    return get


def register() -> None:
    for name, (channel, key, unit) in LAG_FEATURES.items():
        if name not in FEATURES:
            register_feature(name, unit, _lag_getter(channel, key), 0.0 if channel == "velocity" else None)
    if "friction_state" not in FEATURES:
        register_feature("friction_state", "1", _dahl_getter, None)


def dahl_state(v: np.ndarray, dt: float, presliding_m: float) -> np.ndarray:
    """Dahl friction state z in [-1, 1]: z[k] = s + (z[k-1] - s) exp(-|v[k]| dt / x_c), s = sign(v[k]).

    z follows the direction of motion and, after a reversal, swings from -1 to +1
    over a travel of a few pre-sliding lengths x_c [m]; z[0] = sign(v[0]).
    """
    v = np.asarray(v, dtype=np.float64)
    z = np.empty_like(v)
    if v.size == 0:
        return z
    s = np.sign(v)
    travel = np.concatenate(([0.0], np.cumsum(np.abs(v) * dt)))  # travel[k+1]: up to sample k
    # Within a run of constant sign s the recursion is z = s + (z_before - s) exp(-travel / x_c).
    edges = np.concatenate(([0], np.nonzero(np.diff(s))[0] + 1, [v.size]))
    z_before = s[0]
    xc = max(presliding_m, 1e-12)
    for a, b in zip(edges[:-1], edges[1:]):
        sig = s[a]
        z[a:b] = sig + (z_before - sig) * np.exp(-(travel[a + 1:b + 1] - travel[a]) / xc)
        z_before = z[b - 1]
    return z


def _dahl_getter(test, params=None):
    params = params or {}
    if PRESLIDING_KEY not in params:
        raise KeyError(f"feature_params[{PRESLIDING_KEY!r}]")
    return dahl_state(test.channels["velocity"], test.dt, float(params[PRESLIDING_KEY]))


_dahl_getter.channel = "velocity"


register()
