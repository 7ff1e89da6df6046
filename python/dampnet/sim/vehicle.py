"""The quarter car (thesis Table 5) and its controller for the Python side's runs: the runtime's
dn_vehicle and dn_controller (cpp/include/dampnet/dampnet.h), SI units, controls in volts.

Defaults, names and validation are the runtime's own (`dampnet._core.VEHICLE_FIELDS`,
`CONTROLLER_FIELDS`, `CONTROLLER_KINDS`, `ACCEL_FEATURES`, `check_vehicle`,
`check_controller`): nothing here retypes a range or a law name. What differs, and why:

* `Vehicle.f_static` may be None: the damper's force at rest with the control at rest
  (`dampnet.sim.quarter_car.runs` computes it; the runtime's default is 0 N).
* `Vehicle` has no `integrator` / `damper_eval`: these runs always use RK4 with one damper
  evaluation per step (`LOOP_SCHEME`), so that every model of a study is run like for like
  and the rig's stateful truth damper is stepped once per step.
* `Vehicle` has no `temperature`: neural dampers see the runtime's default (20 degC); the
  rig's truth damper runs at its own reference temperature.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from dampnet import _core

#: the loop scheme of every Python-side run (dn_vehicle's integrator and damper_eval)
LOOP_SCHEME = {"integrator": "rk4", "damper_eval": "per_step"}
#: the runtime's vehicle fields Vehicle leaves out (see the module docstring)
VEHICLE_FIELDS_NOT_HERE = ("integrator", "damper_eval", "temperature")


class LoopError(ValueError):
    """Nonsensical vehicle, controller or run settings."""


def _default(fields: dict, name: str):
    return fields[name][0]


def _default_name(fields: dict, name: str, names: dict) -> str:
    """An enum field's default as its name (the registry stores the value)."""
    value = fields[name][0]
    return next(n for n, (v, _) in names.items() if v == value)


def _checked(check, what: dict) -> None:
    """The runtime's validation; its ValueError / TypeError (naming the field and the valid
    range or names) as a LoopError."""
    try:
        check(what)
    except (ValueError, TypeError) as e:
        raise LoopError(str(e)) from None


_V = _core.VEHICLE_FIELDS
_C = _core.CONTROLLER_FIELDS


@dataclass
class Vehicle:
    """Quarter car (thesis Table 5) and the loop's step; SI units (see VEHICLE_FIELDS' docs)."""

    m_s: float = _default(_V, "m_s")
    m_us: float = _default(_V, "m_us")
    k_s: float = _default(_V, "k_s")
    k_t: float = _default(_V, "k_t")
    c_t: float = _default(_V, "c_t")
    dt: float = _default(_V, "dt")
    x_static: float = _default(_V, "x_static")
    f_static: float | None = None     # None: the damper's force at rest with the control at rest
    accel_feature: str = _default_name(_V, "accel_feature", _core.ACCEL_FEATURES)

    def core_dict(self, f_static: float | None = None) -> dict:
        """The runtime's vehicle dict (LoopModel), with LOOP_SCHEME; f_static: the value for
        None (default 0 N, the runtime's)."""
        d = asdict(self)
        if d["f_static"] is None:
            d["f_static"] = _default(_V, "f_static") if f_static is None else float(f_static)
        return {**d, **LOOP_SCHEME}

    def validate(self) -> None:
        """LoopError naming the field and its valid range (the runtime's check_vehicle)."""
        _checked(_core.check_vehicle, self.core_dict())

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass
class Controller:
    """Control law and its settings (the runtime's dn_controller; u in volts).

    kind: a name of `dampnet._core.CONTROLLER_KINDS` (passive, skyhook_onoff,
    skyhook_continuous, groundhook_onoff, groundhook_continuous, external, and the force-tracking
    skyhook_force, groundhook_force, hybrid_force, clipped_optimal: a demanded force [N] through
    the damper's inverse).
    """

    kind: str = _default_name(_C, "kind", _core.CONTROLLER_KINDS)
    u_passive: float = _default(_C, "u_passive")
    u_soft: float = _default(_C, "u_soft")
    u_hard: float = _default(_C, "u_hard")
    u_min: float = _default(_C, "u_min")
    u_max: float = _default(_C, "u_max")
    c_sky: float = _default(_C, "c_sky")
    c_gnd: float = _default(_C, "c_gnd")
    c_min: float = _default(_C, "c_min")
    c_max: float = _default(_C, "c_max")
    u_tau_s: float = _default(_C, "u_tau_s")  # command filter time constant [s]; 0 = none
    alpha: float = _default(_C, "alpha")        # hybrid_force's skyhook share [-]
    k_travel: float = _default(_C, "k_travel")  # clipped_optimal's gains: travel [N/m],
    k_vs: float = _default(_C, "k_vs")          # body velocity [N s/m],
    k_tyre: float = _default(_C, "k_tyre")      # tyre deflection [N/m],
    k_vus: float = _default(_C, "k_vus")        # wheel velocity [N s/m]

    def core_dict(self) -> dict:
        """The runtime's controller dict (LoopModel)."""
        return asdict(self)

    def validate(self) -> None:
        """LoopError naming the field and its valid range or names (the runtime's
        check_controller): an unknown law lists the valid ones."""
        _checked(_core.check_controller, self.core_dict())

    def to_dict(self) -> dict:
        return asdict(self)
