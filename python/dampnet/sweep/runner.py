"""Running a sweep on Dask: the cluster, the cells' submission, their results as they complete.

    df = run("sweep.toml", out="sweep-out")                       # an embedded LocalCluster
    df = run(spec, scheduler="tcp://host:8786", out="sweep-out")  # an existing Dask cluster
    df = run(spec, client=my_client)                              # a dask.distributed.Client of yours

The cluster. Default: a `LocalCluster` of `workers` processes (default: this machine's cores)
with one thread each, started for the sweep and closed after it. `scheduler=ADDRESS`
connects to an existing cluster instead (any deployment: dask-ssh, Kubernetes, an HPC job
queue); its workers need the same dampnet installed. Nothing else changes.

Faults. A cell that raises is a row with status "error" and the message (dampnet.sweep.tasks).
A worker that dies under a cell (a kill, a segfault, out of memory) is Dask's to handle: the
cell is given to another worker, up to the scheduler's allowed failures (the spec's
allowed_failures on the embedded cluster, default 3; an external scheduler's own setting);
after that the cell is a row with status "error" (KilledWorker). Each finished cell is saved
at once (dampnet.sweep.store), so Ctrl-C (KeyboardInterrupt) loses only the cells under way:
the remaining tasks are cancelled, DIR/sweep.json says "interrupted", and `--resume` computes
only the cells without a result (and those that failed).

Python scripts that start the embedded cluster need the `if __name__ == "__main__":` guard
(its workers are processes started by multiprocessing's spawn).
"""

from __future__ import annotations

import functools
import logging
import os
import time
import uuid
from contextlib import contextmanager, nullcontext
from pathlib import Path
from typing import Any, Callable, Iterator

from dampnet.sweep.grid import Cell, expand
from dampnet.sweep.inputs import bind, input_paths, load
from dampnet.sweep.progress import CellProgress
from dampnet.sweep.spec import DATA_MODES, Spec, SpecError, load_spec, parse_spec
from dampnet.sweep.store import Store, record
from dampnet.sweep.tasks import one_line, run_cell, warm

CONNECT_TIMEOUT_S = 20
#: DIR/sweep.json's counts are rewritten at most this often while cells complete [s] (the cells
#: themselves are saved at once; the counts are written again at the end or on an interruption)
STATE_EVERY_S = 1.0
MISSING = ("dampnet sweep needs dask[distributed], pandas and pyarrow (the sweep extra): "
           "pip install 'dampnet[sweep]'")


class SweepError(ValueError):
    """The sweep cannot run as asked (no cluster at the address, missing packages): one line."""


def require() -> None:
    """SweepError naming the sweep extra unless dask.distributed, pandas and pyarrow import."""
    try:
        import dask.distributed  # noqa: F401
        import pandas  # noqa: F401
        import pyarrow  # noqa: F401
    except ImportError as e:
        raise SweepError(f"{MISSING} ({e})") from None


def as_spec(spec: Spec | dict | str | os.PathLike) -> Spec:
    """A Spec from a Spec, a parsed TOML dict (paths relative to the working directory) or a file."""
    if isinstance(spec, Spec):
        return spec
    if isinstance(spec, dict):
        return parse_spec(spec, source="<spec>")
    return load_spec(spec)


def local_workers() -> int:
    """The cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


@contextmanager
def session(client=None, scheduler: str | None = None, workers: int | None = None,
            allowed_failures: int = 3) -> Iterator[tuple[Any, dict[str, Any]]]:
    """(client, {"scheduler", "workers"}): the caller's client, one connected to `scheduler`, or an
    embedded LocalCluster of `workers` single-threaded processes (closed on exit)."""
    from dask.distributed import Client, LocalCluster

    if client is not None:
        yield client, {"scheduler": client.scheduler.address, "workers": len(client.scheduler_info()["workers"])}
        return
    if scheduler:
        try:
            c = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError, ValueError) as e:
            raise SweepError(f"--scheduler {scheduler}: cannot connect to a Dask scheduler there ({one_line(e)})") from None
        try:
            yield c, {"scheduler": scheduler, "workers": len(c.scheduler_info()["workers"])}
        finally:
            c.close()
        return
    import dask

    n = workers or local_workers()
    with dask.config.set({"distributed.scheduler.allowed-failures": int(allowed_failures)}):
        # dashboard_address ":0": its HTTP server on a free port (8787 may be another cluster's)
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                               silence_logs=logging.ERROR, preload=["dampnet.sweep.tasks"])
    c = Client(cluster)
    try:
        yield c, {"scheduler": "local", "workers": n}
    finally:
        try:
            c.close()
        finally:
            cluster.close()


def run(spec: Spec | dict | str | os.PathLike, client=None, *, out: str | os.PathLike | None = None,
        resume: bool = False, force: bool = False, workers: int | None = None, scheduler: str | None = None,
        data: str | None = None, progress: bool | None = None,
        on_cell: Callable[[dict[str, Any], int, int], Any] | None = None):
    """Run every cell of `spec` and return the table (a pandas DataFrame, one row per cell).

    spec: a SPEC.toml path, its parsed dict, or a Spec. client: a dask.distributed.Client to run
    on (else `scheduler`'s address, else an embedded LocalCluster of `workers` processes).
    out: the sweep directory (cells saved as they finish, the model directories, the table,
    summary and plots); None keeps nothing on disk. resume: reuse out's finished cells; force:
    replace an existing out. data: "shared" or "ship" (overrides the spec's [sweep] data).
    progress: the stderr progress (None: on; dampnet.sweep.progress says what it prints).
    on_cell(record, done, total): called in this process after each cell is saved.

    df.attrs["sweep"]: {"computed", "reused" (cells), "workers", "scheduler", "data", and times [s]:
    "start_s" (starting or reaching the cluster), "cells_s" (the first submission to the last cell
    saved), "wall_s" (the call up to the table), "results_s" (writing the table, summary, plots)};
    summary.json has all but results_s.
    Raises SpecError / OutputError / SweepError (ValueErrors, one line) before any work on bad
    input; KeyboardInterrupt after saving the state (see the module docstring).
    """
    require()
    t0 = time.perf_counter()
    sp = as_spec(spec)
    if data is not None:
        if data not in DATA_MODES:
            raise SpecError(f"data: {data!r} is not a data mode; valid: {', '.join(DATA_MODES)}")
        sp.data = data
    if workers is not None and int(workers) < 1:
        raise SweepError(f"--workers: expected a number of worker processes >= 1, got {workers}")
    cells = expand(sp)
    bind(cells, sp)
    inputs = [*input_paths(cells), *([sp.source] if os.path.isfile(sp.source) else [])]
    store: Store | None = None
    records: dict[str, dict[str, Any]] = {}
    if out is not None and Store.check(out, resume=resume, force=force, inputs=inputs):
        records = Store(Path(out)).finished(c.key for c in cells)     # --resume: the finished cells
    todo = [c for c in cells if c.key not in records]
    stats: dict[str, Any] = {"computed": len(todo), "reused": len(records), "data": sp.data,
                             "scheduler": scheduler or ("client" if client is not None else "local"),
                             "workers": 0}
    t_start = time.perf_counter()
    cluster: Any = session(client, scheduler, workers, sp.allowed_failures) if todo else nullcontext((None, {}))
    with cluster as (c, info):
        stats.update(info)
        stats["start_s"] = time.perf_counter() - t_start
        if out is not None:     # written once the cluster is there: a failed start leaves DIR as it was
            store = Store.open(out, resume=resume, force=force, inputs=inputs)
            store.set_state(state="running", spec=sp.raw, spec_source=str(sp.source), cells=len(cells),
                            done=len(records), errors=0)
        if todo:
            try:
                t_cells = time.perf_counter()
                execute(c, todo, sp, store, records, progress, on_cell)
                stats["cells_s"] = time.perf_counter() - t_cells
            except BaseException:    # Ctrl-C, a lost scheduler: the saved cells stay, the state says so
                if store is not None:
                    store.set_state(state="interrupted", done=len(records),
                                    errors=sum(r["status"] != "ok" for r in records.values()))
                raise
    stats["wall_s"] = time.perf_counter() - t0
    from dampnet.sweep.table import frame

    df = frame(cells, records)
    if store is not None:
        t_results = time.perf_counter()
        write_results(store, df, sp, stats)
        stats["results_s"] = time.perf_counter() - t_results
    df.attrs["sweep"] = stats
    return df


def execute(client, todo: list[Cell], spec: Spec, store: Store | None, records: dict[str, dict],
            progress: bool | None, on_cell) -> None:
    """Submit `todo`, save each result as it completes (records[key] = its record)."""
    from dask.distributed import as_completed

    client.run(warm, sorted({c.kind for c in todo}))
    shipped: dict[str, Any] = {}
    if spec.data == "ship":
        for c in todo:
            for ref in c.inputs.values():
                if ref.shippable and ref.digest not in shipped:
                    shipped[ref.digest] = client.scatter(load(ref), broadcast=True, hash=False)
    token = uuid.uuid4().hex[:8]
    by_key: dict[str, tuple[Any, Cell]] = {}
    for c in todo:
        args = {role: shipped.get(r.digest, r) for role, r in c.inputs.items()}
        f = client.submit(run_cell, c.kind, c.params, args, key=f"dampnet-sweep-{c.key}-{token}", pure=False)
        by_key[f.key] = (f, c)
    bar = CellProgress(len(todo), enabled=progress is not False)
    pending = dict(by_key)
    last_state = time.monotonic()
    try:
        for f in as_completed([f for f, _ in by_key.values()]):
            cell = by_key[f.key][1]
            pending.pop(f.key, None)
            result = outcome(f, spec.allowed_failures)
            rec = store.save(cell, result) if store is not None else record(cell, result)
            records[cell.key] = rec
            f.release()
            bar.update(rec["status"] == "ok")
            if store is not None and time.monotonic() - last_state >= STATE_EVERY_S:
                last_state = time.monotonic()
                store.set_state(done=len(records), errors=sum(r["status"] != "ok" for r in records.values()))
            if on_cell is not None:
                on_cell(rec, bar.done, bar.total)
    except BaseException:
        try:
            client.cancel([f for f, _ in pending.values()])
        except Exception:  # the cluster may be going down already
            pass
        raise
    finally:
        bar.close()
        for f in shipped.values():
            f.release()


def outcome(f, allowed_failures: int) -> dict[str, Any]:
    """A finished future's result; a failed one's error as a result with status "error"."""
    if f.status == "finished":
        return f.result()
    if f.status == "cancelled":
        return {"status": "error", "error": "CancelledError: the cell's task was cancelled on the cluster"}
    exc = f.exception()
    from dask.distributed import KilledWorker

    if isinstance(exc, KilledWorker):
        return {"status": "error", "error": f"KilledWorker: a worker process died while running this cell, each "
                                            f"time it was tried (the scheduler's allowed failures; the embedded "
                                            f"cluster's is {allowed_failures})"}
    return {"status": "error", "error": one_line(exc)}


def _plot(df, kind: str, objective: str, sens: list, path: Path) -> None:
    from dampnet.sweep.plots import sensitivity_png

    sensitivity_png(df, kind, objective, sens, path)


def write_results(store: Store, df, spec: Spec, stats: dict[str, Any]) -> None:
    """The table (Parquet, CSV), summary.json / summary.txt and the sensitivity plots, then the state."""
    from dampnet.outputs import json_text
    from dampnet.sweep.summary import summary, text
    from dampnet.sweep.table import write_csv, write_parquet

    objectives = {k: s.objective for k, s in spec.sections.items()}
    summ = summary(df, objectives, stats)
    writers: dict[str, Callable[[Path], Any]] = {
        "results.parquet": lambda p: write_parquet(df, p),
        "results.csv": lambda p: write_csv(df, p),
        "summary.txt": lambda p: p.write_text(text(summ), encoding="utf-8"),
        "summary.json": lambda p: p.write_text(json_text(summ), encoding="utf-8"),
    }
    for kind, objective in objectives.items():
        if summ[kind]["sensitivity"]:
            writers[f"sensitivity_{kind}.png"] = functools.partial(
                _plot, df, kind, objective, summ[kind]["sensitivity"])
    store.publish(writers)
    store.set_state(state="complete", cells=int(len(df)), done=int(len(df)),
                    errors=int((df["status"] != "ok").sum()),
                    summary={k: summ[k] for k in ("ok", "errors", "computed", "reused", "wall_s")})
