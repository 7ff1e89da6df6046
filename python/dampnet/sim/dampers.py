"""Damper specs: a damper model named for a run, and its form in the runtime's loop.

A *damper spec* (`DamperSpec`) names a damper model and how to build it:
'truth' (the rig's physical damper, `dampnet.rig.truth`), 'neural' / 'hybrid' (an
`MlpModel`; hybrid when it has physics terms), 'lookup' (a `LookupTable`), 'linear'
(a coefficient [N s/m]). `load_spec` reads one from a command line's MODEL string.

Every spec runs in the runtime's loop (`runtime_damper`): the rig's truth damper exists
only in Python and enters the loop as a callback damper, stepped once per loop step as
its `step(dt, ...)` requires (so its runs use one damper evaluation per step).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dampnet import _core
from dampnet.features import control_input, steady_inputs
from dampnet.rig.truth import TruthDamper
from dampnet.sim.quarter_car.loop import damper_from_model, truth_damper
from dampnet.sim.vehicle import LoopError, Vehicle

SPEC_KINDS = ("truth", "neural", "hybrid", "lookup", "linear")
# Steps of constant input before a truth damper's force is read: past its 2 ms
# compressibility lag at the loop's 1 ms step.
STEADY_STEPS = 50
TEMPERATURE_C = _core.VEHICLE_FIELDS["temperature"][0]   # what a neural damper sees in the loop


@dataclass
class DamperSpec:
    """A damper model for the loop: kind in SPEC_KINDS; obj the model (the truth's effect
    names, an MlpModel, a LookupTable, or the linear coefficient [N s/m]); u_range the
    control range [V]."""

    name: str
    kind: str
    obj: Any = None
    u_range: tuple = (0.0, 5.0)
    meta: dict = field(default_factory=dict)


def neural_spec(model, name: str = "neural", envelope=None, envelope_note: str | None = None) -> DamperSpec:
    """A neural (hybrid with terms) spec of an MlpModel; `envelope` its training envelope
    (dampnet.envelope; None: coverage reports per-input ranges only, `envelope_note` says why)."""
    i = control_input(model.features)
    u_range = (0.0, 5.0) if i is None else (float(model.sat_lo[i]), float(model.sat_hi[i]))
    kind = "hybrid" if model.terms else "neural"
    return DamperSpec(name, kind, model, u_range, meta=dict(model_id=model.model_id(), envelope=envelope,
                                                            envelope_note=envelope_note))


def lookup_spec(table, name: str = "lookup") -> DamperSpec:
    return DamperSpec(name, "lookup", table, (float(table.voltages[0]), float(table.voltages[-1])))


def truth_spec(effects=(), name: str = "truth") -> DamperSpec:
    return DamperSpec(name, "truth", list(effects), (0.0, 5.0), meta=dict(effects=list(effects)))


def linear_spec(c: float, name: str = "linear") -> DamperSpec:
    """A linear damper F = c v; c [N s/m] finite and >= 0 (LoopError otherwise: negative damping
    feeds energy into the car, a runaway)."""
    v = float(c)
    if not (math.isfinite(v) and v >= 0):
        raise LoopError(f"linear damper: expected a damping coefficient c, a finite number >= 0 [N s/m], got {c!r}")
    return DamperSpec(name, "linear", v)


def _damping_coefficient(text: str) -> float:
    """C of a MODEL string 'linear:C'; LoopError naming the field and what it expects."""
    field = text.split(":", 1)[1]
    try:
        c = float(field)
    except ValueError:
        c = math.nan
    if not (math.isfinite(c) and c >= 0):
        raise LoopError(f"{text!r}: expected linear:C with C the damping coefficient, a finite number "
                        f">= 0 [N s/m], got {field!r}")
    return c


#: the MODEL word for the embedded default model (every front end: the CLI, the sweep's specs)
DEFAULT_MODEL = "default"


def load_spec(text: str) -> DamperSpec:
    """A DamperSpec from a command line's MODEL: a model directory or model.json, 'default' (the
    embedded default model, dampnet.modeldir.default_model_path, as a sweep spec's "default"; a
    directory named so is ./default), a lookup-table JSON, 'truth' or 'truth:EFFECT,...', or
    'linear:C' [N s/m]; LoopError or ModelError (one line, naming the field) otherwise."""
    if not isinstance(text, str) or not text.isprintable():   # a control character: no path, no field
        raise LoopError(f"MODEL {text!r}: expected a model directory or file, 'default', 'truth[:EFFECT,...]' or "
                        "'linear:C' [N s/m]")
    if text == DEFAULT_MODEL:
        from dampnet.paths import default_model_path

        text = str(default_model_path())
    if text == "truth" or text.startswith("truth:"):
        eff = [e for e in text.split(":", 1)[1].split(",") if e] if ":" in text else []
        from dampnet.rig.effects import get_effect

        try:
            for e in eff:
                get_effect(e)
        except ValueError as e:
            raise LoopError(f"{text!r}: the truth's effects: {e}") from None
        twice = sorted({e for e in eff if eff.count(e) > 1})
        if twice:
            raise LoopError(f"{text!r}: the truth's effects: {', '.join(twice)} given more than once")
        return truth_spec(eff)
    if text.startswith("linear:"):
        return linear_spec(_damping_coefficient(text))
    from dampnet import schema
    from dampnet.model import MlpModel, ModelError

    path = os.path.join(text, "model.json") if os.path.isdir(text) else text
    if not os.path.exists(path):
        raise ModelError(f"{path}: no such model file")
    d = schema.load_json(path, ModelError)
    if isinstance(d, dict) and "velocities" in d and "forces" in d:
        from dampnet.evaluation.lookup import LookupTable

        try:
            return lookup_spec(LookupTable.from_dict(d))
        except (KeyError, TypeError, ValueError) as e:
            raise ModelError(f"{path}: not a valid lookup table ({schema.show(str(e))})") from None
    from dampnet.envelope import load_envelope

    model = MlpModel.from_dict(d, path)
    env, note = load_envelope(path, model)
    return neural_spec(model, envelope=env, envelope_note=note)


@dataclass
class RuntimeDamper:
    """A spec's damper in the runtime: `damper` for the loop; `truth` the Python state
    behind a truth callback (None for the others), reset by `reset()` before each run."""

    damper: _core.Damper
    truth: TruthDamper | None = None

    def reset(self) -> None:
        if self.truth is not None:
            self.truth.reset()


def _truth(spec: DamperSpec) -> TruthDamper:
    return TruthDamper(None, spec.obj or ())


def runtime_damper(spec: DamperSpec) -> RuntimeDamper:
    """The runtime's damper (dampnet._core.Damper) for a spec. The truth runs at its own
    reference temperature (TruthParams.temperature_ref_c), not the loop's."""
    if spec.kind == "linear":
        return RuntimeDamper(_core.Damper.linear(float(spec.obj)))
    if spec.kind == "lookup":
        t = spec.obj
        return RuntimeDamper(_core.Damper.table(t.velocities, t.voltages, np.ascontiguousarray(t.forces)))
    if spec.kind in ("neural", "hybrid"):
        return RuntimeDamper(damper_from_model(spec.obj))
    if spec.kind == "truth":
        truth = _truth(spec)
        return RuntimeDamper(truth_damper(truth, loop_temperature=False), truth)
    raise LoopError(f"unknown damper kind {spec.kind!r}; known: {', '.join(SPEC_KINDS)}")


def steady_forces(spec: DamperSpec, v, u: float, dt: float = 1e-3, x: float = 0.0) -> np.ndarray:
    """The damper's steady force [N] at each constant velocity v [m/s] and control u, at
    displacement x [m] and a = 0: the truth after STEADY_STEPS steps of dt [s] (past its lag),
    a model at its derived features' steady state (dampnet.features.steady_inputs: a lag equals
    its input, the friction state is sign(v))."""
    v = np.atleast_1d(np.asarray(v, dtype=np.float64))
    if spec.kind == "truth":
        d = _truth(spec)
        out = np.empty_like(v)
        for i, vi in enumerate(v):
            d.reset()
            for _ in range(STEADY_STEPS):
                out[i] = d.step(dt, x, float(vi), float(u))
        return out
    n = v.size
    full = lambda value: np.full(n, float(value))  # noqa: E731
    f, _, _ = runtime_damper(spec).damper.forces(x=full(x), v=v, a=full(0.0), u=full(u),
                                                 temperature=full(TEMPERATURE_C),
                                                 **steady_inputs(full(x), v, full(u)))
    return np.asarray(f, dtype=np.float64)


def steady_force(spec: DamperSpec, v: float, u: float, dt: float = 1e-3) -> float:
    """The damper's steady force [N] at one velocity v [m/s] and control u (steady_forces)."""
    return float(steady_forces(spec, [v], u, dt)[0])


def force_at_rest(spec: DamperSpec, u: float, vehicle: Vehicle) -> float:
    """The damper's force [N] at rest (x = x_static, v = 0) with control u: the f_static of a
    Vehicle whose f_static is None (as the loop starts, one step of the truth's lag)."""
    if spec.kind == "truth":
        return float(_truth(spec).step(vehicle.dt, vehicle.x_static, 0.0, float(u)))
    return float(steady_forces(spec, [0.0], u, vehicle.dt, vehicle.x_static)[0])
