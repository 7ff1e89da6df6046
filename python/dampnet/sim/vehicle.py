"""The quarter car's parameters (thesis Table 5) and its controller, as the runtime's dn_vehicle and
dn_controller (cpp/include/dampnet/dampnet.h); SI units, controls in volts."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass


CONTROL_LAWS = ("passive", "skyhook", "skyhook_continuous", "groundhook", "groundhook_continuous")


ACCEL_MAX_EVALS = 6          # DN_ACCEL_MAX_EVALS
ACCEL_MODES = ("implicit", "explicit")


class LoopError(ValueError):
    """Nonsensical vehicle, controller or run settings."""


@dataclass
class Vehicle:
    """Quarter car (thesis Table 5) and the loop's step; SI units."""

    m_s: float = 700.0
    m_us: float = 40.0
    k_s: float = 15000.0
    k_t: float = 200000.0
    c_t: float = 0.0
    dt: float = 0.001
    x_static: float = 0.0
    f_static: float | None = None     # None: the damper's force at rest with the initial control
    accel_feature: str = "implicit"   # "implicit" | "explicit": see solve_acceleration / dn_accel_feature

    def validate(self) -> None:
        for name in ("m_s", "m_us", "k_s", "k_t", "c_t", "dt", "x_static"):
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or not math.isfinite(v):
                raise LoopError(f"vehicle {name} must be a finite number, got {v!r}")
        if self.f_static is not None and not math.isfinite(self.f_static):
            raise LoopError(f"vehicle f_static must be finite, got {self.f_static!r}")
        for name in ("m_s", "m_us", "k_t"):
            if getattr(self, name) <= 0:
                raise LoopError(f"vehicle {name} must be > 0, got {getattr(self, name)!r}")
        for name in ("k_s", "c_t"):
            if getattr(self, name) < 0:
                raise LoopError(f"vehicle {name} must be >= 0, got {getattr(self, name)!r}")
        if not (0 < self.dt <= 0.1):
            raise LoopError(f"time step dt must be in (0, 0.1] s, got {self.dt!r}")
        if self.accel_feature not in ACCEL_MODES:
            raise LoopError(f"vehicle accel_feature must be one of {ACCEL_MODES}, got {self.accel_feature!r}")

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass
class Controller:
    """Control law and its settings (the runtime's dn_controller; u in volts)."""

    kind: str = "passive"
    u_passive: float = 0.0
    u_soft: float = 5.0
    u_hard: float = 0.0
    u_min: float = 0.0
    u_max: float = 5.0
    c_sky: float = 2500.0
    c_gnd: float = 2500.0
    c_min: float = 500.0
    c_max: float = 4000.0
    u_tau_s: float = 0.0  # command filter time constant [s]; 0 = none (see run())

    def validate(self) -> None:
        if self.kind not in CONTROL_LAWS:
            raise LoopError(f"unknown control law {self.kind!r}; known: {', '.join(CONTROL_LAWS)}")
        for k, v in asdict(self).items():
            if k != "kind" and not math.isfinite(v):
                raise LoopError(f"controller {k} must be finite, got {v!r}")
        if not self.u_min <= self.u_max:
            raise LoopError("controller u_min must not exceed u_max")
        if self.u_tau_s < 0:
            raise LoopError(f"controller u_tau_s (command filter time constant, s) must be >= 0, got {self.u_tau_s!r}")
        if self.kind.endswith("continuous") and not self.c_max > self.c_min:
            raise LoopError("continuous laws need c_max > c_min")

    def law(self, v_s: float, v_us: float) -> float:
        v = v_s - v_us
        k = self.kind
        if k == "passive":
            return min(max(self.u_passive, self.u_min), self.u_max)
        d = 0.0
        if k == "skyhook":
            d = 1.0 if v_s * v > 0 else 0.0
        elif k == "groundhook":
            d = 1.0 if -v_us * v > 0 else 0.0
        elif k == "skyhook_continuous":
            if v_s * v > 0:
                d = min(max((self.c_sky * v_s / v - self.c_min) / (self.c_max - self.c_min), 0.0), 1.0)
        elif k == "groundhook_continuous":
            if -v_us * v > 0:
                d = min(max((-self.c_gnd * v_us / v - self.c_min) / (self.c_max - self.c_min), 0.0), 1.0)
        u = self.u_soft + d * (self.u_hard - self.u_soft)
        return min(max(u, self.u_min), self.u_max)

    def to_dict(self) -> dict:
        return asdict(self)
