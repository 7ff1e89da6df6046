"""Input features as data: one registry, name -> (unit, how to get it from a test, value at rest),
the derived features, and the one feature-matrix builder (`feature_matrix`).

Base features are channels of a test (velocity, acceleration, displacement, voltage,
current, temperature). Derived features (what the diagnosis adds to a model):

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
dampnet.sim.reference_loop.NeuralLoopDamper): they agree as the sample time goes to 0
(tests/python/test_loop_derived_features.py).

`at_rest` is the value the feature takes when the damper is at rest, used for
the zero-force points (dampnet.training.fit): kinematic quantities are 0 at
rest, while control and state inputs can take any value at rest (None), so
zero points copy them from measured samples.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass
from typing import Any, Callable, Sequence

import numpy as np
from scipy.signal import lfilter

from dampnet.data import DataError, Dataset, DynoTest
from dampnet.data.preprocess import acceleration_of
from dampnet.schema import show


@dataclass(frozen=True)
class Feature:
    unit: str  # SI unit of the feature
    get: Callable[[Any], np.ndarray]  # test -> values [n_samples]
    at_rest: float | None  # value when the damper is at rest, None: any value


def _channel(name: str) -> Callable[[Any], np.ndarray]:
    def get(test: Any) -> np.ndarray:
        return test.channels[name]
    get.channel = name  # type: ignore[attr-defined]  # for error messages
    return get


FEATURES: dict[str, Feature] = {
    "velocity": Feature("m/s", _channel("velocity"), 0.0),
    "acceleration": Feature("m/s^2", _channel("acceleration"), 0.0),
    "displacement": Feature("m", _channel("displacement"), None),
    "voltage": Feature("V", _channel("voltage"), None),
    "current": Feature("A", _channel("current"), None),
    "temperature": Feature("degC", _channel("temperature"), None),
}


def register_feature(name: str, unit: str, get: Callable[[Any], np.ndarray],
                     at_rest: float | None = None) -> None:
    """Add (or replace) a feature, e.g. a derived one computed from a test's channels."""
    FEATURES[name] = Feature(unit, get, at_rest)


def feature(name: str) -> Feature:
    try:
        return FEATURES[name]
    except KeyError:
        raise KeyError(f"unknown feature {name!r}; known: {', '.join(sorted(FEATURES))}") from None


def units_of(features: Sequence[str]) -> list[str]:
    return [feature(f).unit for f in features]


def target_vector(tests: Sequence[Any], channel: str = "force") -> np.ndarray:
    """Concatenate one channel (default the force [N]) of every test."""
    out = []
    for i, test in enumerate(tests):
        try:
            out.append(np.asarray(test.channels[channel], dtype=np.float64).ravel())
        except KeyError:
            raise KeyError(f"test {i} ({getattr(test, 'test_id', '?')}) has no channel {channel!r}") from None
    return np.concatenate(out) if out else np.empty(0)


# -- derived features ------------------------------------------------------------
#: the Dahl friction state's feature_params key (pre-sliding travel [m])
PRESLIDING_KEY = "friction_presliding_m"

#: feature name -> (source channel, feature_params key, unit)
LAG_FEATURES = {
    "voltage_lag": ("voltage", "control_lag_tau_s", "V"),
    "current_lag": ("current", "control_lag_tau_s", "A"),
    "velocity_lag": ("velocity", "velocity_lag_tau_s", "m/s"),
}


def first_order_lag(x, dt: float, tau: float) -> np.ndarray:
    """y[k] = a y[k-1] + (1 - a) x[k], a = exp(-dt/tau), y[0] = x[0], along the last axis
    (tau <= 0: a copy of x). The exact discretisation for an input held over each sample."""
    x = np.asarray(x, dtype=np.float64)
    if tau <= 0 or x.size == 0:
        return x.copy()
    a = float(np.exp(-dt / tau))
    y, _ = lfilter([1.0 - a], [1.0, -a], x, axis=-1, zi=a * x[..., :1])
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


# -- the feature matrix ----------------------------------------------------------

def default_features(ds: Dataset) -> list[str]:
    """velocity, acceleration and the data's control channel (voltage or current)."""
    control = ds.tests[0].control_name if ds.tests else "voltage"
    return ["velocity", "acceleration", control]


def _feature_column(test: DynoTest, name: str, feature_params: dict[str, float]) -> np.ndarray:
    get = feature(name).get
    try:
        n_params = len(inspect.signature(get).parameters)
    except (TypeError, ValueError):
        n_params = 1
    return np.asarray(get(test, feature_params) if n_params >= 2 else get(test), dtype=np.float64).ravel()


def feature_matrix(tests: Sequence[DynoTest], features: Sequence[str],
                   feature_params: dict[str, float] | None = None,
                   acceleration_window: float | int | None = None) -> np.ndarray:
    """X [samples, len(features)] of `tests`, via the feature registry.

    Derives acceleration (on a copy of the test's channels) if a test lacks it.
    Raises DataError naming the feature, the test and the channels it has when a
    test cannot provide a feature (e.g. a model trained with temperature, data without).
    """
    unknown = [f for f in features if f not in FEATURES]
    if unknown:
        raise DataError(f"unknown feature(s) {unknown}; known: {', '.join(sorted(FEATURES))}")
    params = dict(feature_params or {})
    blocks = []
    for t in tests:
        cols = []
        for f in features:
            if f == "acceleration" and "acceleration" not in t.channels:
                try:
                    cols.append(acceleration_of(t, acceleration_window))
                except DataError:
                    raise DataError(f"test {t.test_id}: feature 'acceleration' needs a velocity or "
                                    "displacement channel") from None
                continue
            try:
                cols.append(_feature_column(t, f, params))
            except KeyError as e:
                have = ", ".join(sorted(t.channels))
                raise DataError(f"test {t.test_id}: feature {f!r} needs channel {e.args[0]!r}, which "
                                f"the data do not have (channels: {have})") from None
        if len({len(c) for c in cols}) > 1 or (cols and len(cols[0]) != len(t)):
            raise DataError(f"test {t.test_id}: features {list(features)} have lengths "
                            f"{[len(c) for c in cols]}, expected {len(t)}")
        blocks.append(np.stack(cols, axis=1) if cols else np.empty((len(t), 0)))
    return np.concatenate(blocks) if blocks else np.empty((0, len(features)))


def check_features(model: Any, ds: Dataset) -> None:
    """Raise DataError if a test of `ds` cannot provide one of the model's features."""
    for t in ds.tests:
        for f in model.features:
            if f == "acceleration" and ("velocity" in t.channels or "displacement" in t.channels):
                continue
            getter = FEATURES.get(f)
            channel = getattr(getattr(getter, "get", None), "channel", None)
            if getter is None:
                raise DataError(f"the model needs feature {show(f)}, which this dampnet does not know")
            if channel is not None and channel not in t.channels:
                raise DataError(f"test {t.test_id}: the model was trained on features "
                                f"{show(', '.join(model.features))}, but the data have no {channel!r} channel "
                                f"(channels: {', '.join(sorted(t.channels))})")
