"""Track-replay dyno tests: a quarter car's damper stroke over a road, played on the virtual rig.

A modern damper lab validates beyond sines by replaying road-load data: the damper's stroke
recorded (or simulated) on a car over a road is a drive file the dyno plays. Here the stroke
comes from the quarter-car loop (dampnet.sim.quarter_car.runs.loop_arrays, what `dampnet
simulate` runs, over the part of the road replayed) with the rig's truth damper in the car, over a road of the road registry
(dampnet.recipes.roads: iso:C, rough, bump, a CSV profile, ...) at a speed [m/s], under a control
law of the control-law registry (dampnet.recipes.control_laws). The drive - the damper's
x [m], v [m/s], a [m/s^2] and the law's control u [V] at each step - is then played on the
rig (dampnet.rig.replay.play_drive) with its sensors and effects, at the car's step rate
(the rig's 5 kHz by default), so the recording is what a dyno would measure.

    drive = road_drive("iso:C", speed_m_s=20, law="skyhook_onoff", duration_s=4)
    test = play_drive(drive, effects=["gas_spring"], seed=0)

A full-car corner instead (`corner_drive`, `dampnet rig --replay ROAD --corner fl`): the full
vehicle (the `road` manoeuvre of dampnet.recipes.maneuvers over the same registry's road: two
tracks, correlated for a random road, the rear a wheelbase later) with the truth damper at each
corner, under its damping setting (low, high, skyhook), and the stroke of the corner asked for.
"""

from __future__ import annotations

import numpy as np

from dampnet.rig.plans import RATE_HZ  # the rig's sample rate [Hz]: the drive is upsampled to it
from dampnet.rig.replay import Drive, play_drive, replay_dataset
from dampnet.sim.full_car.runs import CORNERS  # the full vehicle's corners, in the runtime's order

#: the quarter car's step [s] (the loop's default)
CAR_DT_S = 1e-3
#: default replay length [s] (a rig test, not a whole road)
DURATION_S = 6.0
#: default speed [m/s] over a spatial road (the thesis's rough road at 20 m/s, as plan-tests runs it)
SPEED_M_S = 20.0
#: seconds at the start of a run dropped from the drive: the car settles from rest onto the road
SETTLE_S = 0.5


def _check_run(speed_m_s, duration_s, rate_hz) -> None:
    """The speed, duration and rate of a replay (quarter car or full-car corner): ValueError if any
    is out of range."""
    if not (isinstance(speed_m_s, (int, float)) and 0 < speed_m_s <= 100):
        raise ValueError(f"replay: speed {speed_m_s!r}: expected a speed in (0, 100] m/s")
    if not (isinstance(duration_s, (int, float)) and 0.1 <= duration_s <= 600):
        raise ValueError(f"replay: duration {duration_s!r}: expected 0.1 to 600 s")
    if not (isinstance(rate_hz, (int, float)) and 100 <= rate_hz <= 20000):
        raise ValueError(f"replay: rate {rate_hz!r}: expected 100 to 20000 Hz")


def road_drive(road: str = "rough", speed_m_s: float = SPEED_M_S, law: str = "passive",
               effects=(), seed: int = 0, duration_s: float = DURATION_S, rate_hz: float = RATE_HZ,
               damping: str = "high") -> Drive:
    """The damper's stroke and control of a quarter car (truth damper with `effects`) over `road`
    (a road registry name or CSV path) at `speed_m_s` [m/s] under control law `law`; the first
    SETTLE_S dropped, then `duration_s` [s] kept (less if the road is shorter)."""
    from dampnet.recipes import control_laws as laws
    from dampnet.recipes import roads
    from dampnet.sim.dampers import truth_spec
    from dampnet.sim.quarter_car.runs import loop_arrays
    from dampnet.sim.vehicle import Vehicle

    _check_run(speed_m_s, duration_s, rate_hz)
    spec = truth_spec(list(effects))
    veh = Vehicle(dt=CAR_DT_S)
    veh.validate()
    ctrl = laws.make(law, spec, veh, damping=damping)
    r = roads.build(road, seed=seed, speed_m_s=speed_m_s)
    spatial = r.kind == "spatial"
    s = r.sample(veh.dt, speed_m_s if spatial else None)
    n = min(len(s.z), int(round((SETTLE_S + duration_s) / CAR_DT_S)) + 2)   # only the part replayed is simulated
    car, _ = loop_arrays(spec, s.z[:n], s.zdot[:n], veh, ctrl)
    k0 = int(round(SETTLE_S / CAR_DT_S))
    if len(car["t"]) - k0 < 10:
        raise ValueError(f"replay: road {road!r}" + (f" at {speed_m_s:g} m/s" if spatial else "")
                         + f" lasts {len(s.z) * CAR_DT_S:.2f} s: expected more than the {SETTLE_S:g} s the car "
                         "settles")
    a = upsample({k: np.asarray(car[k][k0:]) for k in ("t", "x", "v", "u")}, rate_hz)
    name = _drive_name(road, speed_m_s if spatial else None, law)
    about = {"road": r.name, "road_text": road, "speed_m_s": speed_m_s if spatial else None,
             "control_law": laws.get(law).name,   # by its registered name
             "rate_hz": rate_hz, "settle_s": SETTLE_S, "seed": int(seed),
             "car_dt_s": CAR_DT_S, "stroke_rms_m": float(np.sqrt(np.mean(a["x"] ** 2))),
             "velocity_rms_m_s": float(np.sqrt(np.mean(a["v"] ** 2)))}
    return Drive(name=name, time=a["t"], x=a["x"], v=a["v"], a=a["a"], u=a["u"], meta=about)


def upsample(car: dict[str, np.ndarray], rate_hz: float) -> dict[str, np.ndarray]:
    """The car's t, x, v, u (one row per car step) at `rate_hz`, time from 0: x, v, a from the cubic
    Hermite spline through (x, v); u held over each step."""
    from scipy.interpolate import CubicHermiteSpline

    t = car["t"] - car["t"][0]
    spline = CubicHermiteSpline(t, car["x"], car["v"])
    tr = np.arange(int(np.floor(t[-1] * rate_hz + 1e-9)) + 1) / rate_hz
    steps = tr * (len(t) - 1) / t[-1]   # in car steps (uniform); rounding kept off the step edges
    k = np.minimum(np.floor(steps + 1e-6).astype(int), len(t) - 1)
    return {"t": tr, "x": spline(tr), "v": spline(tr, 1), "a": spline(tr, 2), "u": car["u"][k]}


def vehicle_damping(law: str) -> str:
    """The full vehicle's damping setting (recipes.control_laws.VEHICLE_DAMPING: low, high, skyhook)
    for `law`, given as a setting or as its law's name (passive: high, as the quarter car's)."""
    from dampnet.recipes.control_laws import VEHICLE_DAMPING

    if law in VEHICLE_DAMPING:
        return law
    by_law = {v: k for k, v in VEHICLE_DAMPING.items()}
    if law in by_law:
        return by_law[law]
    if law == "passive":
        return "high"
    raise ValueError(f"replay: control {law!r}: the full vehicle runs {', '.join(VEHICLE_DAMPING)} "
                     f"(or the laws {', '.join(VEHICLE_DAMPING.values())})")


def corner_drive(road: str = "rough", speed_m_s: float = SPEED_M_S, law: str = "skyhook", corner: str = "fl",
                 effects=(), seed: int = 0, duration_s: float = DURATION_S, rate_hz: float = RATE_HZ) -> Drive:
    """The damper stroke and control of one corner of the full vehicle (the truth damper with
    `effects` at all four corners; two correlated tracks of the road, the rear a wheelbase later:
    the `road` manoeuvre of recipes.maneuvers) at `speed_m_s`, damping setting or law `law`."""
    import dataclasses

    from dampnet.recipes import maneuvers
    from dampnet.recipes.control_laws import VEHICLE_DAMPING
    from dampnet.sim.dampers import truth_spec

    if corner not in CORNERS:
        raise ValueError(f"replay: corner {corner!r}: expected one of {', '.join(CORNERS)}")
    _check_run(speed_m_s, duration_s, rate_hz)
    damping = vehicle_damping(law)
    try:
        man = maneuvers.build("road", CAR_DT_S, {"speed_kmh": 3.6 * speed_m_s, "road": road, "road_seed": seed})
    except ValueError as e:
        raise ValueError(f"replay: {e}") from None
    n = min(man.road.shape[0], int(round((SETTLE_S + duration_s) / CAR_DT_S)) + 2)
    if n - int(round(SETTLE_S / CAR_DT_S)) < 10:
        raise ValueError(f"replay: road {road!r} at {speed_m_s:g} m/s lasts {man.road.shape[0] * CAR_DT_S:.2f} s for "
                         f"the full car: expected more than the {SETTLE_S:g} s the car settles")
    man = dataclasses.replace(man, road=man.road[:n], road_rate=man.road_rate[:n], steer=man.steer[:n])
    arr = maneuvers.run(truth_spec(list(effects)), man, damping)["arrays"]
    k0, j = int(round(SETTLE_S / CAR_DT_S)), CORNERS.index(corner)
    a = upsample({"t": np.asarray(arr["t"][k0:]), "x": np.asarray(arr["x"][k0:, j]), "v": np.asarray(arr["v"][k0:, j]),
                  "u": np.asarray(arr["u"][k0:, j])}, rate_hz)
    name = _drive_name(road, speed_m_s, f"{damping}-{corner}")
    about = {"road": f"{man.name} ({road})", "road_text": road, "speed_m_s": speed_m_s,
             "control_law": VEHICLE_DAMPING[damping], "damping": damping,
             "vehicle": "full car", "corner": corner, "rate_hz": rate_hz, "settle_s": SETTLE_S, "seed": int(seed),
             "car_dt_s": CAR_DT_S, "stroke_rms_m": float(np.sqrt(np.mean(a["x"] ** 2))),
             "velocity_rms_m_s": float(np.sqrt(np.mean(a["v"] ** 2)))}
    return Drive(name=name, time=a["t"], x=a["x"], v=a["v"], a=a["a"], u=a["u"], meta=about)


def _drive_name(road: str, speed: float | None, law: str) -> str:
    import re

    base = re.sub(r"[^A-Za-z0-9]+", "-", road.split("/")[-1]).strip("-") or "road"
    return f"replay-{base}" + (f"-{speed:g}mps" if speed else "") + f"-{law}".replace(".", "p")


def replay_tests(roads_: list[str], speed_m_s: float = SPEED_M_S, law: str = "passive", effects=(), seed: int = 0,
                 duration_s: float = DURATION_S, rate_hz: float = RATE_HZ, damping: str = "high",
                 truth_channels: bool = False, corner: str | None = None):
    """A rig dataset of one replay test per road (the same car, law, speed and rig effects); with
    `corner` (fl, fr, rl, rr) the stroke of that corner of the full vehicle instead of the quarter car."""
    tests = []
    for i, road in enumerate(roads_):
        if corner is None:
            drive = road_drive(road, speed_m_s, law, effects, seed + i, duration_s, rate_hz, damping)
        else:
            drive = corner_drive(road, speed_m_s, law, corner, effects, seed + i, duration_s, rate_hz)
        tests.append(play_drive(drive, effects, seed + i, truth_channels=truth_channels))
    ids = [t.test_id for t in tests]
    if len(set(ids)) != len(ids):
        raise ValueError(f"replay: roads {roads_}: each road once")
    return replay_dataset(tests, effects, seed, about={"roads": list(roads_), "speed_m_s": speed_m_s,
                                                       "control_law": law, "duration_s": duration_s,
                                                       "vehicle": "quarter car" if corner is None else
                                                       f"full car, corner {corner}"})
