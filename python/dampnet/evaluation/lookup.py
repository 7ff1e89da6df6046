"""The lookup-table damper model the industry uses (thesis chapter 5.1, Fig. 43), as a baseline.

Fitting (`fit_lookup`): from each sine test, the peak rebound point (peak
positive velocity, peak positive force) and the peak compression point (peak
negative velocity, peak negative force). "Peak" is the 99.5th (0.5th)
percentile of the channel, which on a sine is within 0.012 % of the true
amplitude but averages the sensor noise that a plain max would pick up.
Per voltage the rebound and compression points form one curve (not forced
through (0, 0): the measured force includes the gas preload, and at zero
velocity the curve is the line between the smallest compression and rebound
peaks). The curves are put on one velocity grid (the median peak velocity of
each frequency over voltages, both signs, and 0) by linear interpolation along
each voltage's own points (constant beyond its outermost points). Rebound and compression are therefore separate
halves of the table: negative velocities are compression, positive rebound.

Data (`LookupTable`), the same as the C++ lookup-table damper reads
(`dn_damper_create_table(velocities, n_v, controls, n_u, forces, ...)`):

  velocities  [n_v] m/s, strictly increasing (2..64 points in the C runtime)
  voltages    [n_u] V (or A for current-controlled data), strictly increasing (1..16)
  forces      [n_u][n_v] N, row-major: forces[j][i] is the force at voltages[j], velocities[i]

Evaluation (`LookupTable.force`): bilinear interpolation - linear in velocity,
then linear in voltage - with the query clamped to the grid (constant
extrapolation outside it). An axis with a single point is constant along it.
The thesis's "low damping" and "high damping" tables are the columns at the
lowest and highest voltage (`LookupTable.column`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from dampnet.data import DataError, Dataset, DynoTest
from dampnet.features import FEATURES

PEAK_PERCENTILE = 99.5


@dataclass
class LookupTable:
    """Peak force against peak velocity per control value; see the module docstring."""

    velocities: np.ndarray  # [n_v] m/s, increasing
    voltages: np.ndarray  # [n_u] V, increasing
    forces: np.ndarray  # [n_u, n_v] N (one row per voltage)
    control_name: str = "voltage"

    def __post_init__(self) -> None:
        self.velocities = np.asarray(self.velocities, dtype=np.float64).ravel()
        self.voltages = np.asarray(self.voltages, dtype=np.float64).ravel()
        self.forces = np.asarray(self.forces, dtype=np.float64)
        if self.forces.shape != (self.voltages.size, self.velocities.size):
            raise ValueError(f"forces: expected shape [{self.voltages.size}][{self.velocities.size}] "
                             f"(voltages x velocities), got {list(self.forces.shape)}")
        for name in ("velocities", "voltages"):
            a = getattr(self, name)
            if a.size == 0 or np.any(np.diff(a) <= 0):
                raise ValueError(f"{name}: expected a non-empty, strictly increasing grid")
        if not np.all(np.isfinite(self.forces)):
            raise ValueError("forces: expected finite values")

    # -- evaluation ------------------------------------------------------------
    @staticmethod
    def _bracket(grid: np.ndarray, q: np.ndarray):
        """(lower index, weight of the upper point) with q clamped to the grid."""
        if grid.size == 1:
            return np.zeros(q.shape, dtype=np.intp), np.zeros(q.shape)
        q = np.clip(q, grid[0], grid[-1])
        i = np.clip(np.searchsorted(grid, q, side="right") - 1, 0, grid.size - 2)
        w = (q - grid[i]) / (grid[i + 1] - grid[i])
        return i, w

    def force(self, velocity, voltage) -> np.ndarray:
        """Force [N] at velocity [m/s] and voltage [V] (arrays broadcast), bilinear and clamped."""
        v, u = np.broadcast_arrays(np.asarray(velocity, dtype=np.float64),
                                   np.asarray(voltage, dtype=np.float64))
        i, a = self._bracket(self.velocities, v)
        j, b = self._bracket(self.voltages, u)
        i1 = np.minimum(i + 1, self.velocities.size - 1)
        j1 = np.minimum(j + 1, self.voltages.size - 1)
        F = self.forces
        lo = F[j, i] + a * (F[j, i1] - F[j, i])  # linear in velocity at voltages[j]
        hi = F[j1, i] + a * (F[j1, i1] - F[j1, i])  # ... and at voltages[j + 1]
        return lo + b * (hi - lo)  # then linear in voltage

    def predict_test(self, test: DynoTest) -> np.ndarray:
        """Force [N] of the table along a test's velocity and control channels."""
        try:
            return self.force(test.channels["velocity"], test.control)
        except KeyError as e:
            raise DataError(f"test {test.test_id}: the lookup table needs channel {e.args[0]!r}") from None

    def column(self, voltage: float) -> np.ndarray:
        """Force [N] against self.velocities at one voltage (e.g. the low/high damping curve)."""
        return self.force(self.velocities, np.full(self.velocities.shape, float(voltage)))

    # -- data ------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        return {"format": "dampnet-lookup", "format_version": 1, "control_name": self.control_name,
                "velocities": self.velocities.tolist(), "voltages": self.voltages.tolist(),
                "forces": self.forces.tolist(),
                "units": {"velocities": "m/s", "voltages": FEATURES[self.control_name].unit,
                          "forces": "N"},
                "layout": "forces[j][i]: voltages[j], velocities[i]; bilinear, clamped outside the grid"}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "LookupTable":
        try:
            return cls(d["velocities"], d["voltages"], d["forces"], d.get("control_name", "voltage"))
        except KeyError as e:
            raise ValueError(f"lookup table: missing field {e.args[0]!r}") from None

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=1)


def peak_points(test: DynoTest, percentile: float = PEAK_PERCENTILE):
    """((v_rebound, F_rebound), (v_compression, F_compression)) of one test: its peaks."""
    v = np.asarray(test.channels["velocity"], dtype=np.float64)
    f = np.asarray(test.channels["force"], dtype=np.float64)
    return ((float(np.percentile(v, percentile)), float(np.percentile(f, percentile))),
            (float(np.percentile(v, 100 - percentile)), float(np.percentile(f, 100 - percentile))))


def _merge_grid(values: Sequence[float], rel_tol: float = 0.02) -> list[float]:
    """Sorted values with near-duplicates (within rel_tol of the largest |value|) merged by median."""
    vals = sorted(values)
    if not vals:
        return []
    tol = rel_tol * max(abs(v) for v in vals)
    groups = [[vals[0]]]
    for v in vals[1:]:
        (groups[-1].append(v) if v - groups[-1][-1] <= tol else groups.append([v]))
    return [float(np.median(g)) for g in groups]


def fit_lookup(data: Dataset | Sequence[DynoTest]) -> LookupTable:
    """The lookup table of `data` (sine tests with velocity, force and a nominal control)."""
    tests = list(data.tests if isinstance(data, Dataset) else data)
    tests = [t for t in tests if "velocity" in t.channels and "force" in t.channels]
    if not tests:
        raise DataError("lookup table: no tests with velocity and force channels")
    per_control: dict[float, list[tuple[float, float]]] = {}
    for t in tests:
        u = t.control_nominal
        if u is None:
            u = float(np.median(t.control)) if t.control_name in t.channels else 0.0
        (vr, fr), (vc, fc) = peak_points(t)
        pts = per_control.setdefault(round(float(u), 9), [])
        if vr > 0:
            pts.append((vr, fr))
        if vc < 0:
            pts.append((vc, fc))
    voltages = sorted(per_control)
    # the velocity grid: peaks merged over voltages (they differ by noise only), plus 0
    grid = _merge_grid([v for pts in per_control.values() for v, _ in pts] + [0.0])
    grid = np.array(sorted(set(grid) | {0.0}))
    forces = np.empty((len(voltages), grid.size))
    for j, u in enumerate(voltages):
        pts = sorted(per_control[u])
        pv = np.array([p[0] for p in pts])
        pf = np.array([p[1] for p in pts])
        pv, keep = np.unique(pv, return_index=True)
        forces[j] = np.interp(grid, pv, pf[keep])
    return LookupTable(grid, np.array(voltages), forces, tests[0].control_name)
