"""Road profiles by name: the one vocabulary `dampnet simulate --road`, the sweep's [simulation]
roads and `dampnet plan-tests`'s built-in cases read.

A road is named as `NAME` or `NAME:ARGS`, ARGS a comma-separated list of `key=value` (a
parameter of the road, in its unit) or one bare value for the road's positional parameter:

    impulse             bump:height_m=0.08          sweep            rough
    iso:C               iso:class=E,length_m=100    rough:seed=3     a CSV file distance_m,elevation_m

Names are case-insensitive and each road keeps its older spellings as aliases (sine_sweep,
sine-sweep; thesis_rough, rough-road; iso8608:C). The numbers live in
dampnet.sim.roads.profiles; an entry here only names a profile, lists its parameters (unit,
default, meaning) and builds it. The parameters a front end fills from its own options (FILLED:
`seed` from --seed, the sweep's road_seeds or the full car's road_seed; `length_m` from the
sweep's road_length_m; `speed_m_s` from --speed, the sweep's speeds or the full car's speed) are
a road's only by declaring them in `fills`, and are passed as `context`; a value written in the
name wins over the context's. A road's own parameter may not take one of those names (refused
when the road is made, so at registration): the sweep once filled a road's own `length_m`.

    req = parse("iso:E")          # RoadRequest; RoadError naming the registry's roads otherwise
    road = req.build(seed=2)      # the dampnet.sim.roads.Road
    road = build("rough", seed=1) # parse + build, or a CSV profile for a path

Adding a road: `register(RoadKind(...))` (docs/recipes.md, "Roads"); every front end then
takes it: `dampnet simulate`, the sweep's [simulation] and [fullcar] roads, plan-tests' cases,
`dampnet vehicle --test road --road` (the full car: two tracks, the rear a wheelbase later) and
`dampnet rig --replay` (with or without --corner); their help and allowed values come from here.
"""

from __future__ import annotations

import functools
import math
import os
from dataclasses import dataclass
from typing import Any, Callable, Mapping

from dampnet.sim.roads.profiles import (ISO_CLASSES, Road, RoadError, bump, impulse, iso8608, read_profile_csv,
                                        sine_sweep, thesis_rough_road)

#: the speeds [m/s] plan-tests runs a distance profile at (the thesis's rough road: 10 and 20 m/s)
CASE_SPEEDS_M_S = (10.0, 20.0)


@dataclass(frozen=True)
class RoadParam:
    """One parameter of a road: its name, unit (SI; "" for none), default, meaning, the type a
    value written in a road's name is read as (float, int or str), and for numbers the range
    [lo, hi] a value must lie in: a road whose parameters leave nothing to simulate (a 1e-300 s
    pulse, a 1e9 octave/s sweep) or more than memory holds (a 1e-7 octave/s sweep: 1.9 TiB),
    or overflow (rms 1e300) is refused naming the parameter, before anything is built (issue 49)."""

    name: str
    unit: str
    default: Any
    doc: str
    kind: type = float
    lo: float | None = None
    hi: float | None = None

    def read(self, value: Any, road: str) -> Any:
        """`value` (text from a name, or a front end's value) as this parameter's type, in range."""
        unit = f" [{self.unit}]" if self.unit else ""
        try:
            if self.kind is int:
                if isinstance(value, bool) or (isinstance(value, float) and not value.is_integer()):
                    raise ValueError
                out = int(value)
            else:
                out = self.kind(value.strip() if isinstance(value, str) else value)
        except (TypeError, ValueError, OverflowError):
            what = {float: "a number", int: "a whole number"}.get(self.kind, self.doc)
            raise RoadError(f"road {road!r}: {self.name}: expected {what}{unit}, got {value!r}") from None
        if self.kind in (int, float) and not (math.isfinite(out) and (self.lo is None or out >= self.lo)
                                              and (self.hi is None or out <= self.hi)):
            raise RoadError(f"road {road!r}: {self.name}: expected {self.range_text()}{unit}, got {value!r}")
        return out

    def range_text(self) -> str:
        num = (lambda x: f"{int(x):d}") if self.kind is int else (lambda x: f"{x:g}")
        if self.lo is not None and self.hi is not None:
            return f"{num(self.lo)} to {num(self.hi)}"
        if self.lo is not None:
            return f"at least {num(self.lo)}"
        return "a finite number" if self.hi is None else f"at most {num(self.hi)}"

    def text(self) -> str:
        unit = f" [{self.unit}]" if self.unit else ""
        limits = f", {self.range_text()}" if self.lo is not None or self.hi is not None else ""
        return f"{self.name}{unit} (default {self.default}{limits}): {self.doc}"


#: the parameters front ends fill from their own options, by name; a road takes one by listing it in
#: RoadKind.fills (its value written in the road's name still wins), and no road's own parameter
#: may be named like one (issue 52: a road's own `length_m` was overwritten by every sweep cell)
FILLED = {p.name: p for p in (
    RoadParam("seed", "", 0, "seed of the random profile (--seed, the sweep's road_seeds, the full car's "
              "road_seed; numpy takes any whole number >= 0)", int, 0),
    RoadParam("length_m", "m", 200.0, "profile length (the sweep's road_length_m)", float, 1.0, 100_000.0),
    RoadParam("speed_m_s", "m/s", 20.0, "the speed driven over the road (--speed, the sweep's speeds, the full "
              "car's speed)", float, 1e-3, 100.0))}


@dataclass(frozen=True)
class RoadKind:
    """A registry entry: `name`, older spellings (`aliases`), `profile` "spatial" (elevation over
    distance: a speed applies) or "temporal" (displacement over time), its parameters, a doc
    line, `positional` (the parameter a bare NAME:VALUE sets) and `build(params)` -> Road, params
    every parameter by name (the defaults filled in). `fills`: the FILLED parameters it takes
    from the front ends (seed, length_m, speed_m_s; its own `params` may not use those names);
    a road that fills `seed` is random: the full car's right track mixes in the road at seed + 1.
    `periodic`: the profile repeats over its length (the full car's rear wheels, a wheelbase
    behind, start on its end; otherwise on its first elevation)."""

    name: str
    doc: str
    profile: str
    build: Callable[[Mapping[str, Any]], Road]
    params: tuple[RoadParam, ...] = ()
    aliases: tuple[str, ...] = ()
    positional: str | None = None
    case_speeds_m_s: tuple[float, ...] = CASE_SPEEDS_M_S
    fills: tuple[str, ...] = ()
    periodic: bool = False

    def __post_init__(self) -> None:
        if self.profile not in ("spatial", "temporal"):
            raise RoadError(f"road {self.name!r}: profile must be 'spatial' or 'temporal', got {self.profile!r}")
        for f in self.fills:
            if f not in FILLED:
                raise RoadError(f"road {self.name!r}: fills {f!r}: a front end fills only {', '.join(FILLED)}")
        own = [p.name for p in self.params]
        for n in own:
            if n in FILLED:
                raise RoadError(f"road {self.name!r}: parameter {n!r} is a name the front ends fill "
                                f"({', '.join(FILLED)}): rename it, or drop it and declare fills=({n!r},) "
                                "to take the front end's value")
            if own.count(n) > 1:
                raise RoadError(f"road {self.name!r}: parameter {n!r} listed twice")
        if self.positional is not None and self.positional not in self.param_names():
            raise RoadError(f"road {self.name!r}: positional {self.positional!r} is not one of its parameters")

    @property
    def all_params(self) -> tuple[RoadParam, ...]:
        """Its own parameters, then the ones front ends fill (FILLED's, in `fills` order)."""
        return self.params + tuple(FILLED[f] for f in self.fills)

    def param_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.all_params)

    def usage(self) -> str:
        """How the road is written, e.g. 'iso:CLASS'."""
        return f"{self.name}:{self.positional.upper()}" if self.positional else self.name


@dataclass(frozen=True)
class RoadRequest:
    """A parsed road name: the entry, the parameters written in the name and the text itself."""

    kind: RoadKind
    given: Mapping[str, Any]
    text: str

    @property
    def profile(self) -> str:
        return self.kind.profile

    def takes(self, param: str) -> bool:
        return param in self.kind.param_names()

    def params(self, **context: Any) -> dict[str, Any]:
        """Every parameter: the name's, else the context's (FILLED names only: those the road
        fills are used, the others ignored), else the default."""
        unknown = sorted(set(context) - set(FILLED))
        if unknown:
            raise TypeError(f"road context {unknown[0]!r}: a front end fills only {', '.join(FILLED)}")
        out = {}
        for p in self.kind.all_params:
            if p.name in self.given:
                out[p.name] = self.given[p.name]
            elif context.get(p.name) is not None:
                out[p.name] = p.read(context[p.name], self.text)
            else:
                out[p.name] = p.default
        return out

    def build(self, **context: Any) -> Road:
        return self.kind.build(self.params(**context))


_REGISTRY: dict[str, RoadKind] = {}
_ALIASES: dict[str, str] = {}


def register(kind: RoadKind) -> RoadKind:
    """Add a road to the vocabulary (its name and aliases must be new)."""
    for n in (kind.name, *kind.aliases):
        if n.lower() in _ALIASES:
            raise ValueError(f"road {n!r} is already registered (as {_ALIASES[n.lower()]!r})")
        if ":" in n or "," in n or "=" in n:
            raise ValueError(f"road name {n!r}: no ':', ',' or '=' in a name")
    _REGISTRY[kind.name] = kind
    for n in (kind.name, *kind.aliases):
        _ALIASES[n.lower()] = kind.name
    _parse.cache_clear()
    return kind


def unregister(name: str) -> None:
    """Remove a road (tests register their own and remove them after)."""
    kind = _REGISTRY.pop(_ALIASES[name.lower()])
    for n in (kind.name, *kind.aliases):
        _ALIASES.pop(n.lower(), None)
    _parse.cache_clear()


def names() -> tuple[str, ...]:
    """The registered roads' names (not the aliases), in registration order."""
    return tuple(_REGISTRY)


def get(name: str) -> RoadKind:
    """The entry of a name or alias (case-insensitive); RoadError listing the roads otherwise."""
    key = name.strip().lower()
    if key not in _ALIASES:
        raise RoadError(f"unknown road {name!r}: use {usage()}")
    return _REGISTRY[_ALIASES[key]]


def usage() -> str:
    """The roads as a help text writes them, and the CSV alternative."""
    return (", ".join(k.usage() for k in _REGISTRY.values())
            + " (NAME:key=value,... sets a parameter), or a CSV file with columns distance_m,elevation_m")


def is_named(text: str) -> bool:
    """True when `text` names a registered road (whether its parameters are right or not)."""
    return isinstance(text, str) and text.partition(":")[0].strip().lower() in _ALIASES


def parse(text: str) -> RoadRequest:
    """A road name (with its parameters) as a RoadRequest; RoadError naming what is wrong. Each
    text is parsed once (remembered until the registry changes): a sweep's cells share it."""
    if not isinstance(text, str):
        raise RoadError(f"road: expected a name, got {text!r}")
    return _parse(text)


@functools.lru_cache(maxsize=1024)
def _parse(text: str) -> RoadRequest:
    head, colon, args = text.strip().partition(":")
    kind = get(head)
    given: dict[str, Any] = {}
    params = {p.name: p for p in kind.all_params}
    for item in (args.split(",") if colon else ()):
        key, eq, value = item.partition("=")
        if not eq:
            if kind.positional is None or kind.positional in given:
                raise RoadError(f"road {text!r}: {item!r}: expected key=value; {_param_list(kind)}")
            key, value = kind.positional, item
        key = key.strip()
        if key not in params:
            raise RoadError(f"road {text!r}: unknown parameter {key!r}; {_param_list(kind)}")
        if key in given:
            raise RoadError(f"road {text!r}: {key} given twice: give each parameter once")
        try:
            given[key] = params[key].read(value, text)
        except RoadError as e:
            raise RoadError(f"{e} (write {kind.usage()} or {kind.name}:key=value,...)") from None
    return RoadRequest(kind, given, text.strip())


def _param_list(kind: RoadKind) -> str:
    if not kind.all_params:
        return f"{kind.name} takes no parameters"
    return f"{kind.name}'s parameters: " + "; ".join(p.text() for p in kind.all_params)


def is_profile_file(text: str) -> bool:
    """True when `text` is not a registered road but a road profile's file: a path that exists, or
    a name ending in .csv (whose absence `build` then names)."""
    s = text.strip() if isinstance(text, str) else None
    return bool(s) and not is_named(s) and (os.path.exists(s) or s.lower().endswith(".csv"))


def build(text: str, **context: Any) -> Road:
    """The Road `text` names (parse + build with `context`, e.g. seed=...), or the CSV profile at
    the path `text` (a file that exists or a name ending in .csv); RoadError otherwise."""
    if is_named(text):
        return parse(text).build(**context)
    if is_profile_file(text):
        return read_profile_csv(text.strip())
    raise RoadError(f"unknown road {text!r}: use {usage()}")


def help_text() -> str:
    """Every road with its doc line and parameters (for --help texts and docs)."""
    lines = []
    for k in _REGISTRY.values():
        also = f" (also {', '.join(k.aliases)})" if k.aliases else ""
        lines.append(f"{k.usage()}{also}: {k.doc}" + (f"; {_param_list(k)}" if k.all_params else ""))
    return "\n".join(lines)


# -- the built-in roads (dampnet.sim.roads.profiles) ------------------------------------------


def _iso_class(text: Any) -> str:
    c = str(text).strip().upper()
    if c not in ISO_CLASSES:
        raise ValueError(c)
    return c


register(RoadKind(
    "impulse", "the thesis's impulse: a raised-cosine pulse in time", "temporal",
    lambda p: impulse(height_m=p["height_m"], duration_s=p["duration_s"]),
    (RoadParam("height_m", "m", 0.05, "pulse height", float, 1e-6, 1.0),
     RoadParam("duration_s", "s", 0.05, "pulse duration (at least 1 ms: a shorter pulse has no content at the loops' steps)",
               float, 1e-3, 60.0))))
register(RoadKind(
    "bump", "a raised-cosine bump along the road (its duration depends on the speed)", "spatial",
    lambda p: bump(height_m=p["height_m"], length_m=p["width_m"]),
    (RoadParam("height_m", "m", 0.05, "bump height", float, 1e-6, 1.0),
     RoadParam("width_m", "m", 0.5, "bump length", float, 0.01, 1000.0))))
register(RoadKind(
    "sweep", "the bounce sine sweep: a log sweep of constant displacement amplitude", "temporal",
    lambda p: sine_sweep(amplitude_m=p["amplitude_m"], f0=p["f0_hz"], f1=p["f1_hz"], rate_oct_s=p["rate_oct_s"]),
    (RoadParam("amplitude_m", "m", 0.005, "displacement amplitude", float, 1e-6, 1.0),
     RoadParam("f0_hz", "Hz", 0.5, "start frequency", float, 0.01, 500.0),
     RoadParam("f1_hz", "Hz", 20.0, "end frequency", float, 0.01, 500.0),
     RoadParam("rate_oct_s", "octave/s", 0.1, "sweep rate (0.001: over an hour for 5 octaves; 10: a few cycles)",
               float, 1e-3, 10.0)),
    aliases=("sine_sweep", "sine-sweep")))
register(RoadKind(
    "rough", "the thesis's rough road: RMS 0.016 m, 184 m (an ISO 8608 shape)", "spatial",
    lambda p: thesis_rough_road(seed=p["seed"], rms_m=p["rms_m"]),
    (RoadParam("rms_m", "m", 0.016, "displacement RMS", float, 1e-6, 1.0),),
    aliases=("thesis", "thesis_rough", "thesis-rough", "rough-road"), fills=("seed",), periodic=True))
register(RoadKind(
    "iso", "a random ISO 8608 profile of class A..H", "spatial",
    lambda p: iso8608(p["class"], length_m=p["length_m"], seed=p["seed"]),
    (RoadParam("class", "", "C", "ISO 8608 class A..H", _iso_class),),
    aliases=("iso8608",), positional="class", fills=("length_m", "seed"), periodic=True))
