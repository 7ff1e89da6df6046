"""A cell's inputs (datasets, models, road files): what they are, their content hash, how a
worker gets them.

    bind(cells, spec)      every cell's InputRefs and key (one content hash per distinct input)
    load(ref)              the object an input holds (Dataset, DamperSpec, Road)
    materialise(value)     on a worker: a shipped object as it is, or an InputRef loaded by path

Two ways for a worker to get an input (the spec's [sweep] data, or --data):
  "shared": the task carries the input's path (absolute, as the client sees it) and the worker
            reads it: every worker must see the same filesystem at the same paths. The worker
            checks the content hash it reads against the client's (a file changed or different
            on that machine is an error, never a silently different result); loaded once per
            worker process.
  "ship":   the client reads each input once and scatters it to every worker
            (`client.scatter(obj, broadcast=True)`); tasks get the worker's copy, no path.
Generated inputs are built on the worker from the cell's parameters in both modes: rig:PLAN
datasets (with data_seed and rig_effects), the roads by name (with road_seed), 'truth' and
'linear:C' dampers; 'default' is the default model of the worker's dampnet, checked by hash.
"""

from __future__ import annotations

import os
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any

from dampnet.sweep.grid import Cell
from dampnet.sweep.hashing import cell_key, content_digest, file_digest, text_digest
from dampnet.recipes import roads
from dampnet.sweep.spec import Spec, resolve, section_params

_CACHE_SIZE = 8


class InputChanged(RuntimeError):
    """A worker read an input whose content is not what the client hashed."""


@dataclass(frozen=True)
class InputRef:
    """One input: role "dataset" | "model" | "road"; `text` as the spec says; `path` the file or
    directory read (absolute), None when generated or built in; `digest` its content hash (of the
    text for generated inputs)."""

    role: str
    text: str
    path: str | None
    digest: str
    payload: Any = None     # a rig plan read from its JSON file (travels with the task)

    @property
    def shippable(self) -> bool:
        return self.path is not None


def reference(role: str, text: str, spec: Spec) -> InputRef:
    """The InputRef of a spec value (its content hashed now)."""
    if role == "dataset" and text.startswith("rig:"):
        plan = text[4:]
        if plan in ("thesis", "quick"):
            return InputRef(role, text, None, text_digest(text))
        from dataclasses import asdict

        from dampnet.rig.plans import load_plan

        p = resolve(plan, spec.base)
        return InputRef(role, text, None, text_digest("rig:" + file_digest(p)), asdict(load_plan(str(p))))
    if role == "model":
        if text == "default":
            from dampnet.modeldir import default_model_path

            return InputRef(role, text, None, file_digest(default_model_path()))
        if text == "truth" or text.startswith(("truth:", "linear:")):
            return InputRef(role, text, None, text_digest(text))
        p = resolve(text, spec.base)
        p = p / "model.json" if p.is_dir() else p
        return InputRef(role, text, str(p.resolve()), file_digest(p))
    if role == "road" and roads.is_named(text):
        return InputRef(role, text, None, text_digest(text.lower()))
    p = resolve(text, spec.base).resolve()
    return InputRef(role, text, str(p), content_digest(p))


def bind(cells: list[Cell], spec: Spec) -> None:
    """Set every cell's inputs (role -> InputRef) and key; each distinct input is hashed once."""
    refs: dict[tuple[str, str], InputRef] = {}
    roles = {kind: [(p.name, p.input) for p in section_params(kind) if p.input] for kind in spec.sections}
    for c in cells:
        c.inputs = {}
        digests = {}
        for name, role in roles[c.kind]:
            text = c.params[name]
            if text is None:      # not this cell's input (a [fullcar] test without a road)
                continue
            if (role, text) not in refs:
                refs[(role, text)] = reference(role, text, spec)
            c.inputs[role] = refs[(role, text)]
            digests[name] = refs[(role, text)].digest
        c.key = cell_key(c.kind, c.params, digests)


def input_paths(cells: list[Cell]) -> list[str]:
    """Every input file or directory the cells read (for the output directory's checks)."""
    return sorted({r.path for c in cells for r in c.inputs.values() if r.path})


def load(ref: InputRef) -> Any:
    """The object behind a file-backed input: a Dataset, a DamperSpec, a Road."""
    if ref.path is None:
        raise ValueError(f"{ref.text}: a generated {ref.role} has no file to load")
    if ref.role == "dataset":
        from dampnet.data import load_dataset

        return load_dataset(ref.path)
    if ref.role == "model":
        from dampnet.sim.dampers import load_spec

        return load_spec(ref.path)
    from dampnet.sim.roads import read_profile_csv

    return read_profile_csv(ref.path)


_loaded: OrderedDict[str, Any] = OrderedDict()


def materialise(value: Any) -> Any:
    """On a worker: an InputRef read by path (content checked, cached per process), or a shipped
    object as it is. Generated inputs (no path) are returned as their InputRef."""
    if not isinstance(value, InputRef) or value.path is None:
        return value
    if value.digest in _loaded:
        _loaded.move_to_end(value.digest)
        return _loaded[value.digest]
    if not os.path.exists(value.path):
        raise FileNotFoundError(f"{value.path}: no such {value.role} on this worker (the sweep reads inputs by "
                                "path: a shared filesystem is needed, or use data = \"ship\")")
    if content_digest(value.path) != value.digest:
        raise InputChanged(f"{value.path}: this {value.role} differs from the one the sweep hashed when it "
                           "started (changed since, or another file at this path on this worker)")
    obj = load(value)
    _loaded[value.digest] = obj
    while len(_loaded) > _CACHE_SIZE:
        _loaded.popitem(last=False)
    return obj
