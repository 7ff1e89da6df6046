"""The results table: one row per cell, its parameters and its metrics (pandas; Parquet and CSV).

Columns, in order: cell (its key), kind (training / simulation / fullcar), status (ok / error), error
(the message, empty when ok); the parameters (lists as text: hidden "20-10", add and
rig_effects "a+b" or "none", features "velocity,acceleration,voltage" or "default"; a
parameter that does not apply to a cell is empty); the metrics (training: NRMSE = RMSE / force
range, errors in N; simulation: SI units, see dampnet.sim.ride; fullcar: units in the names, see
dampnet.sweep.metrics; a parameter or metric of another kind's cells shares a column only where
it has the same name, e.g. model, road_seed, acc_rms_m_s2; vehicle.m_s is the quarter car's in a
simulation row, the full car's in a fullcar row); time_s (the cell's wall time on
its worker, s), cpu_s (its worker's CPU time, s), worker (host:pid), model_dir (a training cell's model, relative to DIR).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from dampnet.sweep.grid import Cell
from dampnet.sweep.metrics import BY_KIND as METRICS
from dampnet.sweep.spec import KINDS, section_params

HEAD = ("cell", "kind", "status", "error")
TAIL = ("time_s", "cpu_s", "worker", "model_dir")
#: columns that differ between runs of the same cells (timings, where they ran)
VOLATILE = ("time_s", "cpu_s", "worker", "train_time_s")


def flat(name: str, v: Any) -> Any:
    """A parameter's value as a table cell."""
    if v is None and name == "features":
        return "default"
    if isinstance(v, list):
        if name == "hidden":
            return "-".join(str(h) for h in v)
        if name == "features":
            return ",".join(v)
        return "+".join(v) if v else "none"
    return v


def row(cell: Cell, rec: dict[str, Any]) -> dict[str, Any]:
    r: dict[str, Any] = {"cell": cell.key, "kind": cell.kind, "status": rec.get("status", "error"),
                         "error": rec.get("error")}
    r.update({k: flat(k, v) for k, v in cell.params.items()})
    r.update(rec.get("metrics") or {})
    r.update({"time_s": rec.get("time_s"), "cpu_s": rec.get("cpu_s"), "worker": rec.get("worker"),
              "model_dir": rec.get("model_dir")})
    return r


def columns(kinds: list[str], rows: list[dict[str, Any]]) -> list[str]:
    cols = list(HEAD)
    for kind in kinds:
        cols += [p.name for p in section_params(kind) if p.name not in cols]
    for kind in kinds:
        cols += [m for m in METRICS[kind]() if m not in cols]
    seen = set(cols) | set(TAIL)
    extra = []
    for r in rows:
        extra += [k for k in r if k not in seen and k not in extra]
    cols += extra + list(TAIL)
    present = set().union(*rows) if rows else set()
    return [c for c in cols if c in present or c in HEAD]


def frame(cells: list[Cell], records: dict[str, dict[str, Any]]):
    """The DataFrame of `cells` (spec order) with their records (every cell must have one)."""
    import pandas as pd

    rows = [row(c, records[c.key]) for c in cells]
    kinds = [k for k in KINDS if any(c.kind == k for c in cells)]
    df = pd.DataFrame(rows, columns=columns(kinds, rows))
    for col in df.columns:   # integer columns stay integers where other kinds leave them empty
        vals = [r.get(col) for r in rows]
        given = [v for v in vals if v is not None]
        if any(isinstance(v, str) for v in given) and not all(isinstance(v, str) for v in given):
            # a setting given as text in some cells and as a number in others (restarts = [1, "auto", 2]):
            # a text column, each cell as written (issue 49: Parquet refused the mixed column at the end)
            df[col] = pd.array([None if v is None else str(v) for v in vals], dtype="string")
        elif given and all(isinstance(v, int) and not isinstance(v, bool) for v in given):
            # from the Python integers, not from the float column pandas made of them (2**53 + 1
            # would come back as 2**53)
            df[col] = pd.array(vals, dtype="Int64")
    return df


def write_parquet(df, path: Path) -> None:
    df.to_parquet(path, engine="pyarrow", index=False)


def write_csv(df, path: Path) -> None:
    """Integer columns as integers (an empty field where a row has none): read them back as integers
    with pandas.read_csv(path, dtype_backend="numpy_nullable")."""
    df.to_csv(path, index=False)
