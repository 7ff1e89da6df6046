"""Track replay on the virtual dyno: the rig plays a drive (a displacement time history, as an MTS
rig plays a drive file) on the truth damper at the drive's control, and records it like a sine.

A Drive holds the damper's stroke x [m] (+ extension) over time, its velocity and acceleration
when known (a quarter car's damper inputs; else differentiated) and the control u [V] the car's
control law applied. `play_drive` records it with the same truth damper, effects and sensors
as `dampnet.rig.generate` (`generate.play`); the test has no frequency (random content).
Where a drive comes from (a quarter car over a road) is dampnet.campaign.replay, a layer above the rig.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dampnet.data.types import RIG_GENERATOR, DataError, Dataset, DynoTest
from dampnet.rig.effects import get_effect
from dampnet.rig.generate import play
from dampnet.rig.sensors import RESOLUTION, SensorNoise, quantise
from dampnet.rig.truth import TruthParams


@dataclass
class Drive:
    """A drive: time [s] (uniform), stroke x [m], control u [V], optional v [m/s] and a [m/s^2]."""

    name: str
    time: np.ndarray
    x: np.ndarray
    u: np.ndarray
    v: np.ndarray | None = None
    a: np.ndarray | None = None
    meta: dict = field(default_factory=dict)

    def check(self) -> None:
        """DataError naming the drive unless its arrays are finite, equal in length, on uniform time."""
        n = len(self.time)
        if n < 10:
            raise DataError(f"drive {self.name}: {n} samples: expected at least 10")
        for k in ("x", "u", "v", "a"):
            arr = getattr(self, k)
            if arr is None:
                continue
            if len(arr) != n:
                raise DataError(f"drive {self.name}: {k} has {len(arr)} samples, time {n}: expected equal lengths")
            if not np.isfinite(arr).all():
                raise DataError(f"drive {self.name}: {k} sample {int(np.argmax(~np.isfinite(arr)))}: expected a finite number")
        d = np.diff(self.time)
        if not (d > 0).all() or np.ptp(d) > 1e-6 * np.mean(d):
            raise DataError(f"drive {self.name}: time: expected uniform, increasing samples (a drive file's rate)")


def play_drive(drive: Drive, effects=(), seed: int = 0, *, params: TruthParams | None = None,
               noise: SensorNoise | None = None, truth_channels: bool = False,
               test_id: str | None = None) -> DynoTest:
    """The rig's recording of `drive` on the truth damper with `effects` (names or Effect objects)."""
    drive.check()
    t = np.asarray(drive.time, dtype=np.float64) - float(drive.time[0])
    x = np.asarray(drive.x, dtype=np.float64)
    v = np.gradient(x, t) if drive.v is None else np.asarray(drive.v, dtype=np.float64)
    a = np.gradient(v, t) if drive.a is None else np.asarray(drive.a, dtype=np.float64)
    effs = [get_effect(e) for e in effects]
    rng = np.random.default_rng([seed, 0])
    u = np.asarray(drive.u, dtype=np.float64)
    levels = sorted({float(np.min(u)), float(np.max(u))})
    for e in effs:
        u = e.control(t, u, levels, rng)
    t0 = None
    for e in effs:
        t0 = e.initial_temperature(rng) if t0 is None else t0
    ch = play(t, x[None], v[None], a[None], u[None], [t0], effs, params or TruthParams(), noise or SensorNoise(),
              [rng], truth_channels)[0]
    meta = {"excitation": "replay", "drive": drive.name, **drive.meta}
    if t0 is not None:
        meta["initial_temperature_c"] = t0
    return DynoTest(test_id=test_id or drive.name, time=quantise(t, RESOLUTION["time"]), channels=ch,
                    frequency_hz=None, amplitude_m=None, control_nominal=_nominal(drive.u),
                    control_name="voltage", meta=meta)


def _nominal(u: np.ndarray) -> float | None:
    """A constant control's level [V]; None for a control law's varying command (no one level)."""
    return float(u[0]) if np.ptp(u) <= 1e-9 else None


def replay_dataset(tests: list[DynoTest], effects=(), seed: int = 0, params: TruthParams | None = None,
                   noise: SensorNoise | None = None, about: dict | None = None) -> Dataset:
    """A dataset of replayed tests with the rig's meta (what `dampnet rig` writes for sines)."""
    from dampnet import __version__

    effs = [get_effect(e) for e in effects]
    noise = noise or SensorNoise()
    p = params or TruthParams()
    meta = {"generator": RIG_GENERATOR, "dampnet_version": __version__,
            "plan": {"name": "replay", "excitation": "replay", "about": dict(about or {})},
            "effects": {e.name: e.params() for e in effs}, "seed": int(seed), "truth_params": p.to_dict(),
            "noise": noise.to_dict(), "resolution": dict(RESOLUTION)}
    return Dataset(tests=tests, source=f"dampnet rig --replay: {', '.join(t.test_id for t in tests)}", meta=meta)
