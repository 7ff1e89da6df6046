"""A simulation run's directory, as `dampnet simulate` and `dampnet vehicle` write it: run.npz (the
arrays), metrics.json (its marker: the run's metadata with "schema", the verdict of its coverage at
the top), the plots, all written into a staging folder first and moved into place together
(dampnet.outputs.staged_files: a failure leaves the previous run as it was).

    QUARTER_CAR, FULL_CAR              the two kinds: schema, files, plot
    check(kind, out, inputs, force)    before the run: out is new, or a run of this kind (--force)
    save_quarter_car(out, res, spec, road_name, law)
    save_full_car(out, res, spec, title, plot)
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable

import numpy as np


@dataclass(frozen=True)
class RunKind:
    schema: str                   # metrics.json's "schema" (family/version)
    files: tuple[str, ...]        # every file a run of this kind may hold

    @property
    def family(self) -> str:
        """The schema without its version ("dampnet.simulate/"): what every version of the run starts with."""
        return schema_family(self.schema)


def schema_family(schema: str) -> str:
    """A run record's schema without its version: "dampnet.simulate/2" -> "dampnet.simulate/"."""
    return schema.split("/")[0] + "/"


# /2: the runtime's law names in "controller", no "backend" (the runtime's loop is the only one)
QUARTER_CAR = RunKind("dampnet.simulate/2", ("run.npz", "metrics.json", "time_history.png", "transmissibility.png",
                                             "coverage.png"))
FULL_CAR = RunKind("dampnet.vehicle/1", ("run.npz", "metrics.json", "vehicle.png", "coverage.png"))


def check(kind: RunKind, out: str | Path, inputs: Iterable[str], force: bool) -> None:
    """Before the run: `out` does not exist, or (force) holds a run of this kind (never an input)."""
    from dampnet.outputs import check_run_dir

    check_run_dir(Path(out), kind.files, "metrics.json", kind.family, list(inputs), force)


def _meta(kind: RunKind, res: dict, skip: tuple[str, ...]) -> dict[str, Any]:
    meta = {"schema": kind.schema, **{k: v for k, v in res.items() if k not in skip}}
    if "coverage" in res:   # a neural model: the verdict at the top (dampnet.envelope.coverage)
        meta["extrapolated"] = res["coverage"]["extrapolated"]
    return meta


def _publish(out: Path, writers: dict[str, Callable[[Path], Any]], stale: Iterable[str]) -> None:
    """Every file into a staging folder in out, then into place (metrics.json, the marker, last);
    then a file of an earlier run that this run does not write (`stale`: --force over another run)
    is removed. A failure before the move leaves the earlier run whole."""
    from dampnet.outputs import staged_files

    with staged_files(out) as tmp:
        for name, write in writers.items():
            write(tmp / name)
    for name in stale:
        if name not in writers and (out / name).exists():
            (out / name).unlink()


def save_quarter_car(out: str | Path, res: dict, spec, road_name: str, law: str) -> Path:
    """A quarter-car run (dampnet.sim.quarter_car.runs.simulate's result) into `out`."""
    from dampnet.outputs import json_text
    from dampnet.sim.plots import plot_run, plot_transmissibility

    out = Path(out)
    arrays = dict(res["arrays"])
    if "transmissibility" in res:
        for k in ("f_hz", "magnitude", "phase_rad"):
            arrays[f"transmissibility_{k}"] = res["transmissibility"][k]
    meta = _meta(QUARTER_CAR, res, ("arrays", "transmissibility"))
    writers: dict[str, Callable[[Path], Any]] = {
        "run.npz": lambda f: np.savez_compressed(f, **arrays),
        "time_history.png": lambda f: plot_run(res, f, f"{spec.name} on {road_name}, {law}")}
    if "transmissibility" in res:
        writers["transmissibility.png"] = lambda f: plot_transmissibility({spec.name: res}, f)
    if "coverage" in res:   # a neural model: its inputs over its training data
        from dampnet.envelope.coverage import quarter_car_inputs
        from dampnet.envelope.plot import plot_coverage

        writers["coverage.png"] = lambda f: plot_coverage(
            spec.obj, {road_name: quarter_car_inputs(spec.obj, res["arrays"])}, f, spec.meta.get("envelope"),
            f"{spec.name} on {road_name}, {law}: damper inputs")
    writers["metrics.json"] = lambda f: Path(f).write_text(json_text(meta))
    _publish(out, writers, QUARTER_CAR.files)
    return out


def save_full_car(out: str | Path, res: dict, spec, title: str, plot: Callable[[Path], Any]) -> Path:
    """A full-vehicle run (dampnet.recipes.maneuvers.run's result) into `out`; `plot(path)` draws
    vehicle.png (the manoeuvre's own plot: dampnet.recipes.maneuvers.plot)."""
    from dampnet.outputs import json_text

    out = Path(out)
    meta = _meta(FULL_CAR, res, ("arrays",))
    writers: dict[str, Callable[[Path], Any]] = {
        "run.npz": lambda f: np.savez_compressed(f, **res["arrays"]),
        "vehicle.png": plot}
    if "coverage" in res:
        from dampnet.envelope.coverage import fullcar_inputs
        from dampnet.envelope.plot import plot_coverage

        per = fullcar_inputs(spec.obj, res["arrays"])
        writers["coverage.png"] = lambda f: plot_coverage(
            spec.obj, {f"{spec.name} {c}": X for c, X in zip(("FL", "FR", "RL", "RR"), per)}, f,
            spec.meta.get("envelope"), f"{title}: damper inputs")
    writers["metrics.json"] = lambda f: Path(f).write_text(json_text(meta))
    _publish(out, writers, FULL_CAR.files)
    return out
