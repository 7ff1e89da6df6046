"""The MLP damper model as data: weights, scaling, limits, features, provenance.

A `MlpModel` is what training produces, what `model.json` stores, what the
header writer (`dampnet.export`) turns into C, and what the C++ kernel runs.
Layouts follow PyTorch: a weight matrix is [out][in]. Scaling is MATLAB's
mapminmax to [-1, 1]; saturation limits are the training range, in the
feature's own unit (see `cpp/include/dampnet/dampnet.h`).
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dampnet import _core, schema
from dampnet import terms as term_kinds
from dampnet.features import feature_param_names
from dampnet.outputs import atomic_write_text

FORMAT_NAME = "dampnet-model"
FORMAT_VERSION = 1
#: the hidden layers' activations: the runtime's (dampnet._core.ACTIVATIONS)
ACTIVATIONS = tuple(_core.ACTIVATIONS)
_REQUIRED_FIELDS = ("w1", "b1", "w_out", "b_out", "in_offset", "in_gain", "out_offset", "out_gain",
                    "sat_lo", "sat_hi", "features", "units", "activation")


class ModelError(ValueError):
    """A model file or a model's contents are not what dampnet expects."""


def mapminmax_settings(x: np.ndarray, ymin: float = -1.0, ymax: float = 1.0):
    """MATLAB mapminmax settings (xoffset, gain) of each column of `x` [n, k].

    A constant column gets gain 1 (as MATLAB does) so it maps to ymin + (x - xmin).
    """
    x = np.asarray(x, dtype=np.float64)
    if x.ndim == 1:
        x = x[:, None]
    xmin = x.min(axis=0)
    xmax = x.max(axis=0)
    span = xmax - xmin
    gain = np.where(span > 0, (ymax - ymin) / np.where(span > 0, span, 1.0), 1.0)
    return xmin, gain


@dataclass
class MlpModel:
    """An MLP with 1-8 inputs, one or two hidden layers, and a linear output.

    Attributes are numpy float64 arrays; `features` names the inputs in order
    and `units` gives their SI units. `meta` carries provenance (algorithm,
    settings, data, training time); `terms` carries physics terms added to
    the network output (hybrid models), as plain dictionaries
    `{"kind": str, "params": [float, ...]}` (kinds and parameter meanings:
    `dampnet.terms`). `feature_params` holds the constants derived features
    need, by name (dampnet.features.feature_param_names(): e.g. the lagged control's time
    constant [s]).
    """

    w1: np.ndarray  # [h1, n_in]
    b1: np.ndarray  # [h1]
    w_out: np.ndarray  # [n_last]
    b_out: float
    in_offset: np.ndarray  # [n_in] mapminmax xoffset, feature units
    in_gain: np.ndarray  # [n_in] mapminmax gain, 1/feature unit
    out_offset: float  # [N]
    out_gain: float  # [1/N]
    sat_lo: np.ndarray  # [n_in] feature units
    sat_hi: np.ndarray  # [n_in] feature units
    features: list[str]
    units: list[str]
    activation: str  # one of ACTIVATIONS
    w2: np.ndarray | None = None  # [h2, h1]
    b2: np.ndarray | None = None  # [h2]
    in_ymin: float = -1.0
    out_ymin: float = -1.0
    output: str = "force"
    output_unit: str = "N"
    terms: list[dict[str, Any]] = field(default_factory=list)
    feature_params: dict[str, float] = field(default_factory=dict)
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in ("w1", "b1", "w_out", "in_offset", "in_gain", "sat_lo", "sat_hi"):
            setattr(self, name, np.asarray(getattr(self, name), dtype=np.float64))
        if self.w2 is not None:
            self.w2 = np.asarray(self.w2, dtype=np.float64)
            self.b2 = np.asarray(self.b2, dtype=np.float64)
        self.b_out = float(self.b_out)
        self.out_offset = float(self.out_offset)
        self.out_gain = float(self.out_gain)
        self.features = list(self.features)
        self.units = list(self.units)
        self.validate()

    # -- shape -----------------------------------------------------------
    @property
    def n_inputs(self) -> int:
        return int(self.w1.shape[1])

    @property
    def hidden(self) -> tuple[int, ...]:
        h = (int(self.w1.shape[0]),)
        return h + ((int(self.w2.shape[0]),) if self.w2 is not None else ())

    def validate(self) -> None:
        """Raise ModelError naming the first field that is inconsistent."""
        if self.w1.ndim != 2:
            raise ModelError(f"w1: expected a 2-D [hidden, inputs] matrix, got shape {self.w1.shape}")
        h1, n_in = self.w1.shape
        if not 1 <= n_in <= 8:
            raise ModelError(f"w1: 1..8 inputs supported, got {n_in}")
        # the runtime's limits (dn_config.h): layer 1 DN_MAX_HIDDEN, 384 in the Python module's
        # build so that an averaged network fits; layer 2 DN_MAX_HIDDEN2 (64)
        from dampnet import _core

        cap1, cap2 = int(_core.MAX_HIDDEN), int(_core.MAX_HIDDEN2)
        if not 1 <= h1 <= cap1:
            raise ModelError(f"w1: 1..{cap1} neurons in hidden layer 1 supported (the runtime's DN_MAX_HIDDEN), "
                             f"got {h1}")
        if self.activation not in ACTIVATIONS:
            raise ModelError(f"activation: expected one of {', '.join(ACTIVATIONS)}, got {schema.show(self.activation)}")
        n_last = h1
        if self.w2 is not None:
            if self.w2.ndim != 2 or self.w2.shape[1] != h1 or not 1 <= self.w2.shape[0] <= cap2:
                raise ModelError(f"w2: expected [1..{cap2}, {h1}] (hidden layer 2: the runtime's DN_MAX_HIDDEN2), "
                                 f"got {self.w2.shape}")
            if h1 > cap2:
                raise ModelError(f"w1: {h1} neurons in hidden layer 1 of a two-layer network; the runtime holds "
                                 f"{cap2} (DN_MAX_HIDDEN2: only a one-layer network's layer may be wider)")
            n_last = self.w2.shape[0]
            if self.b2 is None or self.b2.shape != (n_last,):
                raise ModelError(f"b2: expected {n_last} values")
        expect = {"b1": h1, "w_out": n_last, "in_offset": n_in, "in_gain": n_in,
                  "sat_lo": n_in, "sat_hi": n_in}
        for name, n in expect.items():
            a = getattr(self, name)
            if a.shape != (n,):
                raise ModelError(f"{name}: expected {n} values, got shape {a.shape}")
        if len(self.features) != n_in or len(self.units) != n_in:
            raise ModelError(f"features/units: expected {n_in} names, got {len(self.features)} / "
                             f"{len(self.units)}: {schema.show(', '.join(map(str, self.features)))}")
        arrays = [self.w1, self.b1, self.w_out, self.in_offset, self.in_gain, self.sat_lo, self.sat_hi]
        if self.w2 is not None:
            arrays += [self.w2, self.b2]
        scalars = [self.b_out, self.out_offset, self.out_gain, self.in_ymin, self.out_ymin]
        if not all(np.all(np.isfinite(a)) for a in arrays) or not np.all(np.isfinite(scalars)):
            raise ModelError("model parameters must all be finite (found NaN or Inf)")
        if self.out_gain == 0:
            raise ModelError("out_gain: must be non-zero")
        if np.any(self.sat_lo > self.sat_hi):
            bad = [self.features[i] for i in np.nonzero(self.sat_lo > self.sat_hi)[0]]
            raise ModelError(f"sat_lo > sat_hi for {schema.show(', '.join(map(str, bad)))}")
        self._validate_feature_params()

    def _validate_feature_params(self) -> None:
        """feature_params: finite numbers; the registry's parameters (time constants [s], travels
        [m]: the runtime refuses <= 0) positive. The one place this is checked, so every command
        (evaluate, simulate, study, export) refuses the same. Unknown names load (a model from
        a newer dampnet can be inspected); the runtime refuses them."""
        if not isinstance(self.feature_params, dict):
            raise ModelError(f"feature_params: expected an object of numbers, got {schema.show(self.feature_params)}")
        known = feature_param_names()
        for key, value in self.feature_params.items():
            v = schema.expect_number(value, f"feature_params[{schema.show(key)}]", ModelError)
            if key in known and not v > 0:
                raise ModelError(f"feature_params[{schema.show(key)}]: expected a positive value "
                                 f"({known[key]}), got {schema.show(v)}")

    # -- evaluation --------------------------------------------------------
    def core(self):
        """The C++ kernel's model (dampnet._core.Mlp) built from these weights."""
        from dampnet import _core

        return _core.Mlp(self.w1, self.b1, self.w2, self.b2, self.w_out, np.array([self.b_out]),
                         self.in_offset, self.in_gain, self.in_ymin, self.out_offset,
                         self.out_gain, self.out_ymin, self.sat_lo, self.sat_hi, self.activation)

    def predict(self, x: np.ndarray, single: bool = False) -> np.ndarray:
        """Force [N] for samples x [n, n_inputs] (feature units), in the C++ kernel."""
        x = np.ascontiguousarray(np.atleast_2d(np.asarray(x, dtype=np.float64)))
        if x.shape[1] != self.n_inputs:
            raise ModelError(f"x: expected {self.n_inputs} columns ({', '.join(self.features)}), "
                             f"got {x.shape[1]}")
        y, _status, _mask = self.core().predict(x, single)
        return y

    # -- identity and files --------------------------------------------------
    def model_id(self) -> str:
        """A short hash of everything that changes the model's output."""
        payload = json.dumps(self._numbers(), sort_keys=True).encode()
        return hashlib.sha256(payload).hexdigest()[:16]

    def _numbers(self) -> dict[str, Any]:
        d = {
            "activation": self.activation,
            "features": self.features,
            "units": self.units,
            "w1": self.w1.tolist(), "b1": self.b1.tolist(),
            "w2": None if self.w2 is None else self.w2.tolist(),
            "b2": None if self.b2 is None else self.b2.tolist(),
            "w_out": self.w_out.tolist(), "b_out": self.b_out,
            "in_offset": self.in_offset.tolist(), "in_gain": self.in_gain.tolist(),
            "in_ymin": self.in_ymin, "out_offset": self.out_offset,
            "out_gain": self.out_gain, "out_ymin": self.out_ymin,
            "sat_lo": self.sat_lo.tolist(), "sat_hi": self.sat_hi.tolist(),
            "terms": self.terms,
            "feature_params": self.feature_params,
        }
        return d

    def to_dict(self) -> dict[str, Any]:
        d = {"format": FORMAT_NAME, "format_version": FORMAT_VERSION, "id": self.model_id(),
             "output": {"name": self.output, "unit": self.output_unit}}
        d.update(self._numbers())
        d["meta"] = self.meta
        return d

    @classmethod
    def from_dict(cls, d: Any, source: str = "model") -> MlpModel:
        """A model from the parsed JSON of model.json; ModelError naming `source` and the field."""
        E = ModelError
        d = schema.expect_object(d, source, E)
        if d.get("format") != FORMAT_NAME:
            raise E(f"{source}: not a dampnet model (format field is {schema.show(d.get('format'))})")
        if d.get("format_version") != FORMAT_VERSION:
            raise E(f"{source}: format_version {schema.show(d.get('format_version'))} is not supported "
                    f"(this dampnet reads {FORMAT_VERSION})")
        missing = [k for k in _REQUIRED_FIELDS if k not in d]
        if missing:
            raise E(f"{source}: missing field {missing[0]!r}")

        def at(key: str) -> str:
            return f"{source}: field {key!r}"

        def arr(key: str, ndim: int = 1):
            return schema.expect_array(d.get(key), ndim, at(key), E)

        def num(key: str, default: float | None = None) -> float:
            return schema.expect_number(d.get(key, default), at(key), E)

        two_layers = d.get("w2") is not None or d.get("b2") is not None
        out = schema.expect_object(d.get("output", {}), at("output"), E)
        terms = d.get("terms", [])
        if not isinstance(terms, list):
            raise E(f"{at('terms')}: expected a list of objects {{\"kind\": ..., \"params\": [...]}}, "
                    f"got {schema.show(terms)}")
        for i, t in enumerate(terms):
            t = schema.expect_object(t, f"{at('terms')}[{i}]", E)
            # the shape only: which kinds exist is checked where terms are used (dampnet.terms,
            # the runtime), so a model from a newer dampnet still loads for inspection
            kind = schema.expect_string(t.get("kind"), f"{at('terms')}[{i}].kind", E)
            if not 0 < len(kind) <= 100:
                raise E(f"{at('terms')}[{i}].kind: expected a term kind name (1-100 characters, e.g. "
                        f"{', '.join(sorted(term_kinds.KINDS))}), got {schema.show(kind)}")
            schema.expect_array(t.get("params", []), 1, f"{at('terms')}[{i}].params", E)
        try:
            model = cls(w1=arr("w1", 2), b1=arr("b1"), w_out=arr("w_out"), b_out=num("b_out"),
                       in_offset=arr("in_offset"), in_gain=arr("in_gain"), out_offset=num("out_offset"),
                       out_gain=num("out_gain"), sat_lo=arr("sat_lo"), sat_hi=arr("sat_hi"),
                       features=schema.expect_strings(d["features"], at("features"), E),
                       units=schema.expect_strings(d["units"], at("units"), E),
                       activation=schema.expect_string(d["activation"], at("activation"), E),
                       w2=arr("w2", 2) if two_layers else None, b2=arr("b2") if two_layers else None,
                       in_ymin=num("in_ymin", -1.0), out_ymin=num("out_ymin", -1.0),
                       output=schema.expect_string(out.get("name", "force"), at("output.name"), E),
                       output_unit=schema.expect_string(out.get("unit", "N"), at("output.unit"), E),
                       terms=terms,
                       feature_params=schema.expect_number_map(d.get("feature_params", {}),
                                                               at("feature_params"), E),
                       meta=_check_meta(d.get("meta", {}), at("meta")))
        except ModelError as e:
            msg = str(e)
            raise ModelError(msg if msg.startswith(source) else f"{source}: {msg}") from None
        return check_runtime_accepts(model, source)  # the runtime's own loader, the field named

    def save(self, path: str | os.PathLike, overwrite: bool = False) -> Path:
        """Write model.json atomically; refuses to replace a file unless overwrite."""
        return atomic_write_text(path, json.dumps(self.to_dict(), indent=1), overwrite)

    @classmethod
    def load(cls, path: str | os.PathLike) -> MlpModel:
        p = Path(path)
        if p.is_dir():
            p = p / "model.json"
        if not p.exists():
            raise ModelError(f"{p}: no such model file")
        return cls.from_dict(schema.load_json(p, ModelError), str(p))


def _check_meta(meta: Any, where: str) -> dict:
    """model.json's `meta`: an object; the fields commands read (data.holdout_tests,
    data.acceleration_window_s) of the right kind."""
    meta = schema.expect_object(meta, where, ModelError)
    if "data" in meta:
        data = schema.expect_object(meta["data"], f"{where}.data", ModelError)
        if "holdout_tests" in data:
            schema.expect_strings(data["holdout_tests"], f"{where}.data.holdout_tests", ModelError)
        if data.get("acceleration_window_s") is not None:
            w = schema.expect_number(data["acceleration_window_s"], f"{where}.data.acceleration_window_s",
                                     ModelError)
            if not w > 0:
                raise ModelError(f"{where}.data.acceleration_window_s: expected a positive window [s], "
                                 f"got {schema.show(w)}")
    return meta


# -- what the runtime's loader does with a model: its folding, and why it refuses one --------

def _folded_double(model: MlpModel) -> dict:
    """The runtime load()'s folded parameters in double, before its one rounding to float32
    (cpp/include/dampnet/mlp.hpp: the same double operations in the same order)."""
    w1 = np.asarray(model.w1, np.float64)
    h1, ni = w1.shape
    w2 = None if model.w2 is None else np.asarray(model.w2, np.float64)
    h2 = 0 if w2 is None else w2.shape[0]
    wo = np.asarray(model.w_out, np.float64).ravel()
    off = [float(v) for v in model.in_offset]
    gain = [float(v) for v in model.in_gain]
    lo = [float(v) for v in model.sat_lo]
    hi = [float(v) for v in model.sat_hi]
    ymin, og, oy = float(model.in_ymin), float(model.out_gain), float(model.out_ymin)
    sig = model.activation == "sigmoid"
    zs, alpha, beta = (0.5, 0.5, 0.5) if sig else (1.0, 1.0, 0.0)
    # Python floats are IEEE doubles and `a * b + c` is never fused: load()'s arithmetic
    fold_off = all(abs(off[i]) <= hi[i] - lo[i] for i in range(ni))
    f1, fb1 = np.zeros((h1, ni)), np.zeros(h1)
    for j in range(h1):
        b = float(model.b1[j])
        for i in range(ni):
            w = float(w1[j, i]) * gain[i]
            f1[j, i] = zs * w
            b += ymin * float(w1[j, i])
            if fold_off:
                b -= w * off[i]
        fb1[j] = zs * b
    f2 = fb2 = None
    if h2:
        f2, fb2 = np.zeros((h2, h1)), np.zeros(h2)
        for k in range(h2):
            b = float(model.b2[k])
            for j in range(h1):
                f2[k, j] = zs * alpha * float(w2[k, j])
                b += beta * float(w2[k, j])
            fb2[k] = zs * b
    c = float(model.b_out)
    fo = np.zeros(wo.size)
    for j in range(wo.size):
        fo[j] = alpha * float(wo[j]) / og
        c += beta * float(wo[j])
    return {"n_inputs": ni, "n_hidden1": h1, "n_hidden2": h2, "offsets_folded": int(fold_off),
            "w1": f1, "b1": fb1, "w2": f2, "b2": fb2, "w_out": fo, "b_out": (c - oy) / og + float(model.out_offset),
            "out_offset": float(model.out_offset), "in_offset": np.array(off), "sat_lo": np.array(lo),
            "sat_hi": np.array(hi), "sat_mid": np.array([0.5 * (a + b) for a, b in zip(lo, hi)])}


_SIZES = ("n_inputs", "n_hidden1", "n_hidden2", "offsets_folded")


def folded_float(model: MlpModel) -> dict | None:
    """The model as a dn_mlp_folded_f (dampnet.h): the scalings folded into the weights exactly
    as the runtime's load() folds them (_folded_double, then one rounding to float32), so that
    dn_mlp_init_folded on these values holds what dn_mlp_init on the double description holds,
    bit for bit (tests/cpp and tests/python/test_embedded.py compare). None when a folded value
    overflows float (the runtime refuses such a model: DN_E_PARAM; runtime_refusal says which).
    Arrays in the description's [out][in] layout."""
    with np.errstate(over="ignore"):
        out = {k: v if k in _SIZES or v is None else
               (np.float32(v) if np.ndim(v) == 0 else np.asarray(v).astype(np.float32))
               for k, v in _folded_double(model).items()}
    finite = all(np.all(np.isfinite(v)) for k, v in out.items() if k not in _SIZES and v is not None)
    return out if finite else None


#: each folded parameter (the plain copies first): the model file's field it is blamed on, and
#: what it is made of (runtime_refusal blames w1 or w_out/b_out instead where they are the large factor)
_FOLDED_FROM = {
    "out_offset": ("out_offset", "out_offset"), "in_offset": ("in_offset", "in_offset"),
    "sat_lo": ("sat_lo", "sat_lo"), "sat_hi": ("sat_hi", "sat_hi"),
    "sat_mid": ("sat_lo", "(sat_lo + sat_hi) / 2: the middle of the saturation range"),
    "w1": ("in_gain", "w1 x in_gain: the first layer's weights on the raw inputs"),
    "b1": ("b1", "b1 + in_ymin w1 - in_offset in_gain w1: the first layer's bias"),
    "w2": ("w2", "w2"), "b2": ("b2", "b2 + w2 / 2"),
    "w_out": ("out_gain", "w_out / out_gain: the output weights in newtons"),
    "b_out": ("out_gain", "(b_out - out_ymin) / out_gain + out_offset: the output bias in newtons"),
}
_FLOAT_MAX = float(np.finfo(np.float32).max)
_PER_INPUT = ("w1", "in_offset", "sat_lo", "sat_hi", "sat_mid")


def runtime_refusal(model: MlpModel) -> str | None:
    """Why the runtime's loader (dn_mlp_create; in Python dampnet._core.Mlp) refuses `model`,
    naming the model file's field (and the input), or None if it accepts it. The runtime says
    only DN_E_PARAM: a folded parameter (weights and scalings multiplied together, rounded to
    float once) beyond float's range; this finds which, from the same folding in double."""
    try:
        model.core()
        return None
    except ValueError as e:
        status = str(e)
    folded = _folded_double(model)
    for key, (name, made_of) in _FOLDED_FROM.items():
        if folded.get(key) is None:
            continue
        a = np.atleast_1d(np.asarray(folded[key], dtype=np.float64))
        big = ~(np.abs(a) <= _FLOAT_MAX)
        if not big.any():
            continue
        at = np.unravel_index(int(np.argmax(big)), a.shape)
        where = ""
        if key in _PER_INPUT:
            i = int(at[-1])
            if key == "w1" and not abs(model.in_gain[i]) >= np.max(np.abs(model.w1[:, i])):
                name = "w1"
            where = f" (input {model.features[i]})"
        elif key in ("w_out", "b_out") and abs(model.out_gain) >= 1:
            name = key  # a gain of 1 or more only shrinks: the weight or bias itself is the large factor
        return (f"field {name!r}{where}: the runtime folds it into {made_of} = {a[at]:.4g}, beyond float's range "
                f"(3.4e38), and refuses the model ({status})")
    # every folded value fits float: the vector kernels' coefficients (activation.hpp's tanh
    # polynomial, up to ~56 x each output weight) are what overflow
    w = float(np.max(np.abs(folded["w_out"])))
    name = "out_gain" if abs(model.out_gain) < 1 else "w_out"
    return (f"field {name!r}: the runtime folds it into w_out / out_gain (the output weights in newtons), up to "
            f"{w:.4g}, and its vector kernel's coefficients (a multiple of them) exceed float's range (3.4e38): "
            f"it refuses the model ({status})")


def check_runtime_accepts(model: MlpModel, source: str = "model") -> MlpModel:
    """`model` if the runtime's loader accepts it; ModelError naming `source` and the field
    (runtime_refusal) otherwise. Every model file read goes through this (MlpModel.from_dict), so
    an export, a simulation or a vehicle run refuses it at once with the file named, instead of an
    ONNX graph giving NaN, an FMU failing at instantiation or "Mlp: DN_E_PARAM" mid-run."""
    why = runtime_refusal(model)
    if why is not None:
        raise ModelError(f"{source}: {why}")
    return model
