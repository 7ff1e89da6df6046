"""The function every worker runs: one cell, its error caught and recorded, its cost timed.

    run_cell(kind, params, inputs, source) -> {"status": "ok" | "error", "error", "metrics", ..., "time_s", "cpu_s", "worker"}

time_s: the cell's wall time on its worker [s]; cpu_s: the worker process's CPU time during it [s]
(below time_s when the machine's cores are shared with other work).

A cell that raises is a result with status "error" and its message (type: message, one line);
the sweep goes on. Only what kills the worker process (a segfault, a kill, out of memory)
escapes: Dask then runs the cell again on another worker (allowed failures).

A worker whose dampnet is not the client's (`source`: the client's source hash, see
dampnet.sweep.hashing) runs nothing: its result has status "mismatch", and the sweep stops
naming the worker (a worker that joined after the sweep's first check of the cluster).
"""

from __future__ import annotations

import os
import socket
import time
import traceback
from typing import Any

MAX_ERROR_CHARS = 500


def run_cell(kind: str, params: dict[str, Any], inputs: dict[str, Any], source: str | None = None) -> dict[str, Any]:
    from dampnet.sweep.hashing import source_digest
    from dampnet.sweep.inputs import materialise

    t0, c0 = time.perf_counter(), time.process_time()
    if source is not None and source_digest() != source:
        return {"status": "mismatch", "worker": worker_name(), "source": source_digest()}
    try:
        got = {role: materialise(v) for role, v in inputs.items()}
        if kind == "training":
            from dampnet.sweep import train_cell as cell
        elif kind == "fullcar":
            from dampnet.sweep import fullcar_cell as cell  # type: ignore[no-redef]
        else:
            from dampnet.sweep import sim_cell as cell  # type: ignore[no-redef]
        out = {"status": "ok", **cell.run(params, got)}
    except Exception as e:  # recorded in the table, never raised: the sweep goes on
        out = {"status": "error", "error": one_line(e),
               "traceback": "".join(traceback.format_exception(e))[-4000:]}
    out["time_s"] = time.perf_counter() - t0
    out["cpu_s"] = time.process_time() - c0
    out["worker"] = worker_name()
    return out


def worker_name() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


def one_line(e: BaseException) -> str:
    msg = " ".join(str(e).split()) or repr(e)
    text = f"{type(e).__name__}: {msg}"
    return text if len(text) <= MAX_ERROR_CHARS else text[:MAX_ERROR_CHARS - 3] + "..."


def dask_setup(worker=None) -> None:
    """The embedded cluster's worker preload: a worker ignores SIGINT. Ctrl-C in a terminal reaches
    every process of the foreground group; the client (the sweep) handles it, cancels the cells under
    way and closes the cluster, instead of every worker dying with its own traceback."""
    from dampnet.signals import worker_ignores_interrupt

    worker_ignores_interrupt()
    from dampnet.sweep.hashing import source_digest

    source_digest()     # this worker's dampnet as it starts (the client hashes its own then too)


def warm(kinds: list[str]) -> int:
    """Import what the cells of `kinds` need (torch for training) before the first cell: a worker's
    first cell then costs what the others cost. Returns the worker's pid."""
    import dampnet.sweep.inputs  # noqa: F401
    if "training" in kinds:
        import torch

        import dampnet.sweep.train_cell  # noqa: F401
        import dampnet.training.pipeline  # noqa: F401
        from dampnet.diagnosis import estimate  # noqa: F401

        torch.set_num_threads(1)
    if "simulation" in kinds:
        import dampnet.sim.quarter_car.runs  # noqa: F401
        import dampnet.sweep.sim_cell  # noqa: F401
    if "fullcar" in kinds:
        import dampnet.sim.full_car.runs  # noqa: F401
        import dampnet.sweep.fullcar_cell  # noqa: F401
    return os.getpid()
