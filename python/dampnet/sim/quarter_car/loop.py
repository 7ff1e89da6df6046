"""The quarter-car loop from Python: a thin layer over `dampnet._core`.

The loop itself (equations, signs, integrators, the acceleration feature,
controller laws, status codes) is documented in docs/simulation.md ("The quarter-car
loop") and in `cpp/include/dampnet/dampnet.h`; everything runs in C++.

    car = QuarterCar(damper_from_model(model), controller={"kind": "skyhook_onoff"})
    out = car.simulate(road)           # numpy arrays, GIL released

Dampers: `_core.Damper.linear(c)`, `.parametric(...)`, `.table(v, u, F)`,
`damper_from_model(MlpModel)` (neural, plus the model's physics terms: the
hybrid), and `truth_damper(TruthDamper)` (the rig's truth model as a Python
callback: the slow path, for studies; it holds the GIL per call and runs with
one damper evaluation per step, because the truth damper is stateful).
`columns(result)` names a `simulate` result's state columns and step outputs.
Every Python-side run (dampnet.sim.quarter_car.runs: the study, `dampnet simulate`) goes through
QuarterCar: this module is the one driver of `_core.Loop`.

Threading: the model side (`_core.Mlp`, `_core.Damper`, `_core.LoopModel`) is immutable
and may be shared by threads; a loop state (`_core.Loop`, and so a `QuarterCar`) is not: one
call at a time, a second concurrent call raises RuntimeError. One `spawn()` per thread.
A truth (callback) damper holds its own state: one loop at a time.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from dampnet import _core
from dampnet.sim.vehicle import LoopError
from dampnet.terms import terms_force, validate as _validate_term

Damper = _core.Damper
STATE_NAMES: tuple[str, ...] = tuple(_core.STATE_NAMES)
FEATURE_NAMES: tuple[str, ...] = tuple(_core.FEATURE_NAMES)
S = {name: i for i, name in enumerate(STATE_NAMES)}  # state index by name


def damper_from_model(model, single: bool = False) -> _core.Damper:
    """A neural damper (hybrid when the model has terms) from an MlpModel.

    Unknown feature names or feature_params, a derived feature without its parameter
    (voltage_lag/current_lag: control_lag_tau_s, velocity_lag: velocity_lag_tau_s,
    friction_state: friction_presliding_m) or a parameter <= 0 raise ValueError here.
    """
    d = _core.Damper.neural(model.core(), list(model.features),
                            {k: float(v) for k, v in model.feature_params.items()}, single)
    for t in model.terms:
        d.add_term(t["kind"], _validate_term(t))
    return d


def add_terms(damper: _core.Damper, terms) -> _core.Damper:
    """Add physics terms ([{"kind", "params"}]) to any damper; returns it."""
    for t in terms:
        damper.add_term(t["kind"], _validate_term(t))
    return damper


def static_term_force(terms, x_static: float = 0.0) -> float:
    """The terms' force at rest at x_static: the value for the vehicle's f_static."""
    return float(terms_force(terms, np.array(x_static), np.array(0.0), u=np.array(0.0)))  # at rest: v = 0


def truth_damper(truth, loop_temperature: bool = True) -> _core.Damper:
    """The rig's TruthDamper (dampnet.rig.truth) as a callback damper.

    Use it with vehicle={"damper_eval": "per_step"} (RK4) or "semi_euler": the
    truth damper has internal state and must be called once per step.
    loop_temperature: the truth at the loop's temperature state; False: at its own
    reference temperature (TruthParams.temperature_ref_c), as the study runs it.
    """
    if loop_temperature:
        def force(inp) -> float:
            return truth.step(inp.dt, inp.x, inp.v, inp.u, inp.temperature)
    else:
        def force(inp) -> float:
            return truth.step(inp.dt, inp.x, inp.v, inp.u)
    return _core.Damper.callback(force)


# Loop.simulate's key of each step output (STEP_OUTPUT_FIELDS) that it names differently:
# the control, "u" in a StepReport, is "control" there (cpp/python/arrays.cpp).
_SIMULATE_KEY = {"u": "control"}


def columns(res: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """A `simulate` result as one array per name: the state's columns (STATE_NAMES: t, z_s,
    v_s, z_us, v_us, z_r, v_r, ...) and the step outputs it holds under their
    STEP_OUTPUT_FIELDS names (force, u, x, v, a, acc_s, acc_us, features, status); views."""
    out = {name: res["state"][:, i] for i, name in enumerate(STATE_NAMES)}
    for name in _core.STEP_OUTPUT_FIELDS:
        key = _SIMULATE_KEY.get(name, name)
        if key in res:
            out[name] = res[key]
    return out


class QuarterCar:
    """A loop model (constant) plus one loop state (mutable).

    vehicle: DN_VEHICLE_FIELDS by name (m_s, m_us, k_s, k_t, c_t, dt, integrator
    "rk4"|"semi_euler", damper_eval "per_stage"|"per_step", x_static, f_static,
    temperature); controller: DN_CONTROLLER_FIELDS (kind "passive",
    "skyhook_onoff", "skyhook_continuous", "groundhook_onoff",
    "groundhook_continuous", "external", and the gains/limits). Each enum field takes
    its own names only (or their integer values); a wrong name, a wrong type or an
    unknown key raises ValueError/TypeError naming the field.

    Threading: `model` (a LoopModel) may be shared by threads; `loop` (the state) may
    not: a call while another is under way (e.g. `simulate` in another thread) raises
    RuntimeError. Give each thread its own `spawn()`.
    """

    def __init__(self, damper: _core.Damper, vehicle: Mapping[str, Any] | None = None,
                 controller: Mapping[str, Any] | None = None, model: _core.LoopModel | None = None):
        if model is None:
            try:
                model = _core.LoopModel(damper, dict(vehicle or {}), dict(controller or {}))
            except ValueError as e:   # the runtime's refusal, naming the field: a run's settings error
                raise LoopError(str(e)) from None
        self.model = model
        self.loop = _core.Loop(self.model)

    @property
    def dt(self) -> float:
        return float(self.model.vehicle["dt"])

    def spawn(self) -> "QuarterCar":
        """Another loop state on the same (shared, constant) model: one per thread."""
        return QuarterCar(None, model=self.model)

    def reset(self) -> None:
        self.loop.reset()

    @property
    def state(self) -> np.ndarray:
        return self.loop.state

    @state.setter
    def state(self, s) -> None:
        self.loop.state = np.asarray(s, dtype=np.float64)

    def step(self, z_r: float, v_r: float, u: float = 0.0) -> "_core.StepReport":
        """One step; (z_r, v_r) is the road at the END of the step. Report at its start: a
        read-only StepReport (attributes, and a Mapping with the same keys); `step_force` of
        `self.loop` returns the force alone, faster."""
        return self.loop.step(z_r, v_r, u)

    def simulate(self, road, road_rate=None, u=None, reset: bool = True, out: dict | None = None) -> dict:
        """Run a road sampled at dt in C++; returns numpy arrays, one row per sample.

        road [n] (m); road_rate [n] (m/s; default: np.gradient(road, dt), which is
        only second-order accurate: pass the exact rate when you have it); u [n]:
        the control for the "external" controller. Row k holds the state at
        t_k = t_0 + k dt (`state`, columns STATE_NAMES) and what the step from t_k
        reported: force, control, x, v, a (the acceleration feature), acc_s,
        acc_us, features [n, n_features], status. With reset, the loop starts at
        rest with the road at road[0]; otherwise from its current state (the
        state's road is replaced by road[0]).

        out: a previous result for a road of the same length (a dict with these keys,
        arrays of the same dtypes and shapes, C-contiguous, aligned, writeable, sharing
        memory neither with the inputs nor with each other): the run writes into its
        arrays instead of allocating new ones (no page faults on fresh memory; the fastest
        way to run many roads) and returns a dict of plain ndarray views of that memory;
        after an error their contents are unspecified. None (default): fresh arrays.
        Without u, the external law's control is 0 (then clamped to its limits).
        The GIL is released during the run; another call on this car meanwhile (another
        thread) raises RuntimeError: use `spawn()` per thread.
        """
        road = np.ascontiguousarray(road, dtype=np.float64)
        if road_rate is None:
            road_rate = np.gradient(road, self.dt) if road.size > 1 else np.zeros_like(road)
        road_rate = np.ascontiguousarray(road_rate, dtype=np.float64)
        if u is not None:
            u = np.ascontiguousarray(u, dtype=np.float64)
        res = self.loop.simulate(road, road_rate, u, reset, out)
        res["t"] = res["state"][:, S["t"]]
        return res
