"""Input features: the registry, the derived features, and the one feature-matrix builder.

The runtime defines the features: their names, the dn_damper_input field each is read
from and the feature parameter each needs are dampnet.h's DN_FEATURE_LIST and
DN_FEATURE_PARAM_LIST, read here from `_core` (FEATURE_NAMES, FEATURE_INPUTS,
FEATURE_PARAMS, FEATURE_PARAM_NAMES). This module adds only what Python needs on top
(`_PYTHON_SIDE`): the unit, how the column is computed from a dyno test, and the value at
rest. tests/python/test_feature_registry.py fails when the two lists differ.

Base features are channels of a test (velocity, acceleration, displacement, voltage,
current, temperature). A derived feature declares its kind of state, which is both its
training formula (on the dyno's samples) and its update in the Python reference loop:

  Lag(source, held)  a first-order lag of the base feature `source`, time constant its
                     parameter [s] (voltage_lag / current_lag: valve or coil dynamics,
                     velocity_lag: oil compressibility)
  Dahl()             the Dahl friction state z in [-1, 1], pre-sliding travel its parameter
                     [m] (friction_state: seal stick-slip)

On the dyno's samples a lag is the exact discretisation for an input held over a
sample, y[k] = a y[k-1] + (1 - a) u[k], a = exp(-dt/tau), y[0] = u[0] (steady state at
the first sample); the Dahl state advances by each sample's travel |v| dt. In a loop the
states have the runtime's exact updates (cpp/include/dampnet/damper_state.hpp: the control
held over a step, the velocity a ramp over a step, the Dahl state by the step's net travel),
used by dampnet.sim.quarter_car.reference_loop.NeuralLoopDamper; the two agree as the sample time
goes to 0 (tests/python/test_loop_derived_features.py).

`at_rest` is the value the feature takes when the damper is at rest, used for
the rest points (dampnet.training.rest_points): kinematic quantities are 0 at
rest, while control and state inputs can take any value at rest (None), so
rest points copy them from measured samples.

The derived features come from the runtime too: a runtime feature whose dn_damper_input
field is one of the damper's states (dampnet.h DN_DAMPER_STATE_LIST, read here from
`_core.DAMPER_STATES`: unit, dynamics, source field, parameter) gets its State from that
state's dynamics (`DYNAMICS`: lag_held -> Lag(held=True), lag_ramp -> Lag, dahl -> Dahl).
A Lag's base feature is the base feature reading the state's source field, and where
several do (the control u: voltage and current) the one whose name the derived feature's
starts with (voltage_lag -> voltage, current_lag -> current; `base_feature`). A lag takes
its unit and value at rest from its base feature (voltage_lag V, current_lag A: the
control's unit; velocity_lag m/s and 0 at rest), a Dahl state its unit from the state
(at rest: None). `_PYTHON_SIDE` holds only the base features (the channels).

Adding a stateful feature: four places, all lists in dn_xmacro.h, which dampnet.h includes (the recipe above DN_FEATURE_LIST:
its parameter, its dn_damper_input field, its DN_FEATURE_LIST line, its
DN_DAMPER_STATE_LIST row); nothing here. Training, export, the runtime's Damper, the
reference loop and the diagnosis then take it with no other edit. A new kind of dynamics
(a row of DN_STATE_DYNAMICS_LIST) needs its Python twin: a State class and its `DYNAMICS`
entry here. A new base feature (a new channel) needs its `_PYTHON_SIDE` line.
A Python-only feature (training, export, reference loop and diagnosis, but refused by
the runtime, which does not know its name) can be added at run time with
`register_feature`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from dampnet import _core
from dampnet.data import DataError, Dataset, DynoTest
from dampnet.data.preprocess import acceleration_of
from dampnet.schema import show


# -- derived states: the training formula and the loop's update, together ------------------

def first_order_lag(x, dt: float, tau: float) -> np.ndarray:
    """y[k] = a y[k-1] + (1 - a) x[k], a = exp(-dt/tau), y[0] = x[0], along the last axis
    (tau <= 0: a copy of x). The exact discretisation for an input held over each sample."""
    x = np.asarray(x, dtype=np.float64)
    if tau <= 0 or x.size == 0:
        return x.copy()
    a = float(np.exp(-dt / tau))
    from scipy.signal import lfilter  # here, not at import: `dampnet --help` stays free of scipy

    y, _ = lfilter([1.0 - a], [1.0, -a], x, axis=-1, zi=a * x[..., :1])
    return y


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


#: The loop's quantities at a step start, by dn_damper_input field: x [m], v [m/s],
#: u (control [V or A]) are what a derived state may follow (`LoopQuantities`).
LoopQuantities = Mapping[str, float]


@dataclass(frozen=True)
class Lag:
    """A first-order lag of the base feature `source`; its parameter is the time constant [s].

    held: the loop holds `source` over each step (the control), so the lag's update is
    exact for a step input (dynamics lag_held); otherwise `source` ramps between step starts
    (a motion quantity: lag_ramp; cpp/include/dampnet/damper_state.hpp).
    """
    source: str
    held: bool = False

    @property
    def channel(self) -> str:
        return self.source

    @property
    def loop_input(self) -> str:
        """The dn_damper_input field the loop follows."""
        return _core.FEATURE_INPUTS[self.source]

    def column(self, test: DynoTest, tau_s: float) -> np.ndarray:
        return first_order_lag(test.channels[self.source], test.dt, tau_s)

    def steady(self, q: LoopQuantities):
        """The state in steady state at the loop quantities q (before any step; scalars or arrays)."""
        return q[self.loop_input]

    def first(self, q: LoopQuantities) -> float:
        """The state at the loop's first step start (the runtime's reset)."""
        return float(q[self.loop_input])

    def step(self, y: float, q0: LoopQuantities, q1: LoopQuantities, dt: float, tau_s: float) -> float:
        """The state at the next step start, from y at the previous one (quantities q0 there, q1 now)."""
        u0, u1 = float(q0[self.loop_input]), float(q1[self.loop_input])
        if self.held:  # u0 held over the step: exact
            return u0 + (y - u0) * math.exp(-dt / tau_s)
        one_minus_a = -math.expm1(-dt / tau_s)  # a ramp from u0 to u1 over the step: exact
        return (1.0 - one_minus_a) * y + one_minus_a * u0 + (u1 - u0) * (1.0 - tau_s * one_minus_a / dt)

    def off(self, y: float, q0: LoopQuantities, q1: LoopQuantities) -> float:
        """The state at the next step start without its parameter (the runtime's default): its
        source over the step, the held value q0's (the control) or the ramp's end q1's."""
        return float((q0 if self.held else q1)[self.loop_input])


@dataclass(frozen=True)
class Dahl:
    """The Dahl friction state z in [-1, 1]; its parameter is the pre-sliding travel x_c [m].

    On the dyno it advances by each sample's travel |v| dt; in the loop by each step's
    net travel x1 - x0 (dynamics dahl, cpp/include/dampnet/damper_state.hpp). The loop starts
    it at 0 (the runtime's reset).
    """

    channel = "velocity"
    loop_input = "x"

    def column(self, test: DynoTest, presliding_m: float) -> np.ndarray:
        return dahl_state(test.channels["velocity"], test.dt, presliding_m)

    def steady(self, q: LoopQuantities):
        return np.sign(q["v"])

    def first(self, q: LoopQuantities) -> float:
        return 0.0

    def step(self, z: float, q0: LoopQuantities, q1: LoopQuantities, dt: float, presliding_m: float) -> float:
        dx = float(q1["x"]) - float(q0["x"])
        if dx == 0.0:
            return z
        sg = 1.0 if dx > 0 else -1.0
        return sg + (z - sg) * math.exp(-abs(dx) / presliding_m)

    def off(self, z: float, q0: LoopQuantities, q1: LoopQuantities) -> float:
        """The state at the next step start without its parameter (the runtime's default): it stays."""
        return z


State = Lag | Dahl

#: Python's twin of each kind of damper-state dynamics (dampnet.h DN_STATE_DYNAMICS_LIST,
#: `_core.STATE_DYNAMICS`): dynamics name -> (State class, Lag's `held`). A Lag follows a base
#: feature (`base_feature`); a Dahl state none.
DYNAMICS: dict[str, tuple[type, bool | None]] = {
    "lag_held": (Lag, True),
    "lag_ramp": (Lag, False),
    "dahl": (Dahl, None),
}


# -- the registry ------------------------------------------------------------------------

@dataclass(frozen=True)
class Feature:
    """One input feature. name, field and param come from the runtime's registry (dampnet.h)
    for the features it knows, and so do a derived feature's State, unit and at_rest (its
    damper state's, `derived_feature`); a base feature's unit, channel and at_rest are
    Python's (`_PYTHON_SIDE`)."""
    name: str
    unit: str  # SI unit of the feature
    source: str | State  # the test channel it is, or the derived state it is computed as
    at_rest: float | None  # value when the damper is at rest, None: any value
    field: str  # the dn_damper_input field the runtime keeps it in (Python-only: its name)
    param: str | None  # the feature_params key its state needs, None for a channel

    @property
    def channel(self) -> str:
        """The test channel it is computed from."""
        return self.source if isinstance(self.source, str) else self.source.channel

    @property
    def state(self) -> State | None:
        return None if isinstance(self.source, str) else self.source

    def column(self, test: DynoTest, feature_params: Mapping[str, float]) -> np.ndarray:
        """Its values [n_samples] on a test; KeyError naming the missing channel or
        DataError naming the missing parameter."""
        if isinstance(self.source, str):
            return np.asarray(test.channels[self.source], dtype=np.float64).ravel()
        if self.param is None or self.param not in feature_params:
            raise DataError(f"feature {self.name!r} needs feature_params[{self.param!r}] "
                            f"({param_doc(str(self.param))})")
        return np.asarray(self.source.column(test, float(feature_params[self.param])), dtype=np.float64).ravel()


#: What Python adds to each runtime base feature (a test channel): name -> (unit, test
#: channel, value at rest). The derived features come from the runtime's damper states
#: (`_core.DAMPER_STATES`, `derived_feature`): no line here.
_PYTHON_SIDE: dict[str, tuple[str, str, float | None]] = {
    "velocity": ("m/s", "velocity", 0.0),
    "acceleration": ("m/s^2", "acceleration", 0.0),
    "displacement": ("m", "displacement", None),
    "voltage": ("V", "voltage", None),
    "current": ("A", "current", None),
    "temperature": ("degC", "temperature", None),
}

#: Feature parameters the runtime does not know, registered with Python-only features: name -> doc.
_PYTHON_PARAMS: dict[str, str] = {}


def base_feature(name: str, source_field: str) -> str:
    """The base feature (a test channel, `_PYTHON_SIDE`) that derived feature `name` follows
    through its damper state's source field (x, v or u): the one base feature reading that
    field, and where several do (u: voltage and current) the one whose name `name` starts with
    (voltage_lag -> voltage, current_lag -> current). ValueError when none or several fit."""
    readers = [b for b in _PYTHON_SIDE if _core.FEATURE_INPUTS.get(b) == source_field]
    fit = readers if len(readers) == 1 else [b for b in readers if name.startswith(b)]
    if len(fit) != 1:
        raise ValueError(f"derived feature {name!r}: its state follows field {source_field!r}, read by the base "
                         f"feature(s) {readers or 'none'}; " + ("none" if not fit else "several") + " of them "
                         "starts its name (a derived feature of a field several base features read is named "
                         "after its base feature: <base>_...)")
    return fit[0]


def derived_feature(name: str) -> tuple[str, State, float | None]:
    """(unit, State, value at rest) of a runtime feature whose dn_damper_input field is a damper
    state (`_core.DAMPER_STATES`): the State of the state's dynamics (`DYNAMICS`) on its source;
    a lag's unit and value at rest its base feature's (`base_feature`: the control's unit
    follows voltage or current), a Dahl state's unit the state's and at rest None."""
    unit, dynamics, source, _param, _doc = _core.DAMPER_STATES[_core.FEATURE_INPUTS[name]]
    try:
        kind, held = DYNAMICS[dynamics]
    except KeyError:
        raise ValueError(f"derived feature {name!r}: dynamics {dynamics!r} (dampnet.h DN_STATE_DYNAMICS_LIST) "
                         "has no Python twin in dampnet.features.DYNAMICS") from None
    if kind is Lag:
        base = base_feature(name, source)
        base_unit, _channel, at_rest = _PYTHON_SIDE[base]
        return base_unit, Lag(base, held=bool(held)), at_rest
    state = kind()
    if state.loop_input != source:
        raise ValueError(f"derived feature {name!r}: its {dynamics} state follows {source!r}, Python's "
                         f"{kind.__name__} follows {state.loop_input!r}")
    return unit, state, None


def _runtime_feature(name: str) -> Feature:
    if _core.FEATURE_INPUTS[name] in _core.DAMPER_STATES:
        unit, source, at_rest = derived_feature(name)
    else:
        unit, source, at_rest = _PYTHON_SIDE[name]
    return Feature(name, unit, source, at_rest, _core.FEATURE_INPUTS[name], _core.FEATURE_PARAMS[name])


#: name -> Feature, in the runtime's order (DN_FEATURE_LIST), then Python-only ones (a runtime
#: base feature without its `_PYTHON_SIDE` line is left out: tests/python/test_feature_registry.py)
FEATURES: dict[str, Feature] = {name: _runtime_feature(name) for name in _core.FEATURE_NAMES
                                if name in _PYTHON_SIDE or _core.FEATURE_INPUTS[name] in _core.DAMPER_STATES}


def damper_states() -> dict[str, tuple[State, str]]:
    """The runtime's damper states (dampnet.h DN_DAMPER_STATE_LIST) in block order: field ->
    (its State, as the runtime features reading it have it; its feature parameter)."""
    out = {}
    for field, (_unit, _dyn, _source, param, _doc) in _core.DAMPER_STATES.items():
        state = next((f.state for f in FEATURES.values() if f.field == field and f.state is not None), None)
        if state is None:
            raise ValueError(f"damper state {field!r}: no runtime feature reads it (dampnet.h DN_FEATURE_LIST)")
        out[field] = (state, param)
    return out


def register_feature(name: str, unit: str, source: str | State, at_rest: float | None = None,
                     param: str | None = None, param_doc: str | None = None) -> Feature:
    """Add a feature only Python knows (training, export, the reference loop, diagnosis; the
    runtime refuses its name until dampnet.h lists it). A derived one names its parameter
    (`param`, with `param_doc`: meaning and unit) unless it reuses one the runtime knows.
    Returns the Feature; remove it with `unregister_feature`."""
    if name in _core.FEATURE_NAMES:
        raise ValueError(f"feature {name!r} is the runtime's (dampnet.h DN_FEATURE_LIST); "
                         "its Python side comes from the runtime's registry (features._PYTHON_SIDE for a "
                         "channel, _core.DAMPER_STATES for a derived one)")
    if isinstance(source, str) != (param is None):
        raise ValueError(f"feature {name!r}: a channel takes no parameter, a derived state needs one")
    if param is not None and param not in _core.FEATURE_PARAM_NAMES:
        _PYTHON_PARAMS[param] = param_doc or f"parameter of {name}"
    FEATURES[name] = Feature(name, unit, source, at_rest, name, param)
    return FEATURES[name]


def unregister_feature(name: str) -> None:
    """Remove a feature added by `register_feature` (and its own parameter)."""
    if name in _core.FEATURE_NAMES:
        raise ValueError(f"feature {name!r} is the runtime's; it cannot be removed")
    f = FEATURES.pop(name, None)
    if f is not None and f.param in _PYTHON_PARAMS and not any(g.param == f.param for g in FEATURES.values()):
        del _PYTHON_PARAMS[f.param]


def feature(name: str) -> Feature:
    try:
        return FEATURES[name]
    except KeyError:
        raise KeyError(f"unknown feature {name!r}; known: {', '.join(sorted(FEATURES))}") from None


def units_of(features: Sequence[str]) -> list[str]:
    return [feature(f).unit for f in features]


def feature_param_names() -> dict[str, str]:
    """Every feature parameter: name -> meaning with unit and range (the runtime's, then Python's)."""
    return {**_core.FEATURE_PARAM_NAMES, **_PYTHON_PARAMS}


def param_doc(param: str) -> str:
    return feature_param_names().get(param, "unknown parameter")


def param_of(name: str) -> str | None:
    """The feature_params key feature `name` needs, or None."""
    return feature(name).param


#: the runtime's dn_damper_input fields that hold the control: u as commanded, and every damper
#: state whose source is u (its lag; _core.DAMPER_STATES)
CONTROL_FIELDS = ("u", *(name for name, (_unit, _dyn, source, _param, _doc) in _core.DAMPER_STATES.items()
                         if source == "u"))


#: control_levels: a gap of this share of the control's range separates two levels, and a level
#: holds at least this share of the rows (values the control only passes through are not levels)
LEVEL_GAP_SHARE = 0.02
LEVEL_MIN_SHARE = 0.01


def control_levels(X: np.ndarray, columns: Sequence[int]) -> np.ndarray:
    """The control levels the rows of X were recorded at, [L, len(columns)], sorted: clusters of the
    first control column's values (split where consecutive values are more than LEVEL_GAP_SHARE of
    its range apart; at least LEVEL_MIN_SHARE of the rows each), each the mean of every control
    column over its rows. From the data, not the tests' nominal levels: a measured control carries
    the driver's offset, and a test may step among levels (the rig's valve_lag effect)."""
    if not columns or len(X) == 0:
        return np.zeros((0, len(columns)))
    v = X[:, columns[0]]
    order = np.argsort(v, kind="stable")
    sv = v[order]
    span = float(sv[-1] - sv[0])
    cuts = np.flatnonzero(np.diff(sv) > LEVEL_GAP_SHARE * span) + 1 if span > 0 else np.zeros(0, dtype=int)
    groups = [g for g in np.split(order, cuts) if len(g) >= LEVEL_MIN_SHARE * len(X)]
    return np.array([[X[g, j].mean() for j in columns] for g in groups]).reshape(len(groups), len(columns))


def control_columns(features: Sequence[str]) -> list[int]:
    """Indices of the features that carry the control (those kept in a CONTROL_FIELDS field, e.g.
    voltage and voltage_lag); in a constant-level test each is at the level's value."""
    return [j for j, f in enumerate(features) if f in FEATURES and FEATURES[f].field in CONTROL_FIELDS]


def control_input(features: Sequence[str]) -> int | None:
    """Index of the one feature the runtime reads from field u (the control as commanded: voltage
    or current), or None when none or several do: then the runtime has no control range and
    refuses the damper's inverse (DN_E_MISMATCH)."""
    reads = [j for j, f in enumerate(features) if f in FEATURES and FEATURES[f].field == "u"]
    return reads[0] if len(reads) == 1 else None


def velocity_column(features: Sequence[str]) -> int | None:
    """Index of the feature the runtime keeps in field v (the velocity), or None."""
    return next((j for j, f in enumerate(features) if f in FEATURES and FEATURES[f].field == "v"), None)


def lags_of(source: str) -> list[str]:
    """The features that are first-order lags of base feature `source` (e.g. velocity -> velocity_lag)."""
    return [f.name for f in FEATURES.values() if isinstance(f.state, Lag) and f.state.source == source]


def with_state(kind: type) -> list[str]:
    """The features whose state is of `kind` (e.g. Dahl -> friction_state), registry order."""
    return [f.name for f in FEATURES.values() if isinstance(f.state, kind)]


def check_runtime(names: Sequence[str], feature_params: Mapping[str, float] | None = None) -> None:
    """ValueError naming the first feature or feature parameter the runtime does not know (one
    registered only in Python, or unknown): the runtime reads its names from dampnet.h."""
    for name in names:
        if name not in _core.FEATURE_NAMES:
            where = "is registered only in Python (dampnet.features)" if name in FEATURES else "is unknown"
            raise ValueError(f"feature {name!r} {where}; the runtime knows {', '.join(_core.FEATURE_NAMES)} "
                             "(a runtime feature needs its dampnet.h DN_FEATURE_LIST line)")
    for key in feature_params or {}:
        if key not in _core.FEATURE_PARAM_NAMES:
            raise ValueError(f"feature_params[{key!r}]: not a runtime feature parameter; the runtime knows "
                             f"{', '.join(_core.FEATURE_PARAM_NAMES)}")


def steady_inputs(x, v, u) -> dict[str, Any]:
    """The runtime's derived dn_damper_input fields (its damper states, _core.DAMPER_STATES) in
    steady state at displacement x [m], velocity v [m/s] and control u (scalars or arrays): the
    keyword arguments of `_core.Damper.forces` for a damper held at (x, v, u), e.g. at rest."""
    q = {"x": x, "v": v, "u": u}
    return {field: state.steady(q) for field, (state, _param) in damper_states().items()}


def target_vector(tests: Sequence[Any], channel: str = "force") -> np.ndarray:
    """Concatenate one channel (default the force [N]) of every test."""
    out = []
    for i, test in enumerate(tests):
        try:
            out.append(np.asarray(test.channels[channel], dtype=np.float64).ravel())
        except KeyError:
            raise KeyError(f"test {i} ({getattr(test, 'test_id', '?')}) has no channel {channel!r}") from None
    return np.concatenate(out) if out else np.empty(0)


# -- the feature matrix ----------------------------------------------------------

def default_features(ds: Dataset) -> list[str]:
    """velocity, acceleration and the data's control channel (voltage or current)."""
    control = ds.tests[0].control_name if ds.tests else "voltage"
    return ["velocity", "acceleration", control]


def feature_matrix(tests: Sequence[DynoTest], features: Sequence[str],
                   feature_params: Mapping[str, float] | None = None,
                   acceleration_window: float | int | None = None) -> np.ndarray:
    """X [samples, len(features)] of `tests`, via the feature registry.

    Derives acceleration (on a copy of the test's channels) if a test lacks it.
    Raises DataError naming the feature, the test and the channels it has when a
    test cannot provide a feature (e.g. a model trained with temperature, data without),
    or naming the parameter a derived feature lacks.
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
                cols.append(FEATURES[f].column(t, params))
            except KeyError as e:
                have = ", ".join(sorted(t.channels))
                raise DataError(f"test {t.test_id}: feature {f!r} needs channel {e.args[0]!r}, which "
                                f"the data do not have (channels: {have})") from None
        if len({len(c) for c in cols}) > 1 or (cols and len(cols[0]) != len(t)):
            raise DataError(f"test {t.test_id}: features {list(features)} have lengths "
                            f"{[len(c) for c in cols]}, expected {len(t)}")
        blocks.append(np.stack(cols, axis=1) if cols else np.empty((len(t), 0)))
    return np.concatenate(blocks) if blocks else np.empty((0, len(features)))


def missing_channel(feature: str, test: DynoTest) -> str | None:
    """The channel `test` lacks to give `feature` (a name of FEATURES), or None: the acceleration is
    derived from a velocity or a displacement when the test has no acceleration channel."""
    if feature == "acceleration" and ("velocity" in test.channels or "displacement" in test.channels):
        return None
    channel = FEATURES[feature].channel
    return None if channel in test.channels else channel


def check_features(model: Any, ds: Dataset) -> None:
    """Raise DataError if a test of `ds` cannot provide one of the model's features."""
    for f in model.features:
        if f not in FEATURES:
            raise DataError(f"the model needs feature {show(f)}, which this dampnet does not know")
    for t in ds.tests:
        for f in model.features:
            channel = missing_channel(f, t)
            if channel is not None:
                raise DataError(f"test {t.test_id}: the model was trained on features "
                                f"{show(', '.join(model.features))}, but the data have no {channel!r} channel "
                                f"(channels: {', '.join(sorted(t.channels))})")
