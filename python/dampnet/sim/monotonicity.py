"""Is a damper's force monotone in its control? The check behind the runtime's inverse.

The inverse (`dn_damper_inverse`, `_core.Damper.inverse`) brackets the control between its limits
[u_min, u_max] (the model's saturation range of its voltage/current input) and assumes that, at a
given motion, the force moves one way from F(u_min) to F(u_max). A model that turns back over part
of the range (dF/du changes sign) still gets a defined inverse (a control giving the demand, or the
nearer limit), but not a unique one, and forces between the turning points may be missed. This
module scans the force over a grid of velocity v [m/s] x control u [V or A] and reports every
velocity at which F(u) goes against its overall direction, where, and by how much [N].

    report = control_monotonicity(damper_from_model(model), v_range=(-0.5, 0.5))
    report = model_control_monotonicity(model)      # the model's own envelope
    if not report.monotone: print(report.summary())

The runtime has the same scan without Python (set-up code, e.g. after loading a model on a
target): `dn_damper_control_monotonicity` in dampnet.h, `_core.Damper.control_monotonicity` here,
which reports the count of turning velocities and the largest turn (equal to this module's on the
same grid: tests/python/test_damper_inverse.py).

Units: v [m/s], u [V or A] (the model's control), forces [N]; the other inputs (displacement x
[m], acceleration a [m/s^2], temperature [degC], the states) are held at the values given.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from dampnet import _core

__all__ = ["MonotonicityViolation", "MonotonicityReport", "control_monotonicity",
           "model_control_monotonicity"]

# The quantities Damper.forces takes, in order (dn_damper_input's fields but the loop's t, dt and
# stage: the damper's states included, from the registry); u is the scanned control, v the velocity.
_QUANTITIES = tuple(f for f in _core.DAMPER_INPUT_FIELDS if f not in ("t", "dt", "stage"))


@dataclass(frozen=True)
class MonotonicityViolation:
    """At velocity v [m/s], F(u) runs against the row's direction (that of F(u_max) - F(u_min))
    from u_from to u_to [V or A] by force_reversal [N] (> the report's tolerance)."""

    v: float
    u_from: float
    u_to: float
    force_reversal: float
    direction: int  # +1: F rises from u_min to u_max at this v, -1: falls


@dataclass(frozen=True)
class MonotonicityReport:
    """The scan: its grid, the tolerance [N] and every velocity row that is not monotone."""

    v: np.ndarray  # the velocities scanned [m/s]
    u: np.ndarray  # the controls scanned [V or A]
    tolerance_N: float
    violations: list[MonotonicityViolation] = field(default_factory=list)

    @property
    def monotone(self) -> bool:
        return not self.violations

    @property
    def worst(self) -> MonotonicityViolation | None:
        return max(self.violations, key=lambda w: w.force_reversal, default=None)

    def summary(self) -> str:
        if self.monotone:
            return (f"monotone in the control over v in [{self.v[0]:g}, {self.v[-1]:g}] m/s, "
                    f"u in [{self.u[0]:g}, {self.u[-1]:g}] (tolerance {self.tolerance_N:.3g} N)")
        w = self.worst
        assert w is not None
        return (f"not monotone in the control at {len(self.violations)} of {len(self.v)} velocities; "
                f"worst at v = {w.v:.4g} m/s: F turns back by {w.force_reversal:.4g} N between "
                f"u = {w.u_from:.4g} and {w.u_to:.4g}")


def _reversal(f: np.ndarray) -> tuple[float, int, int]:
    """The largest rise-then-fall of f (f[i] - f[j], i < j, at its largest) and (i, j)."""
    run_max_idx = np.zeros(len(f), dtype=int)
    best = 0
    for k in range(1, len(f)):
        best = k if f[k] > f[best] else best
        run_max_idx[k] = best
    drops = f[run_max_idx] - f
    j = int(np.argmax(drops))
    return float(drops[j]), int(run_max_idx[j]), j


def control_monotonicity(damper: _core.Damper, v_range: tuple[float, float],
                         u_range: tuple[float, float] | None = None, n_v: int = 101, n_u: int = 201,
                         others: Mapping[str, float] | None = None,
                         tolerance_N: float | None = None) -> MonotonicityReport:
    """Scan F(v, u) of a damper on an n_v x n_u grid and report where dF/du changes sign.

    v_range: velocities [m/s]; u_range: controls [V or A] (default: damper.control_range());
    others: values of the other quantities (x, a, temperature and the damper's states, _core.DAMPER_STATES; default 0).
    At each velocity the direction is that of F(u_max) - F(u_min) (the inverse's bracket); a
    reversal is the largest amount [N] by which F falls back against it over a stretch of u,
    reported when above tolerance_N (default 1e-6 of the largest |F| on the grid, plus 1e-9 N:
    a float model's rounding is not a reversal).
    """
    if n_v < 1 or n_u < 2:
        raise ValueError(f"control_monotonicity: n_v >= 1 and n_u >= 2 (got {n_v}, {n_u})")
    lo_u, hi_u = damper.control_range() if u_range is None else u_range
    lo_v, hi_v = v_range
    if not all(np.isfinite([lo_u, hi_u, lo_v, hi_v])) or hi_u <= lo_u or hi_v < lo_v:
        raise ValueError(f"control_monotonicity: finite ranges with u_max > u_min and v_max >= v_min "
                         f"(u {lo_u, hi_u}, v {lo_v, hi_v})")
    others = dict(others or {})
    unknown = set(others) - set(_QUANTITIES) | ({"u", "v"} & set(others))
    if unknown:
        raise ValueError(f"control_monotonicity: others may set {sorted(set(_QUANTITIES) - {'u', 'v'})}, "
                         f"not {sorted(unknown)}")
    v = np.linspace(lo_v, hi_v, n_v)
    u = np.linspace(lo_u, hi_u, n_u)
    vv, uu = np.meshgrid(v, u, indexing="ij")
    args = {q: float(others.get(q, 0.0)) for q in _QUANTITIES}
    args["v"], args["u"] = vv.ravel(), uu.ravel()
    f, st, _ = damper.forces(**args)
    if np.any(st < 0):
        raise ValueError(f"control_monotonicity: the damper's force failed on the grid (status "
                         f"{int(st[st < 0][0])}): give every input the model reads in `others`")
    f = f.reshape(n_v, n_u)
    tol = 1e-6 * float(np.max(np.abs(f))) + 1e-9 if tolerance_N is None else float(tolerance_N)
    violations = []
    for i in range(n_v):
        row = f[i]
        direction = 1 if row[-1] >= row[0] else -1
        drop, a, b = _reversal(row if direction > 0 else -row)
        if drop > tol:
            violations.append(MonotonicityViolation(v=float(v[i]), u_from=float(u[a]), u_to=float(u[b]),
                                                    force_reversal=drop, direction=direction))
    return MonotonicityReport(v=v, u=u, tolerance_N=tol, violations=violations)


def model_control_monotonicity(model, n_v: int = 101, n_u: int = 201, single: bool = False,
                               others: Mapping[str, float] | None = None,
                               tolerance_N: float | None = None) -> MonotonicityReport:
    """control_monotonicity of an MlpModel's damper (dampnet.damper_from_model) over its envelope:
    v over the model's velocity saturation range [m/s], u over its control's (voltage or current)
    range; the other inputs at `others` (default: 0, or the centre of a feature's range when 0 is
    outside it)."""
    from dampnet.sim.quarter_car.loop import damper_from_model

    feats = list(model.features)
    if "velocity" not in feats:
        raise ValueError("model_control_monotonicity: the model has no velocity input")
    k = feats.index("velocity")
    fields = _core.FEATURE_INPUTS  # feature name -> the dn_damper_input field it reads
    defaults: dict[str, float] = {}
    for i, name in enumerate(feats):
        q = fields.get(name)
        if q and q not in ("v", "u"):
            lo, hi = float(model.sat_lo[i]), float(model.sat_hi[i])
            defaults[q] = 0.0 if lo <= 0.0 <= hi else 0.5 * (lo + hi)
    defaults.update(others or {})
    return control_monotonicity(damper_from_model(model, single=single),
                                (float(model.sat_lo[k]), float(model.sat_hi[k])), n_v=n_v, n_u=n_u,
                                others=defaults, tolerance_N=tolerance_N)
