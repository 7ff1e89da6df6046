"""A spec's cells: every grid point x every random sample, parameters that do not apply dropped.

    for cell in expand(spec): cell.kind, cell.params (a JSON-able dict, the table's columns)

A parameter that does not apply to a cell is None there and does not make cells differ: a
dataset read from a path has no data_seed or rig_effects, a time profile (impulse, sweep)
no speed, a road that does not fill its seed (dampnet.recipes.roads: RoadKind.fills) no
road_seed, one that does not fill its length_m (iso:X does) no road_length_m; a full-vehicle
cell has only its test's settings (dampnet.recipes.maneuvers: a bounce sweep (bsst) no speed, a
lane change (dlc) no road or road_seed, a road that does not fill its seed no road_seed, only a bsst a mode and the bsst_*
settings), each its test's default unless set (dlc 120, road 60 km/h, as `dampnet vehicle`).
Cells with equal parameters are one cell.

Size: a spec may make at most MAX_CELLS cells (counted before equal cells merge: the grid's
axes multiplied, times the random samples), checked before any is listed; `max_cells`
(`dampnet sweep --max-cells N`) raises it up to MAX_CELLS_CEILING. Every sweep cell is a
listed, hashed and submitted Dask task and a file in DIR/cells: a spec of millions of cells
is a typo more often than a plan, and would spend minutes and gigabytes before the first
cell runs. A random sample drawn outside its parameter's range (e.g. a negative speed from
a normal distribution) is a SpecError naming the field, like a bad value in the file.
"""

from __future__ import annotations

import itertools
import json
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dampnet.sweep.spec import (KINDS, RandomSpec, Section, Spec, SpecError, _Bad,
                                _line_of, section_params)

#: the most cells a spec may make by default (see the module docstring)
MAX_CELLS = 100_000
#: the most `max_cells` may allow
MAX_CELLS_CEILING = 10_000_000


@dataclass
class Cell:
    """One unit of work: kind "training", "simulation" or "fullcar", its parameters, its position in the spec."""

    kind: str
    index: int
    params: dict[str, Any]
    key: str = ""                                   # set by dampnet.sweep.inputs.bind (a hash)
    inputs: dict[str, Any] = field(default_factory=dict)   # role -> InputRef, set by bind


def expand(spec: Spec, max_cells: int = MAX_CELLS) -> list[Cell]:
    """The cells of every section of `spec` (training, simulation, fullcar), in grid order;
    SpecError when they would be more than `max_cells`."""
    check_size(spec, max_cells)
    cells: list[Cell] = []
    for kind in KINDS:
        if kind in spec.sections:
            seen: set[str] = set()
            for params in section_cells(spec.sections[kind], spec):
                tag = json.dumps(params, sort_keys=True)
                if tag not in seen:
                    seen.add(tag)
                    cells.append(Cell(kind, len(cells), params))
    return cells


def size(section: Section) -> tuple[int, list[str]]:
    """(the section's cells before equal ones merge, the factors in words)."""
    n, words = 1, []
    for name, values in section.axes.items():
        n *= len(values)
        if len(values) > 1:
            words.append(f"{len(values)} {name}")
    if section.random is not None:
        n *= section.random.n
        words.append(f"{section.random.n:,} random samples")
    return n, words


def check_size(spec: Spec, max_cells: int) -> None:
    """SpecError unless the spec makes at most `max_cells` cells (the limit named)."""
    if isinstance(max_cells, bool) or not isinstance(max_cells, int) or not 1 <= max_cells <= MAX_CELLS_CEILING:
        raise SpecError(f"--max-cells: expected an integer in [1, {MAX_CELLS_CEILING:,}], got {max_cells!r}")
    sizes = {kind: size(sec) for kind, sec in spec.sections.items()}
    total = sum(n for n, _ in sizes.values())
    if total <= max_cells:
        return
    limit = (f"more than the limit of {max_cells:,} cells (dampnet.sweep.grid.MAX_CELLS is {MAX_CELLS:,}; "
             f"--max-cells N raises it, up to {MAX_CELLS_CEILING:,})")
    for kind, sec in spec.sections.items():
        if sec.random is not None and sec.random.n > max_cells:
            line = _line_of(spec.text, f"{kind}.random", "n") if spec.text is not None else None
            where = f"line {line}: " if line else ""
            raise SpecError(f"{spec.source}: {where}{kind}.random.n: {sec.random.n:,} random samples, {limit}")
    parts = "; ".join(f"{kind} {n:,} ({' x '.join(words) or 'one cell'})" for kind, (n, words) in sizes.items())
    raise SpecError(f"{spec.source}: the spec makes up to {total:,} cells ({parts}), {limit}")


def section_cells(section: Section, spec: Spec | None = None) -> list[dict[str, Any]]:
    names = [p.name for p in section_params(section.kind) if p.name in section.axes]
    draws = draw(section.random) if section.random else [{}]
    if section.random is not None:
        check_draws(section, draws, spec)
    out = []
    for combo in itertools.product(*(section.axes[n] for n in names)):
        for d in draws:
            params = applicable(section.kind, {**dict(zip(names, combo)), **d})
            if section.kind == "fullcar":
                check_settings(params, spec)
            out.append(params)
    return out


def check_settings(params: dict[str, Any], spec: Spec | None) -> None:
    """SpecError when a full-vehicle cell's settings fail its test's check of them together
    (dampnet.recipes.maneuvers: a bounce sweep with nothing to measure), before anything runs."""
    from dampnet.recipes.maneuvers import get

    m = get(params["test"])
    if m.check is None:
        return
    chosen = {k: params[k] for k in m.defaults}
    try:
        m.check(chosen)
    except ValueError as e:
        given = ", ".join(f"{k} {v:g}" if isinstance(v, float) else f"{k} {v}" for k, v in chosen.items())
        raise SpecError(f"{spec.source if spec is not None else '<spec>'}: [fullcar] test {m.name} ({given}): "
                        f"{e}") from None


def draw(r: RandomSpec) -> list[dict[str, Any]]:
    """r.n samples: for each, one value per parameter (in sorted name order) from one generator."""
    rng = np.random.default_rng(r.seed)
    out = []
    for _ in range(r.n):
        d: dict[str, Any] = {}
        for name in sorted(r.dists):
            kind, args = r.dists[name]
            if kind == "uniform":
                d[name] = float(rng.uniform(args[0], args[1]))
            elif kind == "loguniform":
                d[name] = float(math.exp(rng.uniform(math.log(args[0]), math.log(args[1]))))
            elif kind == "normal":
                d[name] = float(rng.normal(args[0], args[1]))
            elif kind == "integers":
                d[name] = int(rng.integers(args[0], args[1] + 1))
            else:  # choice
                d[name] = args[int(rng.integers(len(args)))]
        out.append(d)
    return out


def check_draws(section: Section, draws: list[dict[str, Any]], spec: Spec | None) -> None:
    """SpecError naming the field when a sample is not a valid value of its parameter (a normal
    distribution's tail beyond a positive parameter's 0, say)."""
    params = {p.name: p for p in section_params(section.kind)}
    for i, d in enumerate(draws):
        for name, v in d.items():
            try:
                params[name].norm(v)
            except _Bad as e:
                raise SpecError(f"{_random_field(section, name, spec)}: sample {i} of the "
                                f"{section.random.dists[name][0]} distribution is out of the parameter's "
                                f"range ({e}): narrow the distribution") from None


def _random_field(section: Section, name: str, spec: Spec | None) -> str:
    """'FILE: line N: kind.random[.sub].key' for a drawn parameter, its key as the spec writes it."""
    p = {q.name: q for q in section_params(section.kind)}[name]
    sub, short = (name.split(".", 1) if "." in name else (None, name))
    table = f"{section.kind}.random" + (f".{sub}" if sub else "")
    raw = (spec.raw if spec is not None else {}).get(section.kind, {}).get("random", {})
    raw = raw.get(sub, {}) if sub else raw
    key = short if isinstance(raw, dict) and short in raw else p.key
    line = _line_of(spec.text, table, key) if spec is not None and spec.text is not None else None
    source = spec.source if spec is not None else "<spec>"
    return f"{source}: {f'line {line}: ' if line else ''}{table}.{key}"


def applicable(kind: str, params: dict[str, Any]) -> dict[str, Any]:
    """params with the ones that do not apply to this cell set to None."""
    p = dict(params)
    if kind == "training":
        if not str(p["dataset"]).startswith("rig:"):
            p["data_seed"] = p["rig_effects"] = None
        if p.get("restarts") == 1:      # one training: nothing to rank
            p["restart_score"] = None
    elif kind == "fullcar":
        from dampnet.recipes.maneuvers import SETTINGS, get

        defaults = get(p["test"]).defaults
        for name in SETTINGS:      # the test's settings (its default when not set), others empty
            p[name] = (defaults[name] if p.get(name) is None else p[name]) if name in defaults else None
        if p.get("road") is not None and p.get("road_seed") is not None:
            from dampnet.recipes import roads

            if not roads.is_named(p["road"]) or not roads.parse(p["road"]).takes("seed"):   # not random: no seed
                p["road_seed"] = None
    else:
        from dampnet.recipes import roads

        req = roads.parse(p["road"]) if roads.is_named(p["road"]) else None   # else a CSV distance profile
        if req is not None and req.profile == "temporal" and not req.takes("speed_m_s"):
            p["speed"] = None
        if req is None or not req.takes("seed"):
            p["road_seed"] = None
        if req is None or not req.takes("length_m"):
            p["road_length_m"] = None
    return p
