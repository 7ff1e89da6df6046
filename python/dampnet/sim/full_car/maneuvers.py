"""The full vehicle's tests (the thesis's chapter 5.2 and a ride road): what the four wheels and
the steering see, sampled at the run's step.

  bsst         Bounce Sine Sweep Test: a vertical log sweep 0.5-20 Hz under all four wheels
               at rest (a four-post rig), in phase ("heave") or front against rear ("pitch").
  dlc          ISO 3888-1 double lane change: the lanes and cones from the vehicle's width, a
               centreline path for the runtime's preview driver, at 120 km/h by default.
  rough_road   two correlated wheel tracks (left, right) of the thesis's rough road or an ISO
               8608 class; the rear wheels see the front's road a wheelbase later.

Each returns a Maneuver: road [n, 4] and its rate (FL, FR, RL, RR; row k at t = k dt),
the forward speed [m/s], the steering or the driver's path, and the test's geometry.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from dampnet.sim import limits
from dampnet.sim.roads import RoadError, iso8608, sine_sweep, thesis_rough_road

#: ISO 3888-1:2018 lane change: (section, length [m], lane width as (factor, add) of the
#: vehicle width w: width = factor w + add, or None for a transition section)
ISO3888_SECTIONS = (("entry lane", 15.0, (1.1, 0.25)), ("lane change", 30.0, None),
                    ("offset lane", 25.0, (1.0, 1.0)), ("lane change back", 25.0, None),
                    ("exit lane", 15.0, (1.3, 0.25)))
#: lateral offset of the offset lane: its right-hand cone line lies this far left of the entry
#: lane's [m]
ISO3888_OFFSET_M = 3.5
#: a compact pickup's overall width, and overhangs ahead of the front / behind the rear axle [m]
VEHICLE_WIDTH_M = 1.9
OVERHANG_FRONT_M = 0.9
OVERHANG_REAR_M = 1.2
DLC_RUN_IN_M = 60.0   # straight road before the entry lane: the driver settles
DLC_RUN_OUT_M = 60.0
CONES_PER_LINE = 5     # cones on each lane line of each lane section, ends included
TRACK_COHERENCE = 0.6  # correlation of the left and right wheel tracks (a constant: see rough_road)


def _speed(speed_kmh: float) -> float:
    """A test's speed [km/h] within dampnet.sim.limits.SPEED_KMH (RoadError otherwise)."""
    try:
        return limits.check_number("speed", speed_kmh, limits.SPEED_KMH)
    except ValueError as e:
        raise RoadError(str(e)) from None


def _step(dt: float) -> float:
    """A test's step [s]: > 0 and at most the runtime's 0.1 s (RoadError otherwise)."""
    try:
        return limits.check_number("dt", dt, limits.Range(0.0, 0.1, "s", lo_open=True))
    except ValueError as e:
        raise RoadError(str(e)) from None


def _steps(length_m: float, speed_m_s: float, dt: float, what: str) -> int:
    """Steps of a run over length_m at speed_m_s (+1: both ends), within the run size limit."""
    try:
        limits.check_run_size(length_m / speed_m_s / dt + 1.0, limits.FULL_CAR_VALUES,
                              f"{what} ({length_m:.6g} m at {speed_m_s * 3.6:.6g} km/h) in steps of "
                              f"dt = {dt:.6g} s", "raise the speed or the step (--speed, --dt)")
    except ValueError as e:
        raise RoadError(str(e)) from None
    return int(length_m / speed_m_s / dt) + 1


@dataclass
class Maneuver:
    """A test's inputs: road [m] and rate [m/s] under FL, FR, RL, RR at t = k dt, the forward
    speed [m/s], the open-loop steer [rad] (or None) or the driver's path (x, y) [m]."""

    name: str
    dt: float
    road: np.ndarray
    road_rate: np.ndarray
    speed: float
    steer: np.ndarray | None = None
    path: tuple[np.ndarray, np.ndarray] | None = None
    meta: dict = field(default_factory=dict)

    @property
    def t(self) -> np.ndarray:
        return np.arange(self.road.shape[0]) * self.dt


def bsst(dt: float = 1e-3, mode: str = "heave", amplitude_m: float = 0.005, f0: float = 0.5,
         f1: float = 20.0, rate_oct_s: float = 0.1) -> Maneuver:
    """The bounce sine sweep at rest: the quarter car's sweep (dampnet.sim.roads.sine_sweep)
    under all four wheels, in phase (mode "heave") or the rear against the front ("pitch")."""
    if mode not in ("heave", "pitch"):
        raise RoadError(f"bsst mode must be 'heave' or 'pitch', got {mode!r}")
    road = sine_sweep(amplitude_m=amplitude_m, f0=f0, f1=f1, rate_oct_s=rate_oct_s)
    s = road.sample(_step(dt), values_per_step=limits.FULL_CAR_VALUES)
    sign = np.array([1.0, 1.0, 1.0, 1.0]) if mode == "heave" else np.array([1.0, 1.0, -1.0, -1.0])
    meta = dict(road.meta, test="bsst", mode=mode)
    return Maneuver(f"bsst_{mode}", dt, np.outer(s.z, sign), np.outer(s.zdot, sign), 0.0,
                    steer=np.zeros(s.t.size), meta=meta)


def iso3888_lanes(width_m: float = VEHICLE_WIDTH_M) -> list[dict]:
    """The lane sections: start and end x [m] (0 = the entry lane's start), and for the lane
    sections their right and left cone lines y [m] (left positive)."""
    if not width_m > 0:
        raise RoadError(f"vehicle width must be > 0 m, got {width_m}")
    out, x = [], 0.0
    entry_width = 1.1 * width_m + 0.25
    right_entry = -entry_width / 2
    for name, length, rule in ISO3888_SECTIONS:
        sec = dict(name=name, x0=x, x1=x + length)
        if rule is not None:
            w = rule[0] * width_m + rule[1]
            right = right_entry + (ISO3888_OFFSET_M if name == "offset lane" else 0.0)
            sec.update(width=w, y_right=right, y_left=right + w, y_centre=right + w / 2)
        out.append(sec)
        x += length
    return out


def iso3888_cones(width_m: float = VEHICLE_WIDTH_M) -> np.ndarray:
    """The cones' positions [m], rows (x, y): CONES_PER_LINE on each line of each lane."""
    rows = []
    for sec in iso3888_lanes(width_m):
        if "y_right" not in sec:
            continue
        for y in (sec["y_right"], sec["y_left"]):
            for x in np.linspace(sec["x0"], sec["x1"], CONES_PER_LINE):
                rows.append((x, y))
    return np.array(rows)


def iso3888_path(width_m: float = VEHICLE_WIDTH_M, points: int = 240) -> tuple[np.ndarray, np.ndarray]:
    """The driver's path: each lane's centreline, joined across the lane changes by half-cosine
    ramps; from the run-in to the run-out (at most 256 points, the runtime's limit)."""
    lanes = iso3888_lanes(width_m)
    x = np.linspace(-DLC_RUN_IN_M, lanes[-1]["x1"] + DLC_RUN_OUT_M, points)
    y = np.full(x.shape, lanes[0]["y_centre"])
    for k in (1, 3):  # the transitions
        a, b = lanes[k - 1]["y_centre"], lanes[k + 1]["y_centre"]
        x0, x1 = lanes[k]["x0"], lanes[k]["x1"]
        ramp = np.clip((x - x0) / (x1 - x0), 0.0, 1.0)
        y = np.where(x >= x0, a + (b - a) * 0.5 * (1 - np.cos(np.pi * ramp)), y)
    y = np.where(x > lanes[4]["x0"], lanes[4]["y_centre"], y)
    return x, y


def dlc(dt: float = 1e-3, speed_kmh: float = 120.0, width_m: float = VEHICLE_WIDTH_M) -> Maneuver:
    """The ISO 3888-1 double lane change on a flat road, driven by the runtime's preview driver
    along iso3888_path; starts DLC_RUN_IN_M before the entry lane (the runtime's x_pos = 0 there,
    meta["start_x_m"] in the lanes' frame), ends half of DLC_RUN_OUT_M after it."""
    speed = _speed(speed_kmh) / 3.6
    lanes = iso3888_lanes(width_m)
    length = DLC_RUN_IN_M + lanes[-1]["x1"] + DLC_RUN_OUT_M * 0.5
    n = _steps(length, speed, _step(dt), "the lane change")
    x, y = iso3888_path(width_m)
    # the runtime's X starts at 0 where the run starts: the path in that frame
    x = x + DLC_RUN_IN_M
    meta = dict(test="dlc", standard="ISO 3888-1:2018", speed_kmh=speed_kmh, vehicle_width_m=width_m,
                lanes=lanes, cones=iso3888_cones(width_m).tolist(), start_x_m=-DLC_RUN_IN_M)
    return Maneuver("dlc", dt, np.zeros((n, 4)), np.zeros((n, 4)), speed, path=(x, y), meta=meta)


def rough_road(dt: float = 1e-3, speed_kmh: float = 60.0, profile: str = "thesis", seed: int = 0,
               wheelbase_m: float = 3.25, coherence: float = TRACK_COHERENCE) -> Maneuver:
    """Two wheel tracks of a rough road: left the profile (the thesis's rough road, or an ISO
    8608 class "A".."H"), right = coherence x left + sqrt(1 - coherence^2) x an independent
    profile of the same spectrum (a frequency-independent coherence: a simplification, real
    tracks are less coherent at short wavelengths). The rear wheels see the front's road a
    wheelbase later (the profiles are periodic, so the delay wraps)."""
    if not 0.0 <= coherence <= 1.0:
        raise RoadError(f"track coherence must be in [0, 1], got {coherence}")
    speed = _speed(speed_kmh) / 3.6
    dt = _step(dt)
    make = (lambda s: thesis_rough_road(seed=s)) if profile == "thesis" else (lambda s: iso8608(profile, seed=s))
    left, other = make(seed), make(seed + 1)
    right_z = coherence * left.z + math.sqrt(1.0 - coherence**2) * other.z
    length = left.length
    n = _steps(length, speed, dt, f"the {profile} road")
    t = np.arange(n) * dt
    xf = left.x[0] + speed * t
    xr = left.x[0] + np.mod(speed * t - wheelbase_m, length)
    cols = [np.interp(xf, left.x, left.z), np.interp(xf, left.x, right_z),
            np.interp(xr, left.x, left.z), np.interp(xr, left.x, right_z)]
    road = np.stack(cols, axis=1)
    rate = np.gradient(road, dt, axis=0)
    meta = dict(left.meta, test="road", profile=profile, speed_kmh=speed_kmh, coherence=coherence,
                rear_delay_s=wheelbase_m / speed)
    return Maneuver(f"road_{profile}", dt, road, rate, speed, steer=np.zeros(n), meta=meta)
