"""The sweep directory DIR: its layout, its state, each cell's result written as it completes.

    DIR/sweep.json           the marker and the state: schema, the spec, running / interrupted /
                             complete, cells done and failed (rewritten as the sweep runs)
    DIR/cells/<key>.json     one finished cell (parameters, input hashes, status, error, metrics),
                             written atomically (temporary file + rename) when it completes
    DIR/models/<key>/        a training cell's model directory (model.json, metrics.json, model.h,
                             envelope.npz and envelope.json: the files `dampnet train` writes),
                             written before its cell file (dampnet.modeldir.save_model_dir)
    DIR/results.parquet, results.csv, summary.json, summary.txt, sensitivity_*.png
                             the table, the summary and the plots, written at the end

Rules: DIR is no input, holds none and is not inside an input directory (the cells check the
hash of every input directory, which a DIR inside one would change); a new DIR is created
through a staging directory (dampnet.outputs); an existing DIR is
refused unless --force (then it must be a sweep directory: sweep.json, and it is replaced as a
whole) or --resume (then it must be a sweep directory: its finished cells are kept, new cells
are added, the table, summary and plots are rewritten). A cell's file is only ever replaced by
a later run of the same key (--resume recomputing a failed cell).
"""

from __future__ import annotations

import datetime as _dt
import json
import os
from pathlib import Path
from typing import Any, Callable, Iterable

from dampnet.outputs import (OutputError, check_not_input, check_output_dir, is_kind, json_text, staged_dir,
                             staged_files, write_json)
from dampnet.sweep.grid import Cell
from dampnet.sweep.hashing import SCHEMA

STATE_FILE = "sweep.json"
CELLS_DIR = "cells"
MODELS_DIR = "models"


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


class Store:
    """An open sweep directory."""

    def __init__(self, root: Path):
        self.root = Path(root)
        self.cells = self.root / CELLS_DIR
        self.models = self.root / MODELS_DIR

    @staticmethod
    def check(out: str | os.PathLike, *, resume: bool, force: bool, inputs: Iterable[str] = ()) -> bool:
        """OutputError (one line) unless the sweep may write `out`; writes nothing. True when `out` is
        an existing sweep to resume, False when it is to be created (or replaced, with force)."""
        out = Path(out)
        inputs = list(inputs)
        if resume and force:
            raise OutputError(f"{out}: --resume keeps its finished cells, --force replaces it: choose one")
        # nor inside an input directory: its content hash, checked by every cell, would change
        check_not_input(out, inputs, "sweep directory", inside=True)
        if resume and os.path.lexists(out):
            if out.is_symlink() or not out.is_dir() or not is_kind(out, "sweep"):
                raise OutputError(f"{out}: is not a dampnet sweep directory (no {STATE_FILE} of a sweep): "
                                  "cannot resume it")
            return True
        if os.path.lexists(out) and not force:
            raise OutputError(f"{out}: exists; refusing to overwrite (use --force to replace it, or --resume "
                              "to continue that sweep)")
        check_output_dir(out, "sweep", inputs, force)
        return False

    @classmethod
    def open(cls, out: str | os.PathLike, *, resume: bool, force: bool, inputs: Iterable[str] = ()) -> "Store":
        """The sweep directory `out`: reopened (resume), or created / replaced (force) through a staging
        directory. OutputError (one line) when that is not allowed (Store.check)."""
        store = cls(Path(out))
        if cls.check(out, resume=resume, force=force, inputs=inputs):
            store.cells.mkdir(exist_ok=True)
            store.models.mkdir(exist_ok=True)
            return store
        with staged_dir(store.root) as tmp:
            (tmp / CELLS_DIR).mkdir()
            (tmp / MODELS_DIR).mkdir()
            write_json(tmp / STATE_FILE, {"schema": SCHEMA, "state": "created", "created": _now()})
        return store

    # -- the state
    def state(self) -> dict[str, Any]:
        try:
            d = json.loads((self.root / STATE_FILE).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return {}
        return d if isinstance(d, dict) else {}

    def set_state(self, **fields: Any) -> None:
        d = {**self.state(), "schema": SCHEMA, **fields, "updated": _now()}
        write_json(self.root / STATE_FILE, d, overwrite=True)

    # -- cells
    def cell_path(self, key: str) -> Path:
        return self.cells / f"{key}.json"

    def finished(self, keys: Iterable[str]) -> dict[str, dict[str, Any]]:
        """The records of the cells among `keys` that finished without error (what --resume reuses)."""
        out = {}
        for k in keys:
            try:
                rec = json.loads(self.cell_path(k).read_text(encoding="utf-8"))
            except (OSError, ValueError):
                continue
            if isinstance(rec, dict) and rec.get("key") == k and rec.get("status") == "ok":
                if rec.get("kind") == "training" and not (self.root / str(rec.get("model_dir", ""))
                                                          / "model.json").is_file():
                    continue  # its model directory is gone: compute it again
                out[k] = rec
        return out

    def save(self, cell: Cell, result: dict[str, Any]) -> dict[str, Any]:
        """Write one finished cell: its model directory first (training), then cells/<key>.json
        (the cell counts as finished once that file exists). Returns the record."""
        rec = record(cell, result)
        model = result.get("model")
        if rec["status"] == "ok" and model is not None:
            from dampnet.model import MlpModel
            from dampnet.modeldir import save_model_dir

            rel = f"{MODELS_DIR}/{cell.key}"
            save_model_dir(MlpModel.from_dict(model, f"cell {cell.key}"), result.get("metrics_json"),
                           self.root / rel, force=True, envelope=result.get("envelope"))
            rec["model_dir"] = rel
        write_json(self.cell_path(cell.key), rec, overwrite=True)
        return rec

    def publish(self, writers: dict[str, Callable[[Path], Any]]) -> None:
        """Write the result files: each one built in a staging directory, then renamed into place."""
        with staged_files(self.root) as tmp:
            for name, write in writers.items():
                write(tmp / name)


def record(cell: Cell, result: dict[str, Any]) -> dict[str, Any]:
    """A cell's JSON record: what it was (parameters, inputs by content hash) and what it gave."""
    rec = {
        "schema": SCHEMA, "key": cell.key, "kind": cell.kind, "params": cell.params,
        "inputs": {role: {"text": r.text, "digest": r.digest, "path": r.path} for role, r in cell.inputs.items()},
        "status": result.get("status", "error"), "error": result.get("error"),
        "metrics": result.get("metrics", {}), "time_s": result.get("time_s"), "cpu_s": result.get("cpu_s"),
        "worker": result.get("worker"),
        "finished": _now(),
    }
    for k in ("traceback", "controller_settings", "law", "attempts"):
        if result.get(k) is not None:
            rec[k] = result[k]
    return json.loads(json_text(rec))   # the JSON form (NaN -> null), as it is read back
