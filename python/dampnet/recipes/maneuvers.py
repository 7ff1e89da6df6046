"""The full-vehicle manoeuvres (`dampnet vehicle --test NAME`, a sweep's [fullcar] tests, the
full-car study): one entry each, with its settings (units, defaults), its builder (a
dampnet.sim.full_car.maneuvers.Maneuver), its metrics, its plot and its headline metrics.

The physics stays in dampnet.sim.full_car (maneuvers, metrics, plots); this module is the vocabulary
and the wiring: the CLI's options and help, the sweep's allowed keys and values, the grid's
defaults and the table's metric columns are all read from MANEUVERS and SETTINGS.

Adding a manoeuvre (docs/recipes.md, "Manoeuvres"): `setting(...)` for each new setting, then
`register(ManeuverRecipe(...))`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

from dampnet.sim import limits

# -- settings -------------------------------------------------------------------------------


@dataclass(frozen=True)
class Setting:
    """One setting a manoeuvre's builder takes: `name` (the builder's keyword, the sweep cell's
    column), its `unit` ("" for a word or a count), what it means; its values: `kind` "float"
    (within `range`, or any number > 0 when None), "int" (>= 0), "seed" (a seed,
    dampnet.sim.limits.SEED), "flag" (true or false; an option without a value), "road" (a road
    of dampnet.recipes.roads, as text) or "choice" (one of `choices`, described in messages as
    `choices_text`); its spellings: `cli` (`dampnet vehicle` option),
    `sweep_key` ([fullcar] key; `axis`: a list of values is a grid axis)."""

    name: str
    unit: str
    doc: str
    kind: str = "float"
    range: limits.Range | None = None
    choices: tuple[str, ...] = ()
    choices_text: str = ""
    cli: str = ""
    metavar: str | None = None
    sweep_key: str = ""
    axis: bool = False

    def check(self, value: Any, where: str) -> Any:
        """The value, checked (ValueError naming `where` and what was expected)."""
        if self.kind == "choice":
            if value not in self.choices:
                raise ValueError(f"{where}: expected {self.choices_text or ', '.join(self.choices)}, got {value!r}")
            return value
        if self.kind == "seed":
            return limits.check_seed(where, value)
        if self.kind == "road":
            from dampnet.recipes import roads
            from dampnet.sim.roads import Road

            if isinstance(value, Road):     # a road read already (a sweep cell's CSV input)
                return value
            text = value.strip() if isinstance(value, str) else value
            try:
                if roads.is_profile_file(text):
                    roads.build(text)       # read and checked now, not mid-run
                else:
                    roads.parse(text)
            except ValueError as e:
                raise ValueError(f"{where}: {e}") from None
            return text
        if self.kind == "flag":
            if not isinstance(value, bool):
                raise ValueError(f"{where}: expected true or false, got {value!r}")
            return value
        if self.kind == "int":
            return _int(where, value)
        if self.range is not None:
            return limits.check_number(where, value, self.range)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0 or value == float("inf"):
            raise ValueError(f"{where}: expected a finite number > 0 [{self.unit}], got {value!r}")
        return float(value)

    def text(self) -> str:
        """The setting in words, for help texts: its meaning and unit."""
        return f"{self.doc}" + (f" [{self.unit}]" if self.unit else "")


def _int(where: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise ValueError(f"{where}: expected an integer >= 0, got {value!r}")
    return int(value)


#: every manoeuvre setting by name, in the order the sweep's table shows them
SETTINGS: dict[str, Setting] = {}


def setting(s: Setting) -> Setting:
    """Register a setting (its cli and sweep_key default to the name); refused when the name or a
    spelling is taken by another one."""
    s = Setting(**{**s.__dict__, "cli": s.cli or "--" + s.name.replace("_", "-"), "sweep_key": s.sweep_key or s.name})
    for other in SETTINGS.values():
        if s.name == other.name or s.cli == other.cli or s.sweep_key == other.sweep_key:
            raise ValueError(f"manoeuvre setting {s.name!r} ({s.cli}, {s.sweep_key}): taken by {other.name!r}")
    if s.cli in RESERVED_CLI:
        raise ValueError(f"manoeuvre setting {s.name!r}: {s.cli} is an option of `dampnet vehicle` itself")
    SETTINGS[s.name] = s
    return s


#: `dampnet vehicle`'s own options (a setting may not take one); the sweep's own [fullcar] keys
RESERVED_CLI = ("--test", "--damping", "--dt", "--out", "--force", "--help")
RESERVED_SWEEP = ("models", "tests", "damping", "dt", "objective", "random", "vehicle")

setting(Setting("speed_kmh", "km/h", "forward speed", range=limits.SPEED_KMH, cli="--speed", metavar="KMH",
                sweep_key="speeds_kmh", axis=True))
setting(Setting("mode", "", "all wheels in phase (heave) or the rear against the front (pitch)", kind="choice",
                choices=("heave", "pitch"), choices_text="'heave' or 'pitch'", metavar="{heave,pitch}", sweep_key="modes",
                axis=True))
setting(Setting("road", "", "a road of the road registry (dampnet.recipes.roads: rough, iso:C, bump, ...) or a "
                "CSV distance_m,elevation_m",
                kind="road", metavar="ROAD", sweep_key="roads", axis=True))
setting(Setting("road_seed", "", "seed of the road's random tracks", kind="seed", cli="--seed", metavar="SEED",
                sweep_key="road_seeds", axis=True))
setting(Setting("max_speed", "", "also find the highest speed at which the test passes (bisection on speed "
                "within 40-160 km/h to 0.5 km/h, each run as this one)", kind="flag"))
# the bounce sweep's ranges (issue 49: a 1e9 octave/s sweep ran with nothing in it, acc RMS 0; a
# 1e-6 octave/s one failed allocating 198 GiB): an amplitude up to a four-post rig's actuator
# stroke; frequencies from 0.01 Hz (below the body modes) to 100 Hz (10 steps a cycle at the
# default 1 ms); a rate from 0.01 octave/s (the default 5.3 octaves in 9 minutes) to 10 (in 0.5 s).
# With the span and cycles checked together (_bsst_check), a sweep has something to measure.
setting(Setting("bsst_amplitude_m", "m", "sweep amplitude", range=limits.Range(1e-6, 0.1, "m"),
                cli="--bsst-amplitude", metavar="M"))
setting(Setting("bsst_f0_hz", "Hz", "sweep start frequency", range=limits.Range(0.01, 100.0, "Hz"),
                cli="--bsst-f0", metavar="HZ"))
setting(Setting("bsst_f1_hz", "Hz", "sweep end frequency", range=limits.Range(0.01, 100.0, "Hz"),
                cli="--bsst-f1", metavar="HZ"))
setting(Setting("bsst_rate_oct_s", "octave/s", "sweep rate", range=limits.Range(0.01, 10.0, "octave/s"),
                cli="--bsst-rate", metavar="OCT_S"))


# -- manoeuvres -----------------------------------------------------------------------------


@dataclass(frozen=True)
class ManeuverRecipe:
    """A full-vehicle manoeuvre.

    build(dt [s], vehicle: the full car's fields set (SI; dampnet.sim.full_car.params), **settings) ->
    a dampnet.sim.full_car.maneuvers.Maneuver; metrics(arrays, man, params) -> {metric: value} (units
    in the names); plot(runs, path, title) draws runs (label -> dampnet.sim.full_car.runs.run's result);
    defaults: the settings it takes and their default values; headline: the metrics a summary
    line and the study's table show; columns: every metric it reports as the sweep's table columns
    (a per-wheel list as one column per wheel); objective: what a sweep of this test alone ranks by;
    refuse: why a setting of another test is not one of this test (for the CLI's message); check:
    the settings together (each is within its range already), ValueError naming the options."""

    name: str
    doc: str
    build: Callable[..., Any]
    metrics: Callable[[dict, Any, dict], dict]
    plot: Callable[..., None]
    defaults: dict[str, Any]
    headline: tuple[str, ...]
    columns: tuple[str, ...]
    objective: str
    line: Callable[[dict], str] | None = None
    refuse: dict[str, str] = field(default_factory=dict)
    check: Callable[[dict], None] | None = None

    def summary(self, m: dict) -> str:
        """The one-line result `dampnet vehicle` prints (the headline metrics unless `line`)."""
        if self.line is not None:
            return self.line(m)
        return ", ".join(f"{k} {m[k]:.4g}" if not isinstance(m[k], (int, bool)) else f"{k} {m[k]}"
                         for k in self.headline)


#: every manoeuvre by name, in the order help texts list them
MANEUVERS: dict[str, ManeuverRecipe] = {}


def register(m: ManeuverRecipe) -> ManeuverRecipe:
    """Add a manoeuvre; refused when its name is taken or it names a setting not in SETTINGS."""
    if m.name in MANEUVERS:
        raise ValueError(f"manoeuvre {m.name!r} is already registered")
    unknown = [k for k in m.defaults if k not in SETTINGS]
    if unknown:
        raise ValueError(f"manoeuvre {m.name!r}: setting {unknown[0]!r} is not registered (recipes.maneuvers.setting)")
    for k, v in m.defaults.items():
        SETTINGS[k].check(v, f"manoeuvre {m.name!r} default {k}")
    MANEUVERS[m.name] = m
    return m


def unregister(name: str) -> None:
    """Remove a manoeuvre (a test's own), and the settings no other manoeuvre takes."""
    m = MANEUVERS.pop(name)
    for k in m.defaults:
        if k not in BUILTIN_SETTINGS and not any(k in o.defaults for o in MANEUVERS.values()):
            SETTINGS.pop(k, None)


def get(name: str) -> ManeuverRecipe:
    """The manoeuvre `name` (ValueError listing the registered ones)."""
    try:
        return MANEUVERS[name]
    except KeyError:
        raise ValueError(f"{name!r} is not a full-vehicle test; valid: {', '.join(MANEUVERS)}") from None


def names() -> tuple[str, ...]:
    return tuple(MANEUVERS)


def takes(setting_name: str) -> list[str]:
    """The manoeuvres that take a setting."""
    return [m.name for m in MANEUVERS.values() if setting_name in m.defaults]


def settings_of(name: str, given: dict[str, Any]) -> dict[str, Any]:
    """A manoeuvre's settings: its defaults, with `given` (setting -> value, None: not given) over
    them; ValueError naming a given setting it does not take (and the manoeuvres that do)."""
    m = get(name)
    out = dict(m.defaults)
    for k, v in given.items():
        if v is None:
            continue
        s = SETTINGS[k]
        if k not in m.defaults:
            why = m.refuse.get(k) or f"{name} does not take it (it applies to {', '.join(takes(k)) or 'no test'})"
            raise ValueError(f"{s.cli}: {why}; drop {s.cli}")
        out[k] = s.check(v, s.cli)
    if m.check is not None:
        m.check(out)
    return out


def build(name: str, dt: float, settings: dict[str, Any] | None = None, vehicle: dict | None = None):
    """The manoeuvre's dampnet.sim.full_car.maneuvers.Maneuver at step dt [s] (settings over its
    defaults, checked; vehicle: the full car's fields set). meta["test"] is the manoeuvre's name."""
    m = get(name)
    chosen = settings_of(name, settings or {})
    man = m.build(dt, dict(vehicle or {}), **chosen)
    man.meta["test"] = name
    man.meta["settings"] = {k: getattr(v, "name", v) for k, v in chosen.items()}   # a Road by its name
    return man


def run(spec, man, damping: str = "low", params: dict | None = None) -> dict:
    """dampnet.sim.full_car.runs.run of a built manoeuvre (its metrics: the one its meta["test"] names)."""
    from dampnet.recipes.control_laws import VEHICLE_DAMPING, vehicle_controller
    from dampnet.sim.full_car.runs import run as run_test

    recipe = get(man.meta["test"])
    res = run_test(spec, man, damping, params, metrics=recipe.metrics,
                   controller=vehicle_controller(spec, damping, params), law=VEHICLE_DAMPING[damping])
    if man.meta.get("settings", {}).get("max_speed"):
        found = max_speed(spec, man, damping, params, res["metrics"])
        res["max_speed_runs"] = found.pop("max_speed_runs")
        res["metrics"].update(found)
    return res


#: --max-speed: the bracket searched [km/h] and the bisection's resolution [km/h]
MAX_SPEED_RANGE_KMH = (40.0, 160.0)
MAX_SPEED_TOL_KMH = 0.5


def max_speed(spec, man, damping: str = "low", params: dict | None = None, first: dict | None = None,
              progress: Callable[[str], None] | None = print) -> dict:
    """The highest speed [km/h] at which a pass/fail test (its metrics' "passed") passes, by
    bisection on speed_kmh within MAX_SPEED_RANGE_KMH to MAX_SPEED_TOL_KMH, the test rebuilt at
    each speed with its other settings as in `man` (its meta["settings"]). first: the metrics
    of the run at man's own speed (one run saved). Returns {"max_speed_kmh": the highest
    passing speed found (None: none in the bracket; the bracket's top when that passes),
    "max_speed_fails_kmh": the lowest failing speed tried above it (None: none),
    "max_speed_runs": [[speed, passed, clearance_min_m], ...]} (`run` puts the runs beside the
    metrics). Pass/fail need not be monotonic in speed: the bisection
    finds one edge of a passing region, the one next to the lowest failing speed it tried."""
    from dampnet.recipes.control_laws import vehicle_controller
    from dampnet.sim.full_car.runs import run as run_test

    recipe = get(man.meta["test"])
    settings = {k: v for k, v in man.meta["settings"].items() if k != "max_speed"}
    runs: list[list] = []

    def passes(kmh: float) -> bool:
        if first is not None and abs(kmh - settings["speed_kmh"]) < 1e-9:
            m = first
        else:
            m2 = build(recipe.name, man.dt, {**settings, "speed_kmh": kmh})
            m = run_test(spec, m2, damping, params, metrics=recipe.metrics,
                         controller=vehicle_controller(spec, damping, params))["metrics"]
        runs.append([kmh, bool(m["passed"]), m.get("clearance_min_m")])
        if progress:
            progress(f"  max speed search: {kmh:.2f} km/h {'passes' if m['passed'] else 'fails'}"
                     + (f", smallest cone clearance {100 * m['clearance_min_m']:+.1f} cm"
                        if "clearance_min_m" in m else ""))
        return bool(m["passed"])

    lo, hi = MAX_SPEED_RANGE_KMH
    own = settings.get("speed_kmh")
    lo_ok = None
    if own is not None and lo < own < hi:   # the run at the test's own speed splits the bracket
        if passes(own):
            lo_ok, lo = True, own
        else:
            hi = own
    if lo_ok is None:
        lo_ok = passes(lo)
    if not lo_ok:
        return {"max_speed_kmh": None, "max_speed_fails_kmh": lo, "max_speed_runs": runs}
    if hi == MAX_SPEED_RANGE_KMH[1] and passes(hi):
        return {"max_speed_kmh": hi, "max_speed_fails_kmh": None, "max_speed_runs": runs}
    while hi - lo > MAX_SPEED_TOL_KMH:
        mid = 0.5 * (lo + hi)
        if passes(mid):
            lo = mid
        else:
            hi = mid
    return {"max_speed_kmh": lo, "max_speed_fails_kmh": hi, "max_speed_runs": runs}


def run_study(specs, tests: dict, damping: tuple[str, ...] | None = None, **kw) -> dict:
    """dampnet.sim.full_car.study.run_study with each test's metrics and headline from the registry
    and the controllers from dampnet.recipes.control_laws (damping: its VEHICLE_DAMPING names,
    default the thesis's THESIS_VEHICLE_DAMPING); "laws": each damping setting's law, by its registered name."""
    from dampnet.recipes.control_laws import THESIS_VEHICLE_DAMPING, VEHICLE_DAMPING, vehicle_controller
    from dampnet.sim.full_car.study import run_study as study

    damping = THESIS_VEHICLE_DAMPING if damping is None else tuple(damping)
    out = study(specs, tests, damping, recipes={t: get(man.meta["test"]) for t, man in tests.items()},
                controller=vehicle_controller, **kw)
    out["laws"] = {d: VEHICLE_DAMPING[d] for d in damping}
    return out


def plot(runs: dict, path, title: str = "", test: str | None = None) -> None:
    """The test's plot of runs (label -> run; the test: `test`, or the runs' own)."""
    first = next(iter(runs.values()))
    m = get(test or first["maneuver"]["test"])
    if title:
        m.plot(runs, path, title)
    else:
        m.plot(runs, path)         # the plot's own default title


def metric_columns() -> tuple[str, ...]:
    """Every manoeuvre's metric columns, each once, in registry order."""
    out: list[str] = []
    for m in MANEUVERS.values():
        out += [c for c in m.columns if c not in out]
    return tuple(out)


def default_objective(tests) -> str | None:
    """What a sweep of these tests ranks by when the spec does not say: their common objective,
    or None when they differ."""
    objs = {get(t).objective for t in tests}
    return objs.pop() if len(objs) == 1 else None


# -- the built-in manoeuvres ----------------------------------------------------------------


def _bsst(dt, vehicle, mode, bsst_amplitude_m, bsst_f0_hz, bsst_f1_hz, bsst_rate_oct_s):
    from dampnet.sim.full_car.maneuvers import bsst

    return bsst(dt, mode, amplitude_m=bsst_amplitude_m, f0=bsst_f0_hz, f1=bsst_f1_hz, rate_oct_s=bsst_rate_oct_s)


#: a bounce sweep spans at least this many octaves (a third-octave band, the coarsest analysis
#: band) and holds at least this many cycles, (f1 - f0) / (rate ln 2): less is a pulse, not a
#: sweep, with nothing to measure (19.9999 -> 20 Hz gave every peak None and acc RMS 0; 0.5 ->
#: 0.63 Hz at 10 octave/s is 0.02 cycles). Two cycles is a floor, not a good sweep: the tests'
#: cheap 2 -> 4 Hz at 1 octave/s (2.9 cycles) passes; 10 octave/s over the default 5.3 octaves
#: (2.8 cycles) puts the body peak at 0.52 Hz against the linear model's 0.81 Hz
BSST_MIN_OCTAVES = 1.0 / 3.0
BSST_MIN_CYCLES = 2.0


def _bsst_check(s: dict) -> None:
    import math

    f0, f1, rate = s["bsst_f0_hz"], s["bsst_f1_hz"], s["bsst_rate_oct_s"]
    if f1 < f0 * 2.0 ** BSST_MIN_OCTAVES:
        raise ValueError(f"--bsst-f1 {f1:g} Hz: expected at least a third of an octave above --bsst-f0 "
                         f"{f0:g} Hz (>= {f0 * 2.0 ** BSST_MIN_OCTAVES:.4g} Hz): a narrower sweep leaves nothing "
                         "to measure")
    cycles = (f1 - f0) / (rate * math.log(2.0))
    if cycles < BSST_MIN_CYCLES:
        raise ValueError(f"--bsst-rate {rate:g} octave/s: the sweep {f0:g} -> {f1:g} Hz holds {cycles:.3g} cycles: "
                         f"expected at least {BSST_MIN_CYCLES:g} (a rate <= "
                         f"{(f1 - f0) / (BSST_MIN_CYCLES * math.log(2.0)):.3g} octave/s, or a wider sweep)")


def _dlc(dt, vehicle, speed_kmh, max_speed):
    from dampnet.sim.full_car.maneuvers import dlc

    return dlc(dt, speed_kmh)


def _road(dt, vehicle, speed_kmh, road, road_seed):
    """Two tracks of a road of the road registry: its seed and speed filled from road_seed and
    speed_kmh (a value in the road's text wins); a random road (one that fills its seed) gets a
    right track correlated with the left, mixed with the road at seed + 1; the rear wheels a
    wheelbase later (wrapping on a periodic road). A CSV profile (a path, or the Road read from it)
    is both tracks."""
    from dampnet.recipes import roads
    from dampnet.sim.full_car.maneuvers import rough_road
    from dampnet.sim.full_car.params import wheelbase
    from dampnet.sim.roads import Road

    if isinstance(road, Road) or roads.is_profile_file(road):   # distance_m, elevation_m: both tracks alike
        profile = road if isinstance(road, Road) else roads.build(road)
        return rough_road(profile, dt, speed_kmh, None, False, wheelbase_m=wheelbase(vehicle),
                          name=road if isinstance(road, str) else profile.name)
    req = roads.parse(road)
    p = req.params(seed=road_seed, speed_m_s=speed_kmh / 3.6)
    left = req.kind.build(p)
    other = req.kind.build({**p, "seed": p["seed"] + 1}) if "seed" in p else None
    return rough_road(left, dt, speed_kmh, other, req.kind.periodic, wheelbase_m=wheelbase(vehicle), name=road)


def _lazy(module: str, name: str) -> Callable:
    """A function of a dampnet.sim.full_car module, imported when first called (matplotlib, scipy)."""
    def call(*a, **kw):
        import importlib

        return getattr(importlib.import_module(module), name)(*a, **kw)
    call.__name__ = name
    return call


def _dlc_line(m: dict) -> str:
    return (f"a_y peak {m['a_y_peak_m_s2']:.2f} m/s^2, roll peak {m['roll_peak_deg']:.2f} deg, roll rate peak "
            f"{m['roll_rate_peak_deg_s']:.1f} deg/s, yaw rate peak {m['yaw_rate_peak_deg_s']:.1f} deg/s, "
            f"side-slip peak {m['side_slip_peak_deg']:.2f} deg, cones hit {m['cones_hit']} of {m['cones']} "
            f"({'passed' if m['passed'] else 'failed'}; smallest cone clearance "
            f"{100 * m['clearance_min_m']:+.1f} cm" + ("; the car spun" if m["lost_control"] else "") + ")"
            + _max_speed_text(m))


def _max_speed_text(m: dict) -> str:
    if "max_speed_kmh" not in m:
        return ""
    if m["max_speed_kmh"] is None:
        return f"; fails already at {m['max_speed_fails_kmh']:.0f} km/h"
    if m["max_speed_fails_kmh"] is None:
        return f"; passes up to {m['max_speed_kmh']:.0f} km/h (the search's top) at least"
    return f"; highest pass found at {m['max_speed_kmh']:.1f} km/h (fails at {m['max_speed_fails_kmh']:.1f} km/h)"


def _peak_text(m: dict, key: str) -> str:
    if m[f"{key}_peak_hz"] is None:
        return "outside the sweep"
    return (f"{m[f'{key}_peak_hz']:.2f} Hz x{m[f'{key}_peak_gain']:.3g} (linear model "
            f"{m[f'{key}_peak_hz_linear']:.2f} Hz x{m[f'{key}_peak_gain_linear']:.3g})")


_WHEEL_LOADS = tuple(f"tyre_load_dyn_rms_{w}_n" for w in ("fl", "fr", "rl", "rr"))

register(ManeuverRecipe(
    "bsst", "Bounce Sine Sweep Test: a vertical log sweep under all four wheels at rest on a four-post rig",
    _bsst, _lazy("dampnet.sim.full_car.metrics", "bsst_metrics"), _lazy("dampnet.sim.full_car.plots", "plot_bsst"),
    dict(mode="heave", bsst_amplitude_m=0.005, bsst_f0_hz=0.5, bsst_f1_hz=20.0, bsst_rate_oct_s=0.1),
    ("acc_rms_m_s2", "acc_peak_m_s2", "body_peak_hz", "body_peak_gain", "wheel_hop_peak_hz", "wheel_hop_peak_gain"),
    ("acc_rms_m_s2", "acc_peak_m_s2", "pitch_acc_rms_rad_s2", "body_peak_hz", "body_peak_gain", "body_peak_hz_linear",
     "body_peak_gain_linear", "wheel_hop_peak_hz", "wheel_hop_peak_gain", "wheel_hop_peak_hz_linear",
     "wheel_hop_peak_gain_linear", "tyre_load_min_n"), "acc_rms_m_s2",
    line=lambda m: (f"body peak {_peak_text(m, 'body')}, wheel hop {_peak_text(m, 'wheel_hop')}; body acc RMS "
                    f"{m['acc_rms_m_s2']:.4f} m/s^2, pitch acc RMS {m['pitch_acc_rms_rad_s2']:.3f} rad/s^2"),
    refuse={"speed_kmh": "the bounce sine sweep runs at rest on a four-post rig"}, check=_bsst_check))
register(ManeuverRecipe(
    "dlc", "ISO 3888-1 double lane change driven by the preview driver",
    _dlc, _lazy("dampnet.sim.full_car.metrics", "dlc_metrics"), _lazy("dampnet.sim.full_car.plots", "plot_dlc"),
    dict(speed_kmh=120.0, max_speed=False),
    ("a_y_peak_m_s2", "roll_peak_deg", "roll_rate_peak_deg_s", "yaw_rate_peak_deg_s", "side_slip_peak_deg",
     "cones_hit"),
    ("a_y_peak_m_s2", "a_y_rms_m_s2", "roll_peak_deg", "roll_rms_deg", "roll_rate_peak_deg_s", "roll_rate_rms_deg_s",
     "yaw_rate_peak_deg_s", "yaw_rate_rms_deg_s", "side_slip_peak_deg", "side_slip_rms_deg", "steer_peak_deg",
     "steer_rms_deg", "cones_hit", "cones", "passed", "clearance_min_m", "settle_after_exit_s", "lost_control", "tyre_load_min_n"),
    "roll_peak_deg",
    line=_dlc_line))
register(ManeuverRecipe(
    "road", "two tracks of a road of the road registry (correlated tracks of a random road), the rear wheels a "
    "wheelbase after the front",
    _road, _lazy("dampnet.sim.full_car.metrics", "road_metrics"), _lazy("dampnet.sim.full_car.plots", "plot_road"),
    dict(speed_kmh=60.0, road="rough", road_seed=0),
    ("acc_rms_m_s2", "acc_wk_rms_m_s2", "roll_rate_rms_deg_s"),
    ("acc_rms_m_s2", "acc_wk_rms_m_s2", "roll_rate_rms_deg_s", "pitch_rate_rms_deg_s", *_WHEEL_LOADS,
     "tyre_load_min_n"), "acc_rms_m_s2",
    line=lambda m: (f"body acc RMS {m['acc_rms_m_s2']:.4f} m/s^2, Wk RMS {m['acc_wk_rms_m_s2']:.4f} m/s^2, "
                    f"roll rate RMS {m['roll_rate_rms_deg_s']:.2f} deg/s")))

#: the settings of the built-in manoeuvres (unregister keeps them)
BUILTIN_SETTINGS = tuple(SETTINGS)
