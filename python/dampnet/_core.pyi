"""Type stub of dampnet._core, the pybind11 module of the C++ runtime (cpp/python/).

Checked against the built module by tests/python/test_core_stub.py (mypy.stubtest): a name
the module has and this stub lacks fails the test. Units as in dampnet.h (SI; degC for
temperature). The registries are expanded from dampnet.h's X-macro lists.
"""

from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import Any, Final, final

import numpy as np
import numpy.typing as npt
from typing_extensions import Never

class _pybind11_type(type):
    """pybind11's metaclass of the bound classes (pybind11_builtins.pybind11_type)."""

__version__: Final[str]

def version() -> int:
    """Library version as major*10000 + minor*100 + patch."""

def status_str(status: int, /) -> str:
    """Explain a dampnet status code."""

# ---- build and size constants ----

BUILD_INFO: Final[dict[str, str | bool]]  # kernel_isa, flags, isa_flags, eigen, compiler
MAX_INPUTS: Final[int]
MAX_HIDDEN: Final[int]
MAX_HIDDEN2: Final[int]
MAX_HIDDEN_DEFAULT: Final[int]
DN_ACCEL_MAX_EVALS: Final[int]
#: Damper.inverse: at most this many evaluations after the two at the control limits
DN_INVERSE_MAX_ITERS: Final[int]
#: Damper.inverse: the control is found to within this share of the control range
DN_INVERSE_TOL_REL: Final[float]
#: Damper.inverse(u_start=...): at most this many Newton steps from u_start before the limits
DN_INVERSE_WARM_EVALS: Final[int]
#: dampnet.h DN_PLAUSIBLE_LIST: {name: (bound [SI unit], doc)}; a step beyond one is DN_E_DIVERGED
PLAUSIBLE_BOUNDS: Final[dict[str, tuple[float, str]]]
#: dampnet.h DN_STABLE_WDT_*: {integrator: largest dt w_hop}, checked when a model is created
STABLE_WDT: Final[dict[str, float]]

# ---- status codes (DN_STATUS_LIST): warnings are bit flags > 0, errors < 0 ----

DN_OK: Final[int]
DN_W_SATURATED: Final[int]
DN_W_NONFINITE_INPUT: Final[int]
DN_W_ACCEL_UNCONVERGED: Final[int]
DN_W_ACCEL_FALLBACK: Final[int]
DN_W_UNREACHABLE: Final[int]
DN_E_NULL: Final[int]
DN_E_SIZE: Final[int]
DN_E_NONFINITE_PARAM: Final[int]
DN_E_PARAM: Final[int]
DN_E_ACTIVATION: Final[int]
DN_E_ALLOC: Final[int]
DN_E_NONFINITE_OUTPUT: Final[int]
DN_E_MISMATCH: Final[int]
DN_E_UNKNOWN_NAME: Final[int]
DN_E_NONFINITE_INPUT: Final[int]
DN_E_DIVERGED: Final[int]

# ---- registries (dampnet.h's lists) ----

# Enum lists: {name: (value, doc)} in value order. The name is the one spelling of each
# value; vehicle/controller dicts take the name or the value.
CONTROLLER_KINDS: Final[dict[str, tuple[int, str]]]  # controller "kind"
INTEGRATORS: Final[dict[str, tuple[int, str]]]  # vehicle "integrator"
DAMPER_EVALS: Final[dict[str, tuple[int, str]]]  # vehicle "damper_eval"
ACCEL_FEATURES: Final[dict[str, tuple[int, str]]]  # vehicle "accel_feature"
ACTIVATIONS: Final[dict[str, tuple[int, str]]]  # Mlp(activation=...)
DAMPER_KINDS: Final[dict[str, tuple[int, str]]]  # Damper.kind
PRECISIONS: Final[dict[str, tuple[int, str]]]  # Damper.neural(single=...)

FEATURE_NAMES: Final[tuple[str, ...]]  # the neural features (DN_FEATURE_LIST order)
FEATURE_INPUTS: Final[dict[str, str]]  # feature -> the DAMPER_INPUT_FIELDS field it reads
FEATURE_PARAMS: Final[dict[str, str | None]]  # feature -> the FEATURE_PARAM_NAMES it needs
FEATURE_PARAM_NAMES: Final[dict[str, str]]  # feature parameter -> doc with unit and range
TERM_KINDS: Final[dict[str, tuple[int, str]]]  # term kind -> (number of params, formula)
STATE_NAMES: Final[tuple[str, ...]]  # Loop.state's columns: the loop's own, then DAMPER_STATES
STATE_DOCS: Final[dict[str, str]]  # Loop.state's column -> meaning [unit], in STATE_NAMES order
#: dampnet.h DN_DAMPER_STATE_LIST, the damper's own states in block order:
#: {name (its DAMPER_INPUT_FIELDS field): (unit, STATE_DYNAMICS name, source field, FEATURE_PARAM_NAMES parameter, doc)}
DAMPER_STATES: Final[dict[str, tuple[str, str, str, str, str]]]
STATE_DYNAMICS: Final[dict[str, tuple[int, str]]]  # DN_STATE_DYNAMICS_LIST: {name: (value, doc)}
LOOP_OUT_FIELDS: Final[dict[str, str]]  # dn_loop_out's scalars: name -> meaning [unit]
VEHICLE_FIELDS: Final[dict[str, tuple[float | int, str]]]  # field -> (default, doc)
CONTROLLER_FIELDS: Final[dict[str, tuple[float | int, str]]]  # field -> (default, doc)
DAMPER_INPUT_FIELDS: Final[dict[str, str]]  # DamperInput field -> doc with unit
STEP_OUTPUT_FIELDS: Final[dict[str, str]]  # StepReport key -> doc with unit

# A vehicle or controller: field name -> a number, or an enum field's name or value.
_FieldDict = dict[str, float | int | str]

def check_vehicle(vehicle: _FieldDict) -> None:
    """Validate a vehicle dict (VEHICLE_FIELDS) as LoopModel does: None, or ValueError /
    TypeError naming the field and its valid range or names."""

def check_controller(controller: _FieldDict) -> None:
    """Validate a controller dict (CONTROLLER_FIELDS) as LoopModel does: None, or ValueError /
    TypeError naming the field and its valid range or names."""

def force_demand(
    controller: _FieldDict,
    v_s: npt.ArrayLike,
    v_us: npt.ArrayLike,
    travel: npt.ArrayLike,
    tyre: npt.ArrayLike,
) -> npt.NDArray[np.float64]:
    """The force [N] a force-tracking law demands of the damper, as the loop computes it each step
    (positive resisting extension, 0 unless dissipative, 0 for the other laws): v_s, v_us [m/s],
    travel z_s - z_us [m], tyre deflection z_us - z_r [m]; arrays broadcast to one length."""

def check_fullcar(params: _FieldDict) -> None:
    """Validate full-car parameters (FULLCAR_FIELDS) as FullCarModel does: None, or ValueError /
    TypeError naming the field and its valid range or names."""

# ---- the full vehicle's registries (dampnet.h's DN_FULLCAR_* lists) ----
FULLCAR_FIELDS: Final[dict[str, tuple[float | int, str]]]  # field -> (default, doc)
FULLCAR_STATE_NAMES: Final[tuple[str, ...]]  # FullCar.state's columns
FULLCAR_OUT_CORNER_FIELDS: Final[dict[str, str]]  # per-corner report keys ([4] / [n, 4])
FULLCAR_OUT_FIELDS: Final[dict[str, str]]  # vehicle report keys (float / [n])
FULLCAR_CORNERS: Final[tuple[str, ...]]  # ("fl", "fr", "rl", "rr")
TYRE_MODELS: Final[dict[str, tuple[int, str]]]  # full-car "tyre_model"
STEER_MODES: Final[dict[str, tuple[int, str]]]  # full-car "steer_mode"

# ---- the MLP ----

class Mlp(metaclass=_pybind11_type):
    """An immutable MLP model evaluated by the C++ kernel; may be shared by threads."""

    def __init__(
        self,
        w1: npt.ArrayLike,
        b1: npt.ArrayLike,
        w2: npt.ArrayLike | None,
        b2: npt.ArrayLike | None,
        w_out: npt.ArrayLike,
        b_out: npt.ArrayLike,
        in_offset: npt.ArrayLike,
        in_gain: npt.ArrayLike,
        in_ymin: float,
        out_offset: float,
        out_gain: float,
        out_ymin: float,
        sat_lo: npt.ArrayLike,
        sat_hi: npt.ArrayLike,
        activation: str,
    ) -> None: ...
    @property
    def n_inputs(self) -> int: ...
    def forward(self, x: npt.ArrayLike, single: bool = False) -> tuple[float, int, int]:
        """One sample -> (output, status, clamped_mask)."""
    def predict(
        self, x: npt.ArrayLike, single: bool = False
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int32], npt.NDArray[np.uint32]]:
        """Samples [n, n_inputs] -> (outputs[n], status[n], clamped_mask[n]); GIL released."""

# ---- dampers ----

class DamperInput(metaclass=_pybind11_type):
    """What a damper is evaluated on (dn_damper_input; fields: DAMPER_INPUT_FIELDS)."""

    # <generated: DamperInput>
    x: float  # relative displacement, extension positive, from the mid position [m]
    v: float  # relative velocity, extension positive [m/s]
    a: float  # relative acceleration, extension positive [m/s^2] (see the loop)
    u: float  # control, held over the step [V or A]
    u_lag: float  # control after a first-order lag of the model's control_lag_tau_s [V or A]
    temperature: float  # damper temperature [degC]
    t: float  # time of this evaluation [s] (callback dampers)
    dt: float  # step size of the loop [s] (callback dampers); 0 outside a loop
    stage: int  # integrator stage of this evaluation, 0..3 [-] (callback dampers)
    v_lag: float  # velocity after a first-order lag of the model's velocity_lag_tau_s [m/s]
    z_fric: float  # Dahl friction state in [-1, 1]: follows sgn(v) over a travel of a few friction_presliding_m after each reversal [-]
    # </generated>
    def __init__(self) -> None: ...

class Damper(metaclass=_pybind11_type):
    """A damper model (dn_damper); immutable once set up, may be shared by threads."""

    # no constructor (Damper() raises TypeError): build one with a static method below
    def __init__(self, *args: Never, **kwargs: Never) -> None: ...

    @staticmethod
    def linear(c: float) -> Damper:
        """F = c v."""
    @staticmethod
    def parametric(
        c_min: float, c_max: float, gamma: float, f0: float, v_max: float, v_smooth: float = 0.0
    ) -> Damper:
        """The thesis's eq. 1-3 (see dn_parametric_params)."""
    @staticmethod
    def table(velocities: npt.ArrayLike, controls: npt.ArrayLike, forces: npt.ArrayLike) -> Damper:
        """Bilinear lookup table, clamped outside the grid."""
    @staticmethod
    def neural(
        mlp: Mlp, features: list[str], feature_params: Mapping[str, float] = ..., single: bool = False
    ) -> Damper:
        """The MLP on named features (FEATURE_NAMES; parameters FEATURE_PARAM_NAMES)."""
    @staticmethod
    def callback(fn: Callable[[DamperInput], float]) -> Damper:
        """A Python function fn(DamperInput) -> force [N] (slow path, holds the GIL)."""
    def add_term(self, kind: str, params: npt.ArrayLike) -> None:
        """Add a physics term (TERM_KINDS); set-up, before the damper is used."""
    def terms_grad(
        self, x: npt.ArrayLike, v: npt.ArrayLike, u: npt.ArrayLike
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64],
               npt.NDArray[np.float64], npt.NDArray[np.int32]]:
        """The physics terms alone at (x [m], v [m/s], u [V or A]), vectorised -> (force [N],
        dF/dx [N/m], dF/dv [N s/m], dF/du [N per control unit], status) (dn_damper_terms_grad;
        dF/da is 0: no term reads the acceleration)."""
    @property
    def kind(self) -> int:
        """The DAMPER_KINDS value."""
    def forces(
        self,
        x: npt.ArrayLike,
        v: npt.ArrayLike,
        a: npt.ArrayLike,
        u: npt.ArrayLike,
        u_lag: npt.ArrayLike,
        temperature: npt.ArrayLike,
        # <generated: Damper.forces>
        v_lag: npt.ArrayLike = ...,
        z_fric: npt.ArrayLike = ...,
        # </generated>
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int32], npt.NDArray[np.uint32]]:
        """Vectorised force [N] -> (force[n], status[n], clamped_mask[n])."""
    def inverse(
        self,
        force: npt.ArrayLike,
        x: npt.ArrayLike,
        v: npt.ArrayLike,
        a: npt.ArrayLike,
        u_lag: npt.ArrayLike,
        temperature: npt.ArrayLike,
        v_lag: npt.ArrayLike = ...,
        z_fric: npt.ArrayLike = ...,
        *,
        u_start: npt.ArrayLike | None = ...,
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.int32], npt.NDArray[np.int32]]:
        """Vectorised inverse: the control [V or A] giving the demanded force [N] at this motion
        -> (u[n], force[n] achieved [N], status[n], evaluations[n], the limits' included);
        DN_W_UNREACHABLE: the nearer control limit. Newton's steps start at the first-iterate
        grid's control, or at u_start [V or A] (a controller's last command)."""
    def control_range(self) -> tuple[float, float]:
        """(u_min, u_max) [V or A] that the inverse searches; ValueError without a control."""
    def control_monotonicity(
        self,
        v_min: float,
        v_max: float,
        n_v: int = ...,
        n_u: int = ...,
        tolerance_N: float = ...,
        at: Mapping[str, float] = ...,
    ) -> dict[str, float | int]:
        """Where F(u) turns back: {n_reversed, v_worst [m/s], u_from, u_to [V or A], reversal_N [N]}."""

# ---- the quarter-car loop ----

class LoopModel(metaclass=_pybind11_type):
    """Vehicle, damper and controller (constant): immutable, may drive Loops in many threads."""

    def __init__(self, damper: Damper, vehicle: _FieldDict = ..., controller: _FieldDict = ...) -> None: ...
    @property
    def vehicle(self) -> dict[str, float | int]: ...
    @property
    def controller(self) -> dict[str, float | int]: ...
    def control(
        self, v_s: npt.ArrayLike, v_us: npt.ArrayLike, u_ext: npt.ArrayLike = ...
    ) -> npt.NDArray[np.float64]:
        """The control law alone on arrays of velocities -> control [V]."""

@final
class StepReport(Mapping[str, Any]):
    """A step's report (Loop.step): read-only attributes, and a read-only mapping with the
    same keys (STEP_OUTPUT_FIELDS)."""

    @property
    def force(self) -> float: ...
    @property
    def u(self) -> float: ...
    @property
    def x(self) -> float: ...
    @property
    def v(self) -> float: ...
    @property
    def a(self) -> float: ...
    @property
    def acc_s(self) -> float: ...
    @property
    def acc_us(self) -> float: ...
    @property
    def features(self) -> npt.NDArray[np.float64]: ...
    @property
    def clamped_mask(self) -> int: ...
    @property
    def status(self) -> int: ...
    def __getitem__(self, key: str, /) -> Any: ...
    def __iter__(self) -> Iterator[str]: ...
    def __len__(self) -> int: ...
    def __contains__(self, key: object, /) -> bool: ...
    def to_dict(self) -> dict[str, Any]: ...

class Loop(metaclass=_pybind11_type):
    """A loop's mutable state for a LoopModel: one call at a time (RuntimeError otherwise)."""

    def __init__(self, model: LoopModel) -> None: ...
    def reset(self) -> None: ...
    @property
    def state(self) -> npt.NDArray[np.float64]:
        """Flat state (STATE_NAMES)."""
    @state.setter
    def state(self, value: npt.ArrayLike) -> None: ...
    def step(self, z_r: float, v_r: float, u: float = 0.0) -> StepReport:
        """One step; road [m], road rate [m/s] at the end of the step; external control u."""
    def step_force(self, z_r: float, v_r: float, u: float = 0.0) -> float:
        """One step, as step(), returning only the damper force [N]."""
    def forward(self, u: float = 0.0) -> StepReport:
        """The report without advancing."""
    def simulate(
        self,
        road: npt.ArrayLike,
        road_rate: npt.ArrayLike,
        u: npt.ArrayLike | None = None,
        reset: bool = True,
        out: dict[str, npt.NDArray[Any]] | None = None,
    ) -> dict[str, npt.NDArray[Any]]:
        """Run a road in C++ (GIL released) -> state, force, control, x, v, a, acc_s, acc_us,
        features, status arrays."""
    @property
    def model(self) -> LoopModel: ...
    @property
    def damper_evals(self) -> int: ...

# ---- the full vehicle ----
class FullCarModel(metaclass=_pybind11_type):
    """Parameters, four dampers (FL, FR, RL, RR), four controllers and the driver's path
    (constant): immutable, may drive FullCars in many threads."""

    def __init__(
        self,
        dampers: Sequence[Damper],
        params: _FieldDict = ...,
        controllers: _FieldDict | Sequence[_FieldDict] | None = None,
        path_x: npt.ArrayLike | None = None,
        path_y: npt.ArrayLike | None = None,
    ) -> None: ...
    @property
    def params(self) -> dict[str, float | int]: ...
    @property
    def controllers(self) -> list[dict[str, float | int]]: ...
    @property
    def corner_mobility(self) -> npt.NDArray[np.float64]:
        """K [1/kg], 4 x 4: a = a_free - K (F - f_static)."""

class FullCar(metaclass=_pybind11_type):
    """A full vehicle's mutable state for a FullCarModel: one call at a time (RuntimeError
    otherwise)."""

    def __init__(self, model: FullCarModel) -> None: ...
    def reset(self) -> None: ...
    @property
    def state(self) -> npt.NDArray[np.float64]:
        """Flat state (FULLCAR_STATE_NAMES)."""
    @state.setter
    def state(self, value: npt.ArrayLike) -> None: ...
    def step(
        self, z_r: npt.ArrayLike, v_r: npt.ArrayLike, steer: float = 0.0, u: npt.ArrayLike | None = None
    ) -> dict[str, Any]:
        """One step: road [m] / rate [m/s] under the 4 wheels at the step end, steer [rad]."""
    def forward(self, steer: float = 0.0, u: npt.ArrayLike | None = None) -> dict[str, Any]:
        """The report without advancing."""
    def simulate(
        self,
        road: npt.ArrayLike,
        road_rate: npt.ArrayLike,
        steer: npt.ArrayLike | None = None,
        u: npt.ArrayLike | None = None,
        reset: bool = True,
    ) -> dict[str, npt.NDArray[Any]]:
        """Roads [n, 4] in C++ (GIL released) -> state, status, report arrays."""
    @property
    def model(self) -> FullCarModel: ...
    @property
    def damper_evals(self) -> int: ...

# ---- the training envelope's bounded-time check ----

ENVELOPE_CELLS: Final[int]  # cells per input across its training range
ENVELOPE_PAIR_WORDS: Final[int]  # uint32 words of one pair's bitmap
ENV_OUTSIDE_RANGE: Final[int]  # flag bit: an input outside its training range, or NaN
ENV_OUTSIDE_JOINT: Final[int]  # flag bit: two inputs in range, in an empty cell of their plane

class Envelope(metaclass=_pybind11_type):
    """A model's coarse training envelope (per-input ranges and per-pair occupancy bitmaps,
    dampnet.h 'Training envelope'); immutable, may be shared by threads."""

    def __init__(self, lo: npt.ArrayLike, hi: npt.ArrayLike, cells: npt.ArrayLike) -> None: ...
    @property
    def n_inputs(self) -> int: ...
    def check(self, x: npt.ArrayLike) -> npt.NDArray[np.uint32]:
        """Points [n, n_inputs] (feature units) -> flags[n] uint32: 0 inside, bit 0 an input outside its range (or NaN), bit 1 a pair of inputs in an empty cell; GIL released."""
