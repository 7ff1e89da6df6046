"""Input features as data: a registry name -> (unit, how to get it from a test, value at rest).

To add a feature (a new channel or a derived quantity) add one entry here;
nothing else in training branches on feature names. `at_rest` is the value
the feature takes when the damper is at rest, used for the zero-force
points (see dampnet.train.fit): kinematic quantities are 0 at rest, while
control and state inputs (voltage, current, temperature, position) can take
any value at rest (None), so zero points copy them from measured samples.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Sequence

import numpy as np


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


def _test_name(test: Any, i: int) -> str:
    for attr in ("name", "id", "path"):
        v = getattr(test, attr, None)
        if v:
            return f"test {i} ({v})"
    return f"test {i}"


def features_matrix(tests: Sequence[Any], features: Sequence[str]) -> np.ndarray:
    """Stack the named features of every test into X [total samples, len(features)].

    Raises KeyError naming the feature and the test when a test lacks a
    channel, and ValueError when a test's features differ in length.
    """
    for f in features:
        feature(f)  # unknown names fail before any data is touched
    blocks = []
    for i, test in enumerate(tests):
        cols = []
        for f in features:
            try:
                col = np.asarray(FEATURES[f].get(test), dtype=np.float64).ravel()
            except KeyError as e:
                have = ", ".join(sorted(getattr(test, "channels", {}) or {}))
                raise KeyError(f"feature {f!r} needs channel {e.args[0]!r}, which "
                               f"{_test_name(test, i)} does not have (it has: {have})") from None
            cols.append(col)
        if len({len(c) for c in cols}) > 1:
            raise ValueError(f"{_test_name(test, i)}: features {list(features)} have different "
                             f"lengths {[len(c) for c in cols]}")
        blocks.append(np.stack(cols, axis=1))
    if not blocks:
        return np.empty((0, len(features)))
    return np.concatenate(blocks, axis=0)


def target_vector(tests: Sequence[Any], channel: str = "force") -> np.ndarray:
    """Concatenate one channel (default the force [N]) of every test."""
    out = []
    for i, test in enumerate(tests):
        try:
            out.append(np.asarray(test.channels[channel], dtype=np.float64).ravel())
        except KeyError:
            raise KeyError(f"{_test_name(test, i)} has no channel {channel!r}") from None
    return np.concatenate(out) if out else np.empty(0)


# Derived features (lagged control and velocity, Dahl friction state) register themselves.
from dampnet.train import derived as _derived  # noqa: E402,F401  (import for its registration)
