"""The full vehicle's tests (the thesis's chapter 5.2 and a ride road): what the four wheels and
the steering see, sampled at the run's step.

  bsst         Bounce Sine Sweep Test: a vertical log sweep 0.5-20 Hz under all four wheels
               at rest (a four-post rig), in phase ("heave") or front against rear ("pitch").
  dlc          ISO 3888-1 double lane change: the lanes and cones from the vehicle's width, the
               path of least peak lateral acceleration through them (iso3888_path) for the
               runtime's preview driver, at 120 km/h by default; the run goes on DLC_SETTLE_S
               after the exit gate (at least DLC_RUN_OUT_M) so the car settles.
  rough_road   two wheel tracks (left, right) of a road of the road registry (correlated
               tracks of a random road: the thesis's rough road, an ISO 8608 class); the rear
               wheels see the front's road a wheelbase later.

Each returns a Maneuver: road [n, 4] and its rate (FL, FR, RL, RR; row k at t = k dt),
the forward speed [m/s], the steering or the driver's path, and the test's geometry.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from dampnet.sim import limits
from dampnet.sim.full_car.linear import ROAD_PATTERNS
from dampnet.sim.roads import Road, RoadError, sine_sweep

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
BSST_POST_S = 8.0     # rest after the bounce sweep [s]
DLC_RUN_IN_M = 60.0   # straight road before the entry lane: the driver settles
DLC_RUN_OUT_M = 60.0  # straight road after the exit lane, at least (the path straightens within it)
DLC_SETTLE_S = 3.0    # the run goes on this long after the exit gate (or DLC_RUN_OUT_M, the longer)
#: the path keeps the vehicle's body this far inside every cone line [m] (the driver's room; the
#: entry lane leaves 0.22 m a side to the 1.9 m car). 0.1 m: the path's peak curvature 6.3e-3 1/m
#: (3.1 m/s^2 at 80 km/h, 7.0 m/s^2 at 120 km/h); 0: 5.3e-3 1/m (see iso3888_path)
DLC_PATH_MARGIN_M = 0.1
#: the path's curvature changes at most this fast along it [1/m^2]: no curvature step the steering
#: could not follow (costs ~2 % of peak curvature over an unbounded rate)
DLC_PATH_CURVATURE_RATE = 1e-3
#: the path may curve this much more than the least peak curvature to keep further from the cones
DLC_PATH_KAPPA_SLACK = 0.03
DLC_PATH_STEP_M = 1.0  # the path table's spacing [m] (the runtime's table holds at most 256 points)
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
    if mode not in ROAD_PATTERNS:
        raise RoadError(f"bsst mode must be 'heave' or 'pitch', got {mode!r}")
    # 8 s at rest after the sweep: the body modes (~0.7-1 Hz) ring out, so the record holds the
    # whole response and its transform over the road's is the transmissibility (metrics.transmissibility)
    road = sine_sweep(amplitude_m=amplitude_m, f0=f0, f1=f1, rate_oct_s=rate_oct_s, post_s=BSST_POST_S)
    s = road.sample(_step(dt), values_per_step=limits.FULL_CAR_VALUES)
    sign = ROAD_PATTERNS[mode]
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


def iso3888_path(width_m: float = VEHICLE_WIDTH_M, margin_m: float = DLC_PATH_MARGIN_M,
                 step_m: float = DLC_PATH_STEP_M) -> tuple[np.ndarray, np.ndarray]:
    """The driver's path (x, y) [m] through the lanes: the line of least peak curvature (so of
    least peak lateral acceleration U^2 kappa at any speed) keeping the car's width plus margin_m
    inside every cone line, its curvature changing at most DLC_PATH_CURVATURE_RATE per metre;
    straight on the run-in and at the end; then, its peak curvature allowed DLC_PATH_KAPPA_SLACK
    more, the line of the most room to the cone lines (their sum over the lanes' points). A linear programme on y at step_m spacing (curvature
    by second differences; scipy's HiGHS), from DLC_RUN_IN_M before the entry lane to
    DLC_RUN_OUT_M after the exit lane; the run-in and run-out keep the entry's and exit's lane,
    the run-in's first half on the entry lane's centreline (where the car starts).
    The car's body is straight while the path curves: at its ends (2.4 m ahead of the CG,
    2.95 m behind) it lies up to kappa l^2 / 2 = 0.03 m inside the path's offset, within the
    margin. RoadError when no such path exists (a margin too wide for the entry lane)."""
    import scipy.optimize
    import scipy.sparse as sp

    lanes = iso3888_lanes(width_m)
    if not 0.0 <= margin_m < 0.5 * (lanes[0]["width"] - width_m) + 1e-12:
        raise RoadError(f"path margin must be in [0, {0.5 * (lanes[0]['width'] - width_m):.3f}) m for a "
                        f"{width_m} m wide car, got {margin_m}")
    x = np.arange(-DLC_RUN_IN_M, lanes[-1]["x1"] + DLC_RUN_OUT_M + step_m / 2, step_m)
    n = x.size
    half = width_m / 2 + margin_m
    lo, hi = np.full(n, -np.inf), np.full(n, np.inf)
    for k, sec in enumerate(lanes):
        if "y_right" not in sec:
            continue
        inside = (x >= sec["x0"] - 1e-9) & (x <= sec["x1"] + 1e-9)
        if k == 0:
            inside |= x < sec["x0"]
        if k == len(lanes) - 1:
            inside |= x > sec["x1"]
        lo[inside] = np.maximum(lo[inside], sec["y_right"] + half)
        hi[inside] = np.minimum(hi[inside], sec["y_left"] - half)
    start = x <= -DLC_RUN_IN_M / 2   # the run starts on the entry lane's centreline (the runtime's Y = 0)
    lo[start] = hi[start] = lanes[0]["y_centre"]
    # variables: y (n), s (the peak |curvature|); minimise s
    D = sp.diags([np.ones(n - 2), -2 * np.ones(n - 2), np.ones(n - 2)], [0, 1, 2], shape=(n - 2, n)) / step_m**2
    J = (sp.diags([-np.ones(n - 3), np.ones(n - 3)], [0, 1], shape=(n - 3, n - 2)) / step_m) @ D
    one, none = sp.csr_matrix(np.ones((n - 2, 1))), sp.csr_matrix((n - 3, 1))
    A = sp.vstack([sp.hstack([D, -one]), sp.hstack([-D, -one]), sp.hstack([J, none]), sp.hstack([-J, none])])
    b = np.r_[np.zeros(2 * (n - 2)), np.full(2 * (n - 3), DLC_PATH_CURVATURE_RATE)]
    eq = sp.lil_matrix((4, n + 1))
    for row, (i, j) in enumerate(((0, 1), (1, 2), (n - 1, n - 2), (n - 2, n - 3))):  # straight ends
        eq[row, i], eq[row, j] = 1.0, -1.0
    c = np.zeros(n + 1)
    c[n] = 1.0
    bounds = [(a if np.isfinite(a) else None, z if np.isfinite(z) else None) for a, z in zip(lo, hi)]
    res = scipy.optimize.linprog(c, A_ub=A.tocsr(), b_ub=b, A_eq=eq.tocsr(), b_eq=np.zeros(4),
                                 bounds=bounds + [(0.0, None)], method="highs")
    if res.status != 0:
        raise RoadError(f"no path through the ISO 3888-1 lanes for a {width_m} m car with {margin_m} m "
                        f"margin ({res.message})")
    # second: the most room to the cone lines (sum over the lanes' points of the smaller side's
    # room t_k) with the peak curvature at most (1 + DLC_PATH_KAPPA_SLACK) of the least
    cap = res.x[n] * (1.0 + DLC_PATH_KAPPA_SLACK)
    lane = np.flatnonzero(np.isfinite(lo) & np.isfinite(hi) & (x >= lanes[0]["x0"]) & (x <= lanes[-1]["x1"]))
    nt = lane.size
    pick = sp.csr_matrix((np.ones(nt), (np.arange(nt), lane)), shape=(nt, n))
    eye = sp.eye(nt)
    A2 = sp.vstack([sp.hstack([D, sp.csr_matrix((n - 2, nt))]), sp.hstack([-D, sp.csr_matrix((n - 2, nt))]),
                    sp.hstack([J, sp.csr_matrix((n - 3, nt))]), sp.hstack([-J, sp.csr_matrix((n - 3, nt))]),
                    sp.hstack([-pick, eye]), sp.hstack([pick, eye])])
    b2 = np.r_[np.full(2 * (n - 2), cap), np.full(2 * (n - 3), DLC_PATH_CURVATURE_RATE), -lo[lane], hi[lane]]
    eq2 = sp.hstack([eq[:, :n], sp.csr_matrix((4, nt))])
    c2 = np.r_[np.zeros(n), -np.ones(nt)]
    res2 = scipy.optimize.linprog(c2, A_ub=A2.tocsr(), b_ub=b2, A_eq=eq2.tocsr(), b_eq=np.zeros(4),
                                  bounds=bounds + [(0.0, None)] * nt, method="highs")
    return x, np.asarray((res2.x if res2.status == 0 else res.x)[:n])


def path_curvature(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The curvature [1/m] of a path table (second differences; ends 0), at its points."""
    k = np.zeros_like(np.asarray(y, dtype=float))
    h = np.diff(x)
    k[1:-1] = 2 * (h[:-1] * y[2:] - (h[:-1] + h[1:]) * y[1:-1] + h[1:] * y[:-2]) / (h[:-1] * h[1:] * (h[:-1] + h[1:]))
    return k


def dlc(dt: float = 1e-3, speed_kmh: float = 120.0, width_m: float = VEHICLE_WIDTH_M) -> Maneuver:
    """The ISO 3888-1 double lane change on a flat road, driven by the runtime's preview driver
    along iso3888_path; starts DLC_RUN_IN_M before the entry lane (the runtime's x_pos = 0 there,
    meta["start_x_m"] in the lanes' frame), ends DLC_SETTLE_S (at least DLC_RUN_OUT_M) after
    the exit lane."""
    speed = _speed(speed_kmh) / 3.6
    lanes = iso3888_lanes(width_m)
    out = max(DLC_RUN_OUT_M, DLC_SETTLE_S * speed)
    length = DLC_RUN_IN_M + lanes[-1]["x1"] + out
    n = _steps(length, speed, _step(dt), "the lane change")
    x, y = iso3888_path(width_m)
    kappa = float(np.max(np.abs(path_curvature(x, y))))
    # the runtime's X starts at 0 where the run starts: the path in that frame
    x = x + DLC_RUN_IN_M
    meta = dict(test="dlc", standard="ISO 3888-1:2018", speed_kmh=speed_kmh, vehicle_width_m=width_m,
                lanes=lanes, cones=iso3888_cones(width_m).tolist(), start_x_m=-DLC_RUN_IN_M,
                exit_x_m=lanes[-1]["x1"], path_margin_m=DLC_PATH_MARGIN_M, path_kappa_peak_1_m=kappa,
                path_a_y_peak_m_s2=kappa * speed**2, path_x=x.tolist(), path_y=y.tolist())
    return Maneuver("dlc", dt, np.zeros((n, 4)), np.zeros((n, 4)), speed, path=(x, y), meta=meta)


def rough_road(left: Road, dt: float = 1e-3, speed_kmh: float = 60.0, other: Road | None = None,
               periodic: bool = False, wheelbase_m: float = 3.25, coherence: float = TRACK_COHERENCE,
               name: str | None = None) -> Maneuver:
    """Two wheel tracks of a road (any dampnet.sim.roads.Road; the full car's `road` manoeuvre
    builds it from the road registry): left the profile; right = coherence x left +
    sqrt(1 - coherence^2) x `other`, an independent profile of the same spectrum (a random
    road at the next seed; a frequency-independent coherence: a simplification, real tracks are
    less coherent at short wavelengths), or the left profile itself when `other` is None (a bump
    across the lane). The rear wheels see the front's road a wheelbase later: on a `periodic`
    profile the delay wraps to its end, otherwise they start on its first elevation. A temporal
    road (displacement over time) is met by the front wheels at its own times, by the rear
    wheelbase / speed later."""
    if not 0.0 <= coherence <= 1.0:
        raise RoadError(f"track coherence must be in [0, 1], got {coherence}")
    speed = _speed(speed_kmh) / 3.6
    dt = _step(dt)
    name = name or left.name
    if other is None:
        right_z = left.z
    else:
        if other.kind != left.kind or other.x.shape != left.x.shape or np.any(other.x != left.x):
            raise RoadError(f"road {name!r}: the second track must be sampled where the first is")
        right_z = coherence * left.z + math.sqrt(1.0 - coherence**2) * other.z
    spatial = left.kind == "spatial"
    rate = speed if spatial else 1.0      # how fast x advances: m/s over distance, s/s over time
    length = left.length
    n = _steps(length if spatial else length * speed, speed, dt, f"the {name} road")
    t = np.arange(n) * dt
    xf = left.x[0] + rate * t
    delay = wheelbase_m if spatial else wheelbase_m / speed     # the rear's lag in x
    xr = left.x[0] + (np.mod(rate * t - delay, length) if periodic else rate * t - delay)
    cols = [np.interp(xf, left.x, left.z), np.interp(xf, left.x, right_z),
            np.interp(xr, left.x, left.z), np.interp(xr, left.x, right_z)]
    road = np.stack(cols, axis=1)
    road_rate = np.gradient(road, dt, axis=0)
    meta = dict(left.meta, test="road", road=name, speed_kmh=speed_kmh, coherence=coherence if other else 1.0,
                rear_delay_s=wheelbase_m / speed)
    return Maneuver(f"road_{name}", dt, road, road_rate, speed, steer=np.zeros(n), meta=meta)
