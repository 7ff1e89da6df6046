"""Control laws by name: the one vocabulary and the one calibration of every front end
(`dampnet simulate --control`, the sweep's [simulation] controllers and [fullcar] damping,
`dampnet vehicle --damping`, `dampnet study`, the quarter-car FMU's --controller, the Cortex-M
firmware's loop and `dampnet bench`'s hard-input check of the HIL loop).

Each law is calibrated on the damper it controls by its registered builder (its calibration
hook: LawContext -> Controller): passive at the damper's own low or high damping control
(`damping_levels`), the switching laws between those two with the command filter (u_tau_s,
default 5 ms), skyhook_continuous with c_sky, c_min, c_max from the vehicle and the damper
(`continuous_skyhook`), groundhook_continuous with c_gnd, c_min, c_max by the same principle
(`continuous_groundhook`); no law runs with the runtime's default gains. Fields a front end
sets itself (the sweep's [simulation.controller], e.g. u_passive) then replace the calibrated
ones, and the Controller is checked by the runtime (`Controller.validate`). A run records the
law's registered name (`law`) beside the runtime's kind (its controller's `kind`).

    ctrl = make("skyhook_onoff", spec, vehicle)            # dampnet.sim.vehicle.Controller
    ctrl = make("passive", spec, vehicle, damping="low")   # the --damping / --u options
    names()                                                # the laws, for help texts and specs

The runtime's laws (`_core.CONTROLLER_KINDS`, but "external": its control comes from the
caller, QuarterCar.simulate(u=...)) are registered from the runtime's list, so a law added
there is a law here (a switching law between the damper's levels unless calibrated below);
passive_low / passive_high name the passive law at one level.
Adding a law: `register(ControlLaw(...))` (docs/recipes.md, "Control laws").
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Mapping

from dampnet import _core
from dampnet.sim.vehicle import Controller, LoopError, Vehicle

if TYPE_CHECKING:    # the calibration (numpy, the dampers) is imported when a law is made: help texts stay light
    from dampnet.sim.dampers import DamperSpec

#: the law whose control is the caller's (not a law a run can be asked for by name)
EXTERNAL = "external"


@dataclass(frozen=True)
class LawContext:
    """What a law is calibrated on: the damper (`spec`) and its `levels` ({"low", "high"}: its
    low / high damping control [V or A]), the vehicle, the command filter `u_tau_s` [s] (None: the
    law's own default, dampnet.sim.calibration's SKYHOOK_COMMAND_TAU_S or FORCE_COMMAND_TAU_S), and
    the passive law's options `damping` ("low" | "high") and `u` [V or A] (None: the level's)."""

    spec: DamperSpec
    levels: Mapping[str, float]
    vehicle: Vehicle
    u_tau_s: float | None
    damping: str = "high"
    u: float | None = None


@dataclass(frozen=True)
class ControlLaw:
    """A registry entry: `name`, a doc line, the settings it takes from its context or
    calibrates ({name: "unit: meaning"}), and `build(ctx)` -> Controller."""

    name: str
    doc: str
    build: Callable[[LawContext], Controller]
    params: Mapping[str, str] = dataclasses.field(default_factory=dict)
    aliases: tuple[str, ...] = ()
    #: the LawContext options the law reads from its caller ("damping", "u", "u_tau_s"); a caller's
    #: value for another is refused (check_context), not silently ignored
    reads: tuple[str, ...] = ()


_REGISTRY: dict[str, ControlLaw] = {}
_ALIASES: dict[str, str] = {}


def register(law: ControlLaw) -> ControlLaw:
    """Add a law to the vocabulary (its name and aliases must be new)."""
    for n in (law.name, *law.aliases):
        if n in _ALIASES or n == EXTERNAL:
            raise ValueError(f"control law {n!r} is already registered")
    _REGISTRY[law.name] = law
    for n in (law.name, *law.aliases):
        _ALIASES[n] = law.name
    return law


def check_context(name: str, given: Mapping[str, tuple[str, Any]]) -> None:
    """LoopError when the caller gives law `name` an option it does not read: `given` maps each
    option's words (e.g. "--u") to (its LawContext field, its value; None: not given). Issue 49:
    `simulate --control skyhook_onoff --u 3` ran skyhook and ignored --u."""
    law = get(name)
    for words, (field_name, value) in given.items():
        if value is not None and field_name not in law.reads:
            takers = [n for n, x in _REGISTRY.items() if field_name in x.reads]
            raise LoopError(f"{words}: control law {law.name!r} does not take it (it applies to "
                            f"{', '.join(takers) or 'no law'})")


def unregister(name: str) -> None:
    """Remove a law (tests register their own and remove them after)."""
    law = _REGISTRY.pop(_ALIASES[name])
    for n in (law.name, *law.aliases):
        _ALIASES.pop(n, None)


def names() -> tuple[str, ...]:
    """The laws' names, in registration order."""
    return tuple(_REGISTRY)


def get(name: str) -> ControlLaw:
    """The law of a name or alias; LoopError naming it and listing the laws otherwise."""
    if isinstance(name, str) and name in _ALIASES:
        return _REGISTRY[_ALIASES[name]]
    why = ("takes its control from the caller (QuarterCar.simulate(u=...)), not from a control law by name"
           if name == EXTERNAL else "is not a control law")
    raise LoopError(f"{name!r} {why}; valid: " + ", ".join(repr(k) for k in _REGISTRY))


def make(name: str, spec: DamperSpec, vehicle: Vehicle | None = None, *, u_tau_s: float | None = None,
         damping: str = "high", u: float | None = None, fields: Mapping[str, Any] | None = None,
         limit_to_levels: bool = False) -> Controller:
    """The Controller of law `name` calibrated on `spec` (see the module docstring); `fields`:
    Controller fields set over the calibrated ones; `limit_to_levels`: the command limited to the
    damper's low..high levels (u_min, u_max), as the full vehicle runs every law. LoopError (one
    line) on a bad name or value."""
    from dampnet.sim.calibration import damping_levels

    law = get(name)
    veh = vehicle or Vehicle()
    if damping not in ("low", "high"):
        raise LoopError(f"damping: expected 'low' or 'high', got {damping!r}")
    ctx = LawContext(spec, damping_levels(spec, veh.dt), veh, u_tau_s, damping, u)
    ctrl = law.build(ctx)
    if limit_to_levels:
        ctrl = dataclasses.replace(ctrl, u_min=min(ctx.levels.values()), u_max=max(ctx.levels.values()))
    settable = {f.name for f in dataclasses.fields(Controller)} - {"kind"}
    unknown = sorted(set(fields or {}) - settable)
    if unknown:
        raise LoopError(f"control law {name!r}: {unknown[0]!r} is not a controller field to set")
    ctrl = dataclasses.replace(ctrl, **dict(fields or {}))
    ctrl.validate()
    return ctrl


#: the full vehicle's damping settings (`dampnet vehicle --damping`, the sweep's [fullcar] damping,
#: the full-car study): each is a law of this registry at every corner, limited to the damper's levels
VEHICLE_DAMPING: dict[str, str] = {"low": "passive_low", "high": "passive_high", "skyhook": "skyhook_onoff"}
#: the thesis's full-vehicle settings, the full-car study's default (the force-tracking laws added to
#: VEHICLE_DAMPING below need a damper with a control: not the truth, a callback)
THESIS_VEHICLE_DAMPING: tuple[str, ...] = tuple(VEHICLE_DAMPING)


def vehicle_controller(spec: DamperSpec, damping: str, params: Mapping[str, Any] | None = None) -> Controller:
    """Every corner's controller for a full-vehicle damping setting (VEHICLE_DAMPING), calibrated
    on `spec` and on the full car's mean corner (`corner_vehicle`; params: the full car's fields set);
    LoopError naming the settings otherwise."""
    if damping not in VEHICLE_DAMPING:
        raise LoopError(f"damping must be one of {', '.join(VEHICLE_DAMPING)}, got {damping!r}")
    return make(VEHICLE_DAMPING[damping], spec, corner_vehicle(params), limit_to_levels=True)


def model_controller(name: str, model, accel_feature: str, u_tau_s: float) -> Controller:
    """Law `name` made for a trained model (its neural damper) in thesis Table 5's quarter car with
    the acceleration scheme `accel_feature` and the command filter `u_tau_s` [s]: the controller of
    the loops that run a model outside a study (the firmware's, the HIL check's)."""
    from dampnet.sim.dampers import neural_spec

    return make(name, neural_spec(model), Vehicle(accel_feature=accel_feature), u_tau_s=u_tau_s)


def firmware_controller(model) -> Controller:
    """The Cortex-M firmware's controller for `model` (dampnet.export.mcu: `dampnet export --target`'s
    example firmware and the firmware lab): its law LOOP_LAW in its loop's configuration LOOP_CONFIG."""
    from dampnet.export.mcu import LOOP_CONFIG, LOOP_LAW

    return model_controller(LOOP_LAW, model, LOOP_CONFIG["accel_feature"], LOOP_CONFIG["u_tau_s"])


def corner_vehicle(params: Mapping[str, Any] | None = None) -> Vehicle:
    """The quarter car a full-car law is calibrated on: the full car's mean corner (params over the
    full car's defaults): a quarter of the sprung mass m_s, the mean of the axles' m_us and k_s, its
    k_t and c_t (SI units). The default full car's: 650 kg, 40 kg, 15 kN/m, 200 kN/m."""
    from dampnet.sim.full_car.params import defaults

    p = {**defaults(), **(params or {})}
    return Vehicle(m_s=p["m_s"] / 4.0, m_us=0.5 * (p["m_us_f"] + p["m_us_r"]), k_s=0.5 * (p["k_s_f"] + p["k_s_r"]),
                   k_t=p["k_t"], c_t=p["c_t"])


def help_text() -> str:
    """The laws, each with its doc line (for --help and docs)."""
    return "; ".join(f"{law.name}: {law.doc}" for law in _REGISTRY.values())


# -- the built-in laws ------------------------------------------------------------------------

def _passive(level: str | None) -> Callable[[LawContext], Controller]:
    def build(ctx: LawContext) -> Controller:
        if level is None and ctx.u is not None:
            return Controller(kind="passive", u_passive=ctx.u)
        return Controller(kind="passive", u_passive=ctx.levels[level or ctx.damping])
    return build


_LEVEL = "V or A: the damper's own low / high damping control (damping_levels)"
register(ControlLaw("passive", "a constant control: the damper's level --damping (low, high; default high), or --u",
                    _passive(None), {"damping": "low | high", "u_passive": f"{_LEVEL}, or --u"},
                    reads=("damping", "u")))
register(ControlLaw("passive_low", "passive at the damper's low damping control", _passive("low"),
                    {"u_passive": _LEVEL}))
register(ControlLaw("passive_high", "passive at the damper's high damping control", _passive("high"),
                    {"u_passive": _LEVEL}))
def _continuous(calibrate: str) -> Callable[[LawContext], Controller]:
    """A continuous law's builder: dampnet.sim.calibration's `calibrate` on the context."""
    def build(ctx: LawContext) -> Controller:
        from dampnet.sim import calibration

        return getattr(calibration, calibrate)(ctx.spec, dict(ctx.levels), ctx.vehicle, **_tau(ctx))
    return build


def _switching(kind: str) -> Callable[[LawContext], Controller]:
    def build(ctx: LawContext) -> Controller:
        from dampnet.sim.calibration import semi_active

        return semi_active(kind, dict(ctx.levels), **_tau(ctx))
    return build


def _tau(ctx: LawContext) -> dict[str, float]:
    """The caller's command filter for a calibration function, or nothing (its own default)."""
    return {} if ctx.u_tau_s is None else {"u_tau_s": ctx.u_tau_s}


#: the runtime's continuous laws, each calibrated by its dampnet.sim.calibration function:
#: (that function, its doc line, its calibrated gains with their units)
_CONTINUOUS = {
    "skyhook_continuous": ("continuous_skyhook", "the runtime's continuous skyhook, c_sky / c_min / c_max "
                           "calibrated on the damper and the vehicle", "c_sky, c_min, c_max"),
    "groundhook_continuous": ("continuous_groundhook", "the runtime's continuous groundhook, c_gnd / c_min / "
                              "c_max calibrated on the damper and the vehicle as skyhook's are", "c_gnd, c_min, c_max"),
}

def _force_tracking(kind: str) -> Callable[[LawContext], Controller]:
    def build(ctx: LawContext) -> Controller:
        from dampnet.sim.calibration import force_tracking

        return force_tracking(kind, ctx.spec, dict(ctx.levels), ctx.vehicle, **_tau(ctx))
    return build


#: the runtime's force-tracking laws (a demanded force [N] through the damper's inverse), each
#: calibrated by dampnet.sim.calibration.force_tracking: (its doc line, its calibrated gains)
_FORCE = {
    "skyhook_force": ("skyhook as a force, c_sky v_s, through the damper's inverse (c_sky as skyhook_continuous's)",
                      "c_sky"),
    "groundhook_force": ("groundhook as a force, -c_gnd v_us, through the damper's inverse", "c_gnd"),
    "hybrid_force": ("half skyhook_force's demand plus half groundhook_force's (alpha 0.5), through the inverse",
                     "c_sky, c_gnd, alpha"),
    "clipped_optimal": ("an LQR force on the quarter car's state (dampnet.sim.calibration.lqr_gains), clipped to "
                        "what the damper dissipates, through the inverse (Dyke et al. 1996)",
                        "k_travel, k_vs, k_tyre, k_vus"),
}

for _kind in _core.CONTROLLER_KINDS:
    if _kind in ("passive", EXTERNAL):
        continue
    if _kind in _FORCE:
        _doc, _gains = _FORCE[_kind]
        register(ControlLaw(_kind, _doc, _force_tracking(_kind),
                            {"u_soft, u_hard": _LEVEL, _gains: "calibrated on the vehicle (dampnet.sim.calibration)",
                             "u_tau_s": "s: command filter"}, reads=("u_tau_s",)))
    elif _kind in _CONTINUOUS:
        _fn, _doc, _gains = _CONTINUOUS[_kind]
        register(ControlLaw(_kind, _doc, _continuous(_fn),
                            {"u_soft, u_hard": _LEVEL, _gains: "N s/m: calibrated (dampnet.sim.calibration)",
                             "u_tau_s": "s: command filter"}, reads=("u_tau_s",)))
    else:
        register(ControlLaw(_kind, f"the runtime's {_kind} between the damper's low and high damping",
                            _switching(_kind),
                            {"u_soft, u_hard": _LEVEL, "u_tau_s": "s: command filter"}, reads=("u_tau_s",)))

# the full vehicle runs the force-tracking laws too, each by its own name
VEHICLE_DAMPING.update({_law: _law for _law in _FORCE})
