"""A spec's cells: every grid point x every random sample, parameters that do not apply dropped.

    for cell in expand(spec): cell.kind, cell.params (a JSON-able dict, the table's columns)

A parameter that does not apply to a cell is None there and does not make cells differ: a
dataset read from a path has no data_seed or rig_effects, a time profile (impulse, sweep)
no speed, a road that is not random no road_seed, a road that is not iso:X no road_length_m; a
full-vehicle cell's bounce sweep (bsst) no speed, lane change (dlc) no profile or road_seed, and
only a bsst has a mode and the bsst_* settings. A full-vehicle dlc or road cell without a speed
gets its test's (dlc 120, road 60 km/h, as `dampnet vehicle`).
Cells with equal parameters are one cell.
"""

from __future__ import annotations

import itertools
import json
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dampnet.sweep.spec import KINDS, SEEDED_ROADS, TEMPORAL_ROADS, RandomSpec, Section, Spec, section_params


@dataclass
class Cell:
    """One unit of work: kind "training", "simulation" or "fullcar", its parameters, its position in the spec."""

    kind: str
    index: int
    params: dict[str, Any]
    key: str = ""                                   # set by dampnet.sweep.inputs.bind (a hash)
    inputs: dict[str, Any] = field(default_factory=dict)   # role -> InputRef, set by bind


def expand(spec: Spec) -> list[Cell]:
    """The cells of every section of `spec` (training, simulation, fullcar), in grid order."""
    cells: list[Cell] = []
    for kind in KINDS:
        if kind in spec.sections:
            seen: set[str] = set()
            for params in section_cells(spec.sections[kind]):
                tag = json.dumps(params, sort_keys=True)
                if tag not in seen:
                    seen.add(tag)
                    cells.append(Cell(kind, len(cells), params))
    return cells


def section_cells(section: Section) -> list[dict[str, Any]]:
    names = [p.name for p in section_params(section.kind) if p.name in section.axes]
    draws = draw(section.random) if section.random else [{}]
    out = []
    for combo in itertools.product(*(section.axes[n] for n in names)):
        for d in draws:
            params = {**dict(zip(names, combo)), **d}
            out.append(applicable(section.kind, params))
    return out


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


def applicable(kind: str, params: dict[str, Any]) -> dict[str, Any]:
    """params with the ones that do not apply to this cell set to None."""
    p = dict(params)
    if kind == "training":
        if not str(p["dataset"]).startswith("rig:"):
            p["data_seed"] = p["rig_effects"] = None
    elif kind == "fullcar":
        from dampnet.fullcar.runs import DEFAULT_SPEED_KMH

        test = p["test"]
        if test != "bsst":
            p["mode"] = None
            for k in ("bsst_amplitude_m", "bsst_f0_hz", "bsst_f1_hz", "bsst_rate_oct_s"):
                p[k] = None
        if test == "bsst":
            p["speed_kmh"] = None
        elif p["speed_kmh"] is None:
            p["speed_kmh"] = DEFAULT_SPEED_KMH[test]
        if test != "road":
            p["profile"] = p["road_seed"] = None
    else:
        road = str(p["road"]).lower()
        if road in TEMPORAL_ROADS:
            p["speed"] = None
        if road not in SEEDED_ROADS and not road.startswith("iso:"):
            p["road_seed"] = None
        if not road.startswith("iso:"):
            p["road_length_m"] = None
    return p
