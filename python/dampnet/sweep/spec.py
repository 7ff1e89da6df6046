"""The sweep's SPEC.toml: what it may say, read and checked into a `Spec` (one-line errors).

    spec = load_spec("sweep.toml")        # or parse_spec(dict_or_toml_text, source=..., base=...)

A spec has up to four tables:

  [sweep]       data = "shared" | "ship" (how workers get datasets and models: by path on a
                shared filesystem, or shipped once per worker), allowed_failures (deaths of a
                worker under one cell before it is given up, embedded cluster; default 3)
  [training]    axes (a list: one value per item, every combination of the axes is a cell; a
                single value: a one-value axis) over datasets, data_seeds, rig_effects,
                algorithms, add, features, seeds, hidden, decimate, max_epochs, max_fail,
                holdout_voltage, activation, restarts (a number or "auto"; default 1), average,
                restart_score (a cell is a dampnet.recipes.training.TrainingRequest, trained as
                `dampnet train` trains); objective (the metric the summary ranks, lower is
                better). Where a value is itself a list, the axis is a list of them:
                hidden = [30, [20, 10]], rig_effects = [[], ["gas_spring", "thermal"]],
                features = [["velocity", "acceleration", "voltage", "displacement"]]
  [simulation]  models, roads, road_seeds, road_length_m, speeds [m/s], controllers (roads and
                controllers by name: dampnet.recipes.roads, dampnet.recipes.control_laws);
                [simulation.vehicle] and [simulation.controller]: the quarter car's and the
                control law's fields (a value or a list); objective
  [fullcar]     full-vehicle cells (dampnet.sim.full_car.runs.run, as `dampnet vehicle`): models (as
                [simulation]), tests (dampnet.recipes.maneuvers: bsst, dlc, road), damping (low, high, skyhook: every
                corner), speeds_kmh [km/h] (dlc, road; default the test's: 120, 60), modes
                (bsst: heave, pitch), roads (road: the road registry's, dampnet.recipes.roads:
                rough, iso:C, bump, ...; the old profiles key is refused naming it), road_seeds (road), dt [s], bsst_amplitude_m, bsst_f0_hz, bsst_f1_hz,
                bsst_rate_oct_s (the bounce sweep); [fullcar.vehicle]: the full car's fields
                (dampnet._core.FULLCAR_FIELDS, SI; enums by name: tyre_model, damper_eval,
                accel_feature) except those the test sets (speed, dt, steer_mode, f_static_f,
                f_static_r); objective (default: the tests' own when they share one, roll_peak_deg for
                dlc, acc_rms_m_s2 for bsst and road; else acc_rms_m_s2). A test's settings and
                their defaults are its entry's in dampnet.recipes.maneuvers; another test's are empty.
                E.g. [fullcar] models = ["default", "truth"], tests = ["dlc", "bsst"],
                damping = ["low", "skyhook"] and [fullcar.vehicle] m_s = [2400.0, 2800.0]: 16 cells

`[training.random]` / `[simulation.random]` / `[fullcar.random]`: n samples drawn with `seed`
(numpy's default_rng), each parameter named by its cell name or its key (speed or speeds,
road_seed, vehicle.m_s as m_s in a [simulation.random.vehicle] or [fullcar.random.vehicle]
table; the training seed as seeds = {...}, since `seed` there is the draws' own) with one
distribution: {uniform = [lo, hi]}, {loguniform = [lo, hi]}, {normal = [mean, sd]}, {integers = [lo, hi]} (both ends included)
or {choice = [...]}. Every grid point is combined with every sample (the same n samples for
each point: Monte Carlo over parameter spreads, compared on common draws). A distribution's
numbers are finite, its ends (a normal's mean) valid values of the parameter, and every sample
is checked as a value of the parameter (dampnet.sweep.grid).

Training values are checked where every training front end checks them
(dampnet.training.settings: seeds, hidden sizes up to the runtime's limit, max_epochs,
max_fail, decimate, holdout_voltage, the feature count), so a bad one is refused when the spec
is read, not in every cell.

Relative paths are relative to the spec file's directory (to the working directory for a
spec given as a dict). Errors are `SpecError` (a ValueError): one line naming the file, the
line where the key is when it can be found, and the field, e.g.
`sweep.toml: line 7: training.algorithms[1]: 'foo' is not a training algorithm; valid: ...`.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from dampnet.schema import parse_toml
from dampnet.sim import limits
from dampnet.sweep.metrics import objectives

DATA_MODES = ("shared", "ship")
DISTRIBUTIONS = ("uniform", "loguniform", "normal", "integers", "choice")
DEFAULT_OBJECTIVE = {"training": "holdout_nrmse", "simulation": "acc_wk_rms_m_s2", "fullcar": "acc_rms_m_s2"}
#: the sections (tables) that make cells, in the table's order
KINDS = ("training", "simulation", "fullcar")
#: full-vehicle damping settings (dampnet vehicle --damping); the tests and their settings:
#: dampnet.recipes.maneuvers (read when a spec is parsed: `fullcar_params`)
#: full-car fields a cell sets from its test (not [fullcar.vehicle] keys): why, for the error
FULLCAR_SET_BY_TEST = {
    "speed": "set by the test: use [fullcar] speeds_kmh [km/h]",
    "dt": "set by the test: use [fullcar] dt [s]",
    "steer_mode": "set by the test (the preview driver for dlc, open loop otherwise)",
    "f_static_f": "set per cell: the damper's force at rest",
    "f_static_r": "set per cell: the damper's force at rest",
}


class SpecError(ValueError):
    """A bad sweep spec: one line naming the file, the line and the field."""


class _Bad(ValueError):
    """A bad value (message without the location); turned into a SpecError by the parser."""


#: the most characters of a value (or key) an error message repeats
SHOW_CHARS = 80


def _show(v: Any) -> str:
    """A value as an error message repeats it: its repr, cut to SHOW_CHARS."""
    text = repr(v)
    return text if len(text) <= SHOW_CHARS else text[:SHOW_CHARS - 3] + "..."


# -- values -----------------------------------------------------------------------------------

def _int(lo: int | None = None) -> Callable[[Any], int]:
    def norm(v):
        if isinstance(v, bool) or not isinstance(v, int):
            raise _Bad(f"expected an integer, got {_show(v)}")
        if lo is not None and v < lo:
            raise _Bad(f"expected an integer >= {lo}, got {v}")
        return int(v)
    return norm


def _float(positive: bool = False, allow_none: str | None = None) -> Callable[[Any], float | None]:
    def norm(v):
        if allow_none is not None and isinstance(v, str) and v.strip().lower() == allow_none:
            return None
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            extra = f" or {_show(allow_none)}" if allow_none else ""
            raise _Bad(f"expected a number{extra}, got {_show(v)}")
        if positive and v <= 0:
            raise _Bad(f"expected a number > 0, got {_show(v)}")
        return float(v)
    return norm


def _flag(v):
    if not isinstance(v, bool):
        raise _Bad(f"expected true or false, got {_show(v)}")
    return v


def _choice(valid: tuple[str, ...] | Callable[[], tuple[str, ...]], what: str) -> Callable[[Any], str]:
    def norm(v):
        names = valid() if callable(valid) else valid
        if not isinstance(v, str) or v not in names:
            raise _Bad(f"{_show(v)} is not {what}; valid: {', '.join(names)}")
        return v
    return norm


def _road(v) -> str:
    """A road: a name of the road registry (dampnet.recipes.roads) or a CSV distance profile, an
    input of the cell (checked by check_input; a CSV's content is in the cell's key)."""
    if not isinstance(v, str):
        raise _Bad(f"expected a road name or a CSV file, got {_show(v)}")
    return v.strip()


def _text(v) -> str:
    if not isinstance(v, str) or not v.strip():
        raise _Bad(f"expected a non-empty string, got {_show(v)}")
    return v.strip()


def _effects(v) -> list[str]:
    """An effect id, a list of them, or "none" / "" / []: none."""
    from dampnet.effects import CATALOGUE

    items = [] if v in ("none", "") else [v] if isinstance(v, str) else v
    if not isinstance(items, list) or not all(isinstance(e, str) for e in items):
        raise _Bad(f"expected an effect id, a list of them or 'none', got {_show(v)}")
    for e in items:
        if e not in CATALOGUE:
            raise _Bad(f"{_show(e)} is not an effect; valid: {', '.join(CATALOGUE)}")
    out: list[str] = []
    for e in items:
        if e not in out:
            out.append(e)
    return out


def _hidden(v) -> list[int]:
    """30, [20, 10] or "20-10": the hidden layer sizes."""
    items = v
    if isinstance(v, str):
        try:
            items = [int(s) for s in re.split(r"[-,x ]+", v.strip()) if s]
        except ValueError:
            raise _Bad(f"expected hidden sizes like 30, [20, 10] or '20-10', got {_show(v)}") from None
    elif isinstance(v, int) and not isinstance(v, bool):
        items = [v]
    if (not isinstance(items, list) or not 1 <= len(items) <= 2
            or not all(isinstance(h, int) and not isinstance(h, bool) and h >= 1 for h in items)):
        raise _Bad(f"expected one or two hidden layer sizes >= 1 (30, [20, 10]), got {_show(v)}")
    from dampnet.training.settings import check_hidden

    try:        # the runtime's layer limit, as `dampnet train --hidden` checks it
        return list(check_hidden(items))
    except ValueError as e:
        raise _Bad(str(e)) from None


def _features(v) -> list[str] | None:
    """"default" (velocity, acceleration and the data's control) or a list of feature names."""
    from dampnet.features import FEATURES

    if v == "default":
        return None
    if not isinstance(v, list) or not v or not all(isinstance(f, str) for f in v):
        raise _Bad(f"expected 'default' or a list of feature names, got {_show(v)}")
    bad = [f for f in v if f not in FEATURES]
    if bad:
        raise _Bad(f"{_show(bad[0])} is not a feature; valid: {', '.join(FEATURES)}")
    if len(set(v)) != len(v):
        raise _Bad(f"each feature once, got {_show(v)}")
    from dampnet.training.settings import check_inputs

    try:
        check_inputs(v)
    except ValueError as e:
        raise _Bad(str(e)) from None
    return list(v)


def _training(name: str, none: str | None = None) -> Callable[[Any], Any]:
    """A training option checked as every front end checks it (dampnet.training.settings.option:
    one line naming the option and its range), before any cell trains; `none`: the word for None."""
    def norm(v):
        from dampnet.training.settings import option

        if none is not None and isinstance(v, str) and v.strip().lower() == none:
            return None
        try:
            return option(name, v)
        except ValueError as e:
            raise _Bad(str(e)) from None
    return norm


def _restarts(v) -> int | str:
    """'auto' (as `dampnet train` without --restarts) or a number of restarts."""
    from dampnet.recipes.training import AUTO

    if isinstance(v, str) and v.strip().lower() == AUTO:
        return AUTO
    return _training("restarts")(v)


def _restart_scores() -> tuple[str, ...]:
    from dampnet.training.restarts import SCORES

    return tuple(SCORES)


def _default_restart_score() -> str:
    from dampnet.training.restarts import DEFAULT_SCORE

    return DEFAULT_SCORE


def _objective(kind: str, v) -> str:
    """A numeric metric of the section's cells (what the summary ranks, lower is better)."""
    valid = objectives(kind)
    if v not in valid:
        raise _Bad(f"{_show(v)} is not a {kind} metric; valid: {', '.join(valid)}")
    return v


def _vehicle_damping() -> tuple[str, ...]:
    """A full-vehicle cell's damping settings (dampnet.recipes.control_laws.VEHICLE_DAMPING)."""
    from dampnet.recipes.control_laws import VEHICLE_DAMPING

    return tuple(VEHICLE_DAMPING)


def _control_laws() -> tuple[str, ...]:
    """A simulation cell's controllers: the control-law registry's names (dampnet.recipes.control_laws)."""
    from dampnet.recipes import control_laws

    return control_laws.names()


def _algorithms() -> tuple[str, ...]:
    """The training algorithms, and 'auto' (dampnet train's default: br or lm by the rows)."""
    from dampnet.recipes.training import AUTO
    from dampnet.training.fitting import ALGORITHMS

    return (AUTO, *ALGORITHMS)


# -- the parameters ---------------------------------------------------------------------------

@dataclass(frozen=True)
class Param:
    """One cell parameter: `name` in the cell and the table, `key` in its spec table (a value, or a
    list of values: an axis), `axis`: a main axis of its section (a plural key); `kind`: the type a
    random draw must have ("int", "float", "any": choice only)."""

    name: str
    key: str
    norm: Callable[[Any], Any]
    default: Any
    axis: bool = False
    kind: str = "any"
    input: str | None = None      # the input role the value names (a file read by the cell)
    help: str = ""
    required: bool = False        # the spec must give it (a dataset, a quarter-car road)


def _vehicle_params() -> list[Param]:
    from dampnet.sim.vehicle import Vehicle

    out = []
    for name in ("m_s", "m_us", "k_s", "k_t", "c_t", "dt", "x_static", "f_static"):
        if name in Vehicle.__dataclass_fields__:
            out.append(Param(f"vehicle.{name}", name, _float(), None, kind="float",
                             help="quarter-car field (SI units), default: Table 5's"))
    return out


def _in(rng: limits.Range) -> Callable[[Any], float]:
    """A number within one of dampnet.sim.limits' ranges: the ones `dampnet simulate` and
    `dampnet vehicle` check (--dt, --speed), so a spec accepts what the commands accept."""
    number = _float()

    def norm(v):
        x = number(v)
        try:
            return limits.check_number("", x, rng)
        except ValueError:
            raise _Bad(f"expected a number in {rng.text()}, got {_show(v)}") from None
    return norm


def _fullcar_params() -> list[Param]:
    """[fullcar.vehicle]: every field of the runtime's full car (FULLCAR_FIELDS) but those the test sets."""
    from dampnet import _core

    enums = {"tyre_model": _core.TYRE_MODELS, "damper_eval": _core.DAMPER_EVALS,
             "accel_feature": _core.ACCEL_FEATURES}
    out = []
    for name, (_default, doc) in _core.FULLCAR_FIELDS.items():
        if name in FULLCAR_SET_BY_TEST:
            continue
        if name in enums:
            out.append(Param(f"vehicle.{name}", name, _choice(tuple(enums[name]), f"a {name}"), None,
                             help=f"full-car field: one of {', '.join(enums[name])}"))
        else:
            out.append(Param(f"vehicle.{name}", name, _float(), None, kind="float", help=f"full-car field: {doc}"))
    return out


def _controller_params() -> list[Param]:
    from dampnet.sim.vehicle import Controller

    return [Param(f"controller.{name}", name, _float(), None, kind="float",
                  help="control-law field (V, N s/m, s), default: calibrated on the damper")
            for name in Controller.__dataclass_fields__ if name != "kind"]


#: the [training] keys' values the options table's check does not say: their own spellings ("20-10",
#: 'default', 'auto', effect ids) and messages
_TRAINING_NORMS: dict[str, Callable[[Any], Any]] = {
    "algorithm": _choice(_algorithms, "a training algorithm"), "add": _effects, "features": _features,
    "hidden": _hidden, "restarts": _restarts, "activation": _choice(lambda: _table()["activation"].choices,
                                                                     "an activation"),
    "restart_score": _choice(_restart_scores, "a restart score"),
    "decimate": _training("decimate", none="auto"), "holdout_voltage": _training("holdout_voltage", none="none")}
#: the words a [training] key's help adds to its row's
_TRAINING_HELP = {"algorithm": "lm (the default here: a sweep compares what it names), br, scg, adam, or auto (dampnet "
                               "train's default; the column algorithm_used says which)",
                  "features": "'default' or feature names", "decimate": "or 'auto'", "holdout_voltage": "or 'none'",
                  "restarts": "a number or 'auto'; default 1, one training"}


def _table():
    from dampnet.training.settings import OPTIONS

    return OPTIONS


def training_params() -> list[Param]:
    """[training]'s keys: the dataset's, then one per row of the options table with a sweep key
    (dampnet.training.settings.OPTIONS: its default, its check, its help), read now (a row
    registered later counts)."""
    out = [
        Param("dataset", "datasets", _text, None, axis=True, input="dataset", required=True,
              help="a dataset path, or rig:PLAN (thesis, quick, a plan JSON) generated per cell"),
        Param("data_seed", "data_seeds", _int(0), 0, axis=True, kind="int", help="seed of rig:PLAN data"),
        Param("rig_effects", "rig_effects", _effects, [], axis=True, help="effects on in the rig (rig:PLAN)"),
    ]
    for row in _table().values():
        if row.sweep is None:
            continue
        default = list(row.default) if isinstance(row.default, tuple) else row.default
        kind = {"whole": "int", "real": "float"}.get(row.kind, "any")
        words = _TRAINING_HELP.get(row.name)
        out.append(Param(row.name, row.sweep, _TRAINING_NORMS.get(row.name) or _training(row.name), default,
                         axis=row.axis, kind=kind, help=row.help() + (f"; {words}" if words else "")))
    return out


SIMULATION_PARAMS = [
    Param("model", "models", _text, "default", axis=True, input="model",
          help="'default', a model directory or model.json, a lookup-table JSON, 'truth', "
               "'truth:EFFECT,...', 'linear:C' [N s/m]"),
    Param("road", "roads", _text, None, axis=True, input="road", required=True,
          help="a road by name (dampnet.recipes.roads), or a CSV distance_m,elevation_m"),
    Param("road_seed", "road_seeds", _int(0), 0, axis=True, kind="int",
          help="seed of the random roads (a road's seed parameter: rough, iso)"),
    Param("road_length_m", "road_length_m", _float(positive=True), 200.0, kind="float",
          help="length of the roads that take one [m] (a road's length_m parameter: iso)"),
    Param("speed", "speeds", _in(limits.SPEED_M_S), 10.0, axis=True, kind="float",
          help=f"{limits.SPEED_M_S.text()}"),
    Param("controller", "controllers", _choice(_control_laws, "a controller"), "passive_high", axis=True,
          help="a control law by name (dampnet.recipes.control_laws)"),
]

def _maneuver_tests() -> tuple[str, ...]:
    from dampnet.recipes.maneuvers import names

    return names()


def _setting_param(st) -> Param:
    """A manoeuvre setting (dampnet.recipes.maneuvers.Setting) as a [fullcar] key: None by
    default (the grid gives each test its own default, dampnet.sweep.grid.applicable)."""
    from dampnet.recipes.maneuvers import MANEUVERS

    if st.kind == "choice":
        norm, kind = _choice(st.choices, f"a {st.name}"), "any"
    elif st.kind == "flag":
        norm, kind = _flag, "any"
    elif st.kind in ("int", "seed"):
        norm, kind = _int(0), "int"
    elif st.kind == "road":
        norm, kind = _road, "any"
    else:
        norm, kind = (_in(st.range) if st.range is not None else _float(positive=True)), "float"
    by = ", ".join(f"{m.name} {m.defaults[st.name]}" for m in MANEUVERS.values() if st.name in m.defaults)
    return Param(st.name, st.sweep_key, norm, None, axis=st.axis, kind=kind, help=f"{st.text()} (default: {by})",
                 input="road" if st.kind == "road" else None)


def fullcar_params() -> list[Param]:
    """[fullcar]'s own keys: the model, the test, the damping, the dt and every manoeuvre's
    settings, read from dampnet.recipes.maneuvers now (a manoeuvre registered later counts)."""
    from dampnet.recipes.maneuvers import SETTINGS

    settings = [_setting_param(st) for st in SETTINGS.values()]
    return [
        Param("model", "models", _text, "default", axis=True, input="model",
              help="as [simulation] models: the damper at all four corners"),
        Param("test", "tests", _choice(_maneuver_tests, "a full-vehicle test"), "dlc", axis=True,
              help="a full-vehicle test of dampnet.recipes.maneuvers (bsst, dlc, road, ...)"),
        Param("damping", "damping", _choice(_vehicle_damping, "a full-vehicle damping setting"), "low", axis=True,
              help="every corner passive at the damper's low or high setting, or on-off skyhook"),
        *[p for p in settings if p.axis],
        Param("dt", "dt", _in(limits.STEP_S), 1e-3, kind="float", help=f"step, {limits.STEP_S.text()}"),
        *[p for p in settings if not p.axis],
    ]


SECTION_PARAMS = {"training": training_params, "simulation": lambda: SIMULATION_PARAMS,
                  "fullcar": fullcar_params}
SUBTABLES = {"simulation": {"vehicle": _vehicle_params, "controller": _controller_params},
             "fullcar": {"vehicle": _fullcar_params}}
#: keys renamed: {(section, old key): the message naming the new one}
RENAMED = {("fullcar", "profiles"): "renamed roads (issue 52): a road of the road registry, e.g. roads = "
                                    "[\"rough\", \"iso:C\"] for the old profiles [\"thesis\", \"C\"]"}
#: why a key is not in a sub-table (instead of "unknown key"): {(section, sub-table): {key: reason}}
SUBTABLE_HINTS = {("fullcar", "vehicle"): FULLCAR_SET_BY_TEST}


def section_params(kind: str) -> list[Param]:
    """Every parameter of a section's cells, in table order (sub-table fields last)."""
    out = list(SECTION_PARAMS[kind]())
    for make in SUBTABLES.get(kind, {}).values():
        out += make()
    return out


# -- the spec ---------------------------------------------------------------------------------

@dataclass
class RandomSpec:
    """n samples drawn with numpy.random.default_rng(seed): {param name: (distribution, args)}."""

    n: int
    seed: int
    dists: dict[str, tuple[str, list]]


@dataclass
class Section:
    """A section's grid: {param name: its values} (every parameter: one value when fixed)."""

    kind: str
    axes: dict[str, list]
    random: RandomSpec | None
    objective: str
    given: set[str] = field(default_factory=set)   # parameters the spec named (the rest: defaults)


@dataclass
class Spec:
    source: str                       # the file name in messages
    base: Path                        # relative paths resolve here
    sections: dict[str, Section]
    data: str = "shared"
    allowed_failures: int = 3
    raw: dict = field(default_factory=dict)   # the parsed TOML (kept in DIR/sweep.json)
    text: str | None = None


def load_spec(path: str | os.PathLike) -> Spec:
    """The spec in a TOML file; SpecError naming the file, line and field."""
    from dampnet.schema import read_text

    p = Path(path)
    text = read_text(p, SpecError, "UTF-8 text (a sweep spec is TOML)")
    return parse_spec(text, source=str(path), base=p.resolve().parent)


def parse_spec(spec: str | dict, source: str = "<spec>", base: str | os.PathLike | None = None) -> Spec:
    """A Spec from TOML text or an already parsed dict; SpecError on anything wrong."""
    text = None
    if isinstance(spec, str):
        text = spec
        raw = parse_toml(spec, source, SpecError)
    elif isinstance(spec, dict):
        raw = spec
    else:
        raise SpecError(f"{source}: expected a TOML text, a file or a dict, got {type(spec).__name__}")
    return _Parser(raw, source, Path(base) if base is not None else Path.cwd(), text).spec()


class _Parser:
    def __init__(self, raw: dict, source: str, base: Path, text: str | None):
        self.raw, self.source, self.base, self.text = raw, source, base.resolve(), text

    # -- errors with a location
    def fail(self, table: str, key: str | None, msg: str, index: int | None = None) -> SpecError:
        line = _line_of(self.text, table, key) if self.text is not None else None
        if key is not None and len(key) > SHOW_CHARS:
            key = key[:SHOW_CHARS - 3] + "..."
        path = ".".join(p for p in (table, key) if p)
        where = f"line {line}: " if line else ""
        field_ = f"{path}[{index}]" if index is not None else path
        return SpecError(f"{self.source}: {where}{field_}: {msg}")

    def table(self, d: Any, table: str) -> dict:
        if not isinstance(d, dict):
            raise self.fail(table, None, f"expected a table, got {_show(d)}")
        return d

    def spec(self) -> Spec:
        raw = self.table(self.raw, "")
        unknown = [k for k in raw if k not in ("sweep", *KINDS)]
        if unknown:
            raise self.fail("", unknown[0], f"unknown table; valid: sweep, {', '.join(KINDS)}")
        if not any(k in raw for k in KINDS):
            raise SpecError(f"{self.source}: no [training], [simulation] or [fullcar] table: nothing to sweep")
        out = Spec(source=self.source, base=self.base, sections={}, raw=raw, text=self.text)
        top = self.table(raw.get("sweep", {}), "sweep")
        for k, v in top.items():
            try:
                if k == "data":
                    out.data = _choice(DATA_MODES, "a data mode")(v)
                elif k == "allowed_failures":
                    out.allowed_failures = _int(0)(v)
                elif k == "name":
                    _text(v)
                else:
                    raise _Bad("unknown key; valid: data, allowed_failures, name")
            except _Bad as e:
                raise self.fail("sweep", k, str(e)) from None
        for kind in KINDS:
            if kind in raw:
                out.sections[kind] = self.section(kind, self.table(raw[kind], kind))
        return out

    def section(self, kind: str, d: dict) -> Section:
        params = {p.key: p for p in SECTION_PARAMS[kind]()}
        subtables = SUBTABLES.get(kind, {})
        axes: dict[str, list] = {}
        given: set[str] = set()
        objective = DEFAULT_OBJECTIVE[kind]
        objective_given = False
        random = None
        for key, v in d.items():
            if key == "objective":
                objective_given = True
                try:
                    objective = _objective(kind, v)
                except _Bad as e:
                    raise self.fail(kind, key, str(e)) from None
            elif key == "random":
                random = self.random(kind, self.table(v, f"{kind}.random"))
            elif key in subtables:
                sub = {p.key: p for p in subtables[key]()}
                for k2, v2 in self.table(v, f"{kind}.{key}").items():
                    if k2 not in sub:
                        raise self.fail(f"{kind}.{key}", k2, _unknown(kind, key, k2, sub))
                    axes[sub[k2].name] = self.values(sub[k2], v2, f"{kind}.{key}")
                    given.add(sub[k2].name)
            elif key in params:
                axes[params[key].name] = self.values(params[key], v, kind)
                given.add(params[key].name)
            elif (kind, key) in RENAMED:
                raise self.fail(kind, key, RENAMED[(kind, key)])
            else:
                valid = [*params, *subtables, "objective", "random"]
                raise self.fail(kind, key, f"unknown key; valid: {', '.join(valid)}")
        for p in section_params(kind):
            if p.name not in axes:
                if "." in p.name:
                    continue      # a vehicle or controller field not set: the run's own default
                if p.required:
                    raise SpecError(f"{self.source}: [{kind}] needs {p.key} ({p.help})")
                axes[p.name] = [p.default]
        if random is not None:
            both = sorted(set(random.dists) & given)
            if both:
                raise self.fail(f"{kind}.random", both[0].split(".")[-1],
                                f"is also set in [{kind}]: a parameter is either swept on the grid or "
                                "drawn at random")
        if kind == "training":
            self.check_averages(axes)
        if kind == "fullcar" and not objective_given:
            from dampnet.recipes.maneuvers import default_objective

            tests = random.dists["test"][1] if random is not None and "test" in random.dists else axes["test"]
            objective = default_objective(tests) or objective
        return Section(kind, axes, random, objective, given)

    def check_averages(self, axes: dict[str, list]) -> None:
        """Each grid point's average within its restarts and the runtime's width (as `dampnet train`
        checks --average), when the spec is read; 'auto' restarts are known with the data."""
        from dampnet.training.restarts import check_average

        for r in axes["restarts"]:
            for a in axes["average"]:
                for h in axes["hidden"]:
                    for score in axes["restart_score"]:
                        try:
                            check_average(a, a if isinstance(r, str) else r, h, score)
                        except ValueError as e:
                            raise self.fail("training", "average", str(e)) from None

    def values(self, p: Param, v: Any, table: str) -> list:
        """A key's values: each item of a list, or the one value."""
        if isinstance(v, list) and not v:
            raise self.fail(table, p.key, "expected a value or a non-empty list of values, got []")
        items = v if isinstance(v, list) else [v]
        out = []
        for i, item in enumerate(items):
            try:
                val = p.norm(item)
            except _Bad as e:
                raise self.fail(table, p.key, str(e), i if isinstance(v, list) else None) from None
            if p.input:
                try:
                    check_input(p.input, val, self.base)
                except _Bad as e:
                    raise self.fail(table, p.key, str(e), i if isinstance(v, list) else None) from None
            if val not in out:
                out.append(val)
        return out

    def random(self, kind: str, d: dict) -> RandomSpec:
        table = f"{kind}.random"
        by_name = {p.name: p for p in section_params(kind)}
        by_key = {p.key: p for p in SECTION_PARAMS[kind]()}
        n = seed = None
        dists: dict[str, tuple[str, list]] = {}
        entries: list[tuple[str, str, Any]] = []
        for k, v in d.items():
            if k in SUBTABLES.get(kind, {}):
                sub = [p.key for p in SUBTABLES[kind][k]()]
                for k2, v2 in self.table(v, f"{table}.{k}").items():
                    if k2 not in sub:
                        raise self.fail(f"{table}.{k}", k2, _unknown(kind, k, k2, sub))
                    entries.append((f"{table}.{k}", f"{k}.{k2}", v2))
            else:
                entries.append((table, k, v))
        for tbl, name, v in entries:
            key = name.split(".")[-1]
            try:
                if name == "n":
                    n = _int(1)(v)
                    continue
                if name == "seed" and not isinstance(v, dict):
                    seed = _int(0)(v)
                    continue
                p = by_name.get(name) or by_key.get(name)
                if p is None:
                    raise _Bad("unknown parameter; valid: n, seed (of the draws) and "
                               + ", ".join(by_name))
                dists[p.name] = self.dist(p, v)
            except _Bad as e:
                raise self.fail(tbl, key, str(e)) from None
        if n is None:
            raise self.fail(table, "n", "missing: the number of random samples")
        if seed is None:
            raise self.fail(table, "seed", "missing: the seed of the random samples (an integer >= 0)")
        if not dists:
            raise SpecError(f"{self.source}: [{table}] draws nothing: name a parameter with a distribution, "
                            "e.g. speed = {uniform = [5, 25]}")
        return RandomSpec(n, seed, dists)

    def dist(self, p: Param, v: Any) -> tuple[str, list]:
        if not isinstance(v, dict) or len(v) != 1:
            raise _Bad(f"expected one distribution, e.g. {{uniform = [lo, hi]}}; valid: {', '.join(DISTRIBUTIONS)}")
        (name, args), = v.items()
        if name not in DISTRIBUTIONS:
            raise _Bad(f"{_show(name)} is not a distribution; valid: {', '.join(DISTRIBUTIONS)}")
        if not isinstance(args, list) or not args:
            raise _Bad(f"{name}: expected a list, got {_show(args)}")
        if name == "choice":
            vals = []
            for a in args:
                vals.append(p.norm(a))
                if p.input:
                    check_input(p.input, vals[-1], self.base)
            return name, vals
        if len(args) != 2 or not all(isinstance(a, (int, float)) and not isinstance(a, bool) for a in args):
            raise _Bad(f"{name}: expected two numbers, got {_show(args)}")
        if not all(math.isfinite(a) for a in args):
            raise _Bad(f"{name}: expected two finite numbers, got {_show(args)}")
        lo, hi = args
        what = ("mean", "sd") if name == "normal" else ("lo", "hi")
        if name == "integers":
            if p.kind != "int" or not all(isinstance(a, int) for a in args) or lo > hi:
                raise _Bad("integers = [lo, hi] (integers, lo <= hi) draws an integer parameter only")
        elif p.kind != "float":
            raise _Bad(f"{name} draws a number parameter only; use choice = [...] or integers")
        elif name == "normal" and hi < 0:
            raise _Bad("normal = [mean, sd]: sd must be >= 0")
        elif name in ("uniform", "loguniform") and lo > hi:
            raise _Bad(f"{name} = [lo, hi]: lo must be <= hi")
        elif name == "loguniform" and lo <= 0:
            raise _Bad("loguniform = [lo, hi]: lo must be > 0")
        if not math.isfinite(float(hi) - float(lo)) or not math.isfinite(float(lo) + float(hi)):
            raise _Bad(f"{name} = {_show(args)}: the range is too wide to draw from (beyond a float's range)")
        for w, a in zip(what, args):
            if w != "sd":
                try:       # the ends (and the mean) must be values of the parameter
                    p.norm(a)
                except _Bad as e:
                    raise _Bad(f"{name} = [{', '.join(what)}]: {w}: {e}") from None
        return name, [lo, hi]


def _unknown(kind: str, sub: str, key: str, valid) -> str:
    """The message for a key a sub-table does not have (why, when it is one the cell sets itself)."""
    hint = SUBTABLE_HINTS.get((kind, sub), {}).get(key)
    if hint:
        return f"not a key of [{kind}.{sub}]: {hint}"
    return f"unknown key; valid: {', '.join(valid)}"


def check_input(role: str, value: str, base: Path) -> None:
    """_Bad unless a dataset / model / road names something that exists (generated ones: by name)."""
    if role == "dataset":
        if value.startswith("rig:"):
            plan = value[4:]
            if plan in ("thesis", "quick"):
                return
            if not resolve(plan, base).is_file():
                raise _Bad(f"{_show(value)}: rig:PLAN takes thesis, quick or a plan JSON file; {_show(plan)} is none")
            from dampnet.rig.plans import load_plan

            try:
                load_plan(str(resolve(plan, base)))
            except (ValueError, OSError) as e:
                raise _Bad(f"{_show(value)}: {e}") from None
            return
        path = resolve(value, base)
        if not os.path.exists(path):
            raise _Bad(f"{_show(value)}: no such dataset (a directory, CSV/text or .mat file, or rig:PLAN)")
        from dampnet.data.fileformat import is_dataset_dir

        if path.is_dir() and not is_dataset_dir(path):   # (the sweep hashes an input directory whole)
            raise _Bad(f"{_show(value)}: a directory without manifest.csv: not a dataset directory")
    elif role == "model":
        if value in ("default", "truth") or value.startswith(("truth:", "linear:")):
            return
        p = resolve(value, base)
        if not os.path.exists(p):
            raise _Bad(f"{_show(value)}: no such model (a model directory or model.json, a lookup-table JSON, "
                       "'default', 'truth', 'truth:EFFECT,...' or 'linear:C')")
        if p.is_dir() and not (p / "model.json").is_file():
            raise _Bad(f"{_show(value)}: a directory without model.json: not a model directory")
    elif role == "road":     # a road by name (dampnet.recipes.roads) or a CSV distance profile
        from dampnet.recipes import roads

        if roads.is_named(value):
            try:
                roads.parse(value)
            except ValueError as e:
                raise _Bad(str(e)) from None
            return
        if not os.path.isfile(resolve(value, base)):
            raise _Bad(f"{_show(value)}: not a road: use {roads.usage()}")


def resolve(value: str, base: Path) -> Path:
    """A spec's path, relative to `base` (the spec file's directory) unless absolute."""
    p = Path(os.path.expanduser(value))
    return p if p.is_absolute() else base / p


def _line_of(text: str, table: str, key: str | None) -> int | None:
    """The line (1-based) of `key` in `[table]` of the TOML text, or of the table's header; None if
    not found (a best effort: plain and dotted keys, quoted or not)."""
    current = ""
    header_line = None
    want = table.split(".") if table else []
    for i, line in enumerate(text.splitlines(), 1):
        s = line.strip()
        m = re.match(r"^\[\[?\s*([^\]]+?)\s*\]\]?", s)
        if m:
            current = m.group(1).replace('"', "").replace("'", "").replace(" ", "")
            if current == table and header_line is None:
                header_line = i
            continue
        if key is None:
            continue
        m = re.match(r"""^["']?([A-Za-z0-9_.\-"' ]+?)["']?\s*=""", s)
        if not m:
            continue
        full = [x for x in (current.split(".") if current else [])]
        full += [x.strip().strip('"').strip("'") for x in m.group(1).split(".")]
        if full == [*want, key]:
            return i
    return header_line
