"""The full vehicle's parameters: the runtime's dn_fullcar_params (dampnet._core.FULLCAR_FIELDS:
defaults, units, ranges, enum names), validated by the runtime's own check, and where each
default figure comes from.

The defaults are a compact-pickup-class vehicle built around the thesis's quarter car: each
front corner is Table 5 exactly (700 kg sprung, 40 kg unsprung, 15 kN/m, 200 kN/m); the rest
are estimates of the class, listed in SOURCES.
"""

from __future__ import annotations

from dampnet import _core
from dampnet.sim.vehicle import LoopError

#: the scheme of the Python-side full-car runs (the studies: `dampnet vehicle`, the sweep, the
#: demo): the dampers and tyres evaluated at every RK4 stage, fourth order throughout. The
#: real-time configuration `dampnet bench` times evaluates them once per step (first order in the
#: forces: a linear damper's sweep transmissibility 1-3 % off); the rig's truth damper, a
#: callback whose state advances at each call, runs per step (TRUTH_SCHEME).
RUN_SCHEME = {"damper_eval": "per_stage"}
TRUTH_SCHEME = {"damper_eval": "per_step"}

#: where each default comes from
SOURCES = {
    "m_s": "estimate: 2600 kg sprung (a loaded compact pickup); with a, b it puts 700 kg on each front "
           "corner, thesis Table 5",
    "a, b": "estimate: 1.5 m / 1.75 m, wheelbase 3.25 m (compact crew-cab pickups: 3.2-3.3 m)",
    "t_f, t_r": "estimate: 1.6 m (class typical 1.55-1.65 m)",
    "h_cg": "estimate: 0.75 m (NHTSA light-vehicle inertial database, SAE 1999-01-1336: pickups "
            "0.65-0.80 m)",
    "i_xx, i_yy, i_zz": "estimate: radii of gyration 0.59 m roll, 1.22 m pitch (sprung mass), 1.32 m yaw (whole car) "
                        "(within the same database's pickup range)",
    "h_rc_f, h_rc_r": "estimate: 0.10 m front (independent), 0.35 m rear (leaf-sprung live axle)",
    "m_us_f, m_us_r, k_s_f, k_s_r, k_t": "thesis Table 5 (40 kg, 15 kN/m, 200 kN/m), all corners",
    "k_arb_f, k_arb_r": "estimate: 40 / 15 kN/m at the wheel: a roll gradient of 0.75 deg per m/s^2 "
                        "(7.4 deg/g with the tyres' compliance; soft Table 5 springs need stiff bars)",
    "tyre_*": "estimate: Magic Formula of a light-truck tyre: cornering stiffness ~100 kN/rad at "
              "7 kN, peak friction 0.95, load sensitivity -0.1",
    "speed": "120 km/h: the thesis's CarSim double lane change",
}


def defaults() -> dict:
    """{field: default} of the runtime (enum fields by name)."""
    names = {"tyre_model": _core.TYRE_MODELS, "steer_mode": _core.STEER_MODES,
             "damper_eval": _core.DAMPER_EVALS, "accel_feature": _core.ACCEL_FEATURES}
    out = {}
    for k, (v, _doc) in _core.FULLCAR_FIELDS.items():
        out[k] = next(n for n, (val, _) in names[k].items() if val == v) if k in names else v
    return out


def check(params: dict) -> dict:
    """The parameters validated by the runtime (LoopError naming the field otherwise)."""
    try:
        _core.check_fullcar(dict(params))
    except (ValueError, TypeError) as e:
        raise LoopError(f"vehicle parameter: {e}") from None
    return dict(params)


def wheelbase(params: dict | None = None) -> float:
    p = {**defaults(), **(params or {})}
    return float(p["a"] + p["b"])


def cg_to_axles(params: dict | None = None) -> tuple[float, float]:
    """(a_h, b_h) [m]: the whole car's CG (sprung mass at a, b; the unsprung masses at the axles,
    as the static loads put them) behind the front axle and ahead of the rear one: the lever
    arms of the runtime's lateral and yaw equations (fullcar.hpp) and of the car's footprint."""
    p = {**defaults(), **(params or {})}
    L = p["a"] + p["b"]
    m = p["m_s"] + 2 * p["m_us_f"] + 2 * p["m_us_r"]
    b_h = (p["m_s"] * p["b"] + 2 * p["m_us_f"] * L) / m  # L x the front axle's share of the weight
    return float(L - b_h), float(b_h)
