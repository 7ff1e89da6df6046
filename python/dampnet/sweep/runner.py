"""Running a sweep on Dask: the cluster, the cells' submission, their results as they complete.

    df = run("sweep.toml", out="sweep-out")                       # an embedded LocalCluster
    df = run(spec, scheduler="tcp://host:8786", out="sweep-out")  # an existing Dask cluster
    df = run(spec, scheduler="scheduler.json", out="sweep-out")   # ... named by its scheduler file
    df = run(spec, client=my_client)                              # a dask.distributed.Client of yours

The cluster. Default: a `LocalCluster` of `workers` processes (default: this machine's cores)
with one thread each, started for the sweep and closed after it. `scheduler` connects to an
existing cluster instead (any deployment: dask-ssh, Kubernetes, an HPC job queue): its address,
or the JSON file a scheduler writes with `--scheduler-file` (the usual pattern on HPC systems,
where the scheduler's host is known only once its job runs). Nothing else changes.

Same dampnet everywhere. Every worker must run the client's dampnet (the same source hash,
dampnet.sweep.hashing.source_digest): the workers present when the sweep starts are compared
and a sweep with a differing worker is refused, naming it; a worker that joins later compares
itself before each cell and stops the sweep the same way.

Faults. A cell that raises is a row with status "error" and the message (dampnet.sweep.tasks).
A worker that dies under a cell (a kill, a segfault, out of memory) is Dask's to handle: the
cell is given to another worker, up to the scheduler's allowed failures (the spec's
allowed_failures on the embedded cluster, default 3; an external scheduler's own setting);
after that the cell is a row with status "error" (KilledWorker). Each finished cell is saved
at once (dampnet.sweep.store), so a stop loses only the cells under way: Ctrl-C
(KeyboardInterrupt), the scheduler going away (its cells cancelled: SweepInterrupted), or no
worker on the cluster for `worker_timeout` seconds (SweepInterrupted; a line on stderr after
NO_WORKER_NOTICE_S without one). Then the remaining tasks are cancelled, DIR/sweep.json says
"interrupted", and `--resume` computes only the cells without a result (and those that failed).

Python scripts that start the embedded cluster need the `if __name__ == "__main__":` guard
(its workers are processes started by multiprocessing's spawn).
"""

from __future__ import annotations

import functools
import json
import logging
import math
import os
import sys
import time
import uuid
from concurrent.futures import CancelledError
from contextlib import contextmanager, nullcontext
from pathlib import Path
from typing import Any, Callable, Iterator

from dampnet.sweep.grid import MAX_CELLS, Cell, expand
from dampnet.sweep.hashing import source_digest
from dampnet.sweep.inputs import bind, input_paths, load
from dampnet.sweep.progress import CellProgress
from dampnet.sweep.spec import DATA_MODES, Spec, SpecError, load_spec, parse_spec
from dampnet.sweep.store import Store, record
from dampnet.sweep.tasks import one_line, run_cell, warm

CONNECT_TIMEOUT_S = 20
#: default of --worker-timeout: how long a sweep waits on a cluster without any worker [s]
WORKER_TIMEOUT_S = 600.0
#: a cluster without a worker for this long is said on stderr [s]
NO_WORKER_NOTICE_S = 10.0
#: how often the cluster's workers are counted while no cell completes [s]
WATCH_EVERY_S = 1.0
#: the wait between two looks for completed cells [s]
POLL_S = 0.05
#: DIR/sweep.json's counts are rewritten at most this often while cells complete [s] (the cells
#: themselves are saved at once; the counts are written again at the end or on an interruption)
STATE_EVERY_S = 1.0
#: after a connection error, how long the client is given to notice that its scheduler is gone
#: before the error is reported as a broken connection instead [s]
LOST_NOTICE_S = 10.0
MISSING = ("dampnet sweep needs dask[distributed], pandas and pyarrow (the sweep extra): "
           "pip install 'dampnet[sweep]'")


class SweepError(ValueError):
    """The sweep cannot run as asked (no cluster at the address, missing packages): one line."""


class SweepInterrupted(SweepError):
    """The sweep stopped before its end (the scheduler went away, no worker, a worker running another
    dampnet): its finished cells are saved and --resume continues; one line."""


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


def scheduler_address(scheduler: str) -> str:
    """The address `scheduler` names: an address as it is, or the one in a Dask scheduler file
    (the JSON `dask scheduler --scheduler-file FILE` writes). SweepError for a file that is not one."""
    if "://" in scheduler or not (os.path.isfile(scheduler) or scheduler.endswith(".json")):
        return scheduler
    try:
        d = json.loads(Path(scheduler).read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError) as e:
        raise SweepError(f"--scheduler {scheduler}: cannot read it as a Dask scheduler file ({one_line(e)})") from None
    if not isinstance(d, dict) or not isinstance(d.get("address"), str) or not d["address"]:
        raise SweepError(f"--scheduler {scheduler}: not a Dask scheduler file (a JSON object with an \"address\", "
                         "as `dask scheduler --scheduler-file FILE` writes)")
    return d["address"]


@contextmanager
def quiet_distributed() -> Iterator[None]:
    """Nothing logged (e.g. distributed's tracebacks while a client that lost its scheduler closes:
    the sweep says what happened in one line)."""
    previous = logging.root.manager.disable
    logging.disable(logging.CRITICAL)
    try:
        yield
    finally:
        logging.disable(previous)


class SyncCancelRace(logging.Filter):
    """Drops one record: distributed's sync() (2026.8) schedules a `cancel` callback on Ctrl-C
    that reads its coroutine's `future` before the coroutine has assigned it when the interrupt
    comes early, a NameError tornado logs as a traceback ("Exception in callback"). The interrupt
    itself is handled (the sweep saves its state and says so in one line); every other record,
    and every other NameError, passes."""

    def filter(self, record: logging.LogRecord) -> bool:
        exc = record.exc_info[1] if record.exc_info else None
        if not isinstance(exc, NameError) or "'future'" not in str(exc) or exc.__traceback__ is None:
            return True
        tb = exc.__traceback__
        while tb.tb_next is not None:
            tb = tb.tb_next
        code = tb.tb_frame.f_code
        return not (code.co_name == "cancel"
                    and Path(code.co_filename).parts[-2:] == ("distributed", "utils.py"))


@contextmanager
def sync_cancel_race_dropped() -> Iterator[None]:
    """SyncCancelRace on tornado's callback logger while a sweep runs."""
    log = logging.getLogger("tornado.application")
    race = SyncCancelRace()
    log.addFilter(race)
    try:
        yield
    finally:
        log.removeFilter(race)


def close_client(c) -> None:
    """Close a client; quietly when it has lost its scheduler (its reconnection is cancelled)."""
    with quiet_distributed() if c.status != "running" else nullcontext():
        c.close()


@contextmanager
def session(client=None, scheduler: str | None = None, workers: int | None = None,
            allowed_failures: int = 3) -> Iterator[tuple[Any, dict[str, Any]]]:
    """(client, {"scheduler", "workers"}): the caller's client, one connected to `scheduler` (an
    address or a scheduler file), or an embedded LocalCluster of `workers` single-threaded
    processes (closed on exit)."""
    from dask.distributed import Client, LocalCluster

    source_digest()   # this process's dampnet, hashed before the workers start (they hash theirs)
    if client is not None:
        yield client, {"scheduler": client.scheduler.address, "workers": len(client.nthreads())}
        return
    if scheduler:
        address = scheduler_address(scheduler)
        try:
            c = Client(address, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError, ValueError) as e:
            raise SweepError(f"--scheduler {scheduler}: cannot connect to a Dask scheduler "
                             f"{'there' if address == scheduler else 'at ' + address} ({one_line(e)})") from None
        try:
            yield c, {"scheduler": scheduler, "workers": len(c.nthreads())}
        finally:
            close_client(c)
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
            close_client(c)
        finally:
            cluster.close()


def run(spec: Spec | dict | str | os.PathLike, client=None, *, out: str | os.PathLike | None = None,
        resume: bool = False, force: bool = False, workers: int | None = None, scheduler: str | None = None,
        data: str | None = None, progress: bool | None = None,
        on_cell: Callable[[dict[str, Any], int, int], Any] | None = None,
        worker_timeout: float = WORKER_TIMEOUT_S, max_cells: int = MAX_CELLS):
    """Run every cell of `spec` and return the table (a pandas DataFrame, one row per cell).

    spec: a SPEC.toml path, its parsed dict, or a Spec. client: a dask.distributed.Client to run
    on (else `scheduler`, an address or a scheduler file, else an embedded LocalCluster of
    `workers` processes). out: the sweep directory (cells saved as they finish, the model
    directories, the table, summary and plots); None keeps nothing on disk. resume: reuse out's
    finished cells; force: replace an existing out. data: "shared" or "ship" (overrides the
    spec's [sweep] data). progress: the stderr progress (None: on; dampnet.sweep.progress says
    what it prints). on_cell(record, done, total): called in this process after each cell is
    saved. worker_timeout: how long the sweep waits on a cluster without any worker before it
    stops [s]. max_cells: the most cells the spec may make (dampnet.sweep.grid.MAX_CELLS).

    df.attrs["sweep"]: {"computed", "reused" (cells), "workers", "scheduler", "data", and times [s]:
    "start_s" (starting or reaching the cluster), "cells_s" (the first submission to the last cell
    saved), "wall_s" (the call up to the table), "results_s" (writing the table, summary, plots)};
    summary.json has all but results_s.
    Raises SpecError / OutputError / SweepError (ValueErrors, one line) before any work on bad
    input; SweepInterrupted or KeyboardInterrupt after saving the state (see the module docstring).
    """
    require()
    t0 = time.perf_counter()
    if isinstance(worker_timeout, bool) or not isinstance(worker_timeout, (int, float)) \
            or not worker_timeout > 0:   # inf: wait for workers as long as it takes
        raise SweepError(f"--worker-timeout: expected a number of seconds > 0 (or inf), got {worker_timeout!r}")
    sp = as_spec(spec)
    if data is not None:
        if data not in DATA_MODES:
            raise SpecError(f"data: {data!r} is not a data mode; valid: {', '.join(DATA_MODES)}")
        sp.data = data
    if workers is not None and int(workers) < 1:
        raise SweepError(f"--workers: expected a number of worker processes >= 1, got {workers}")
    cells = expand(sp, max_cells)
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
    with sync_cancel_race_dropped(), cluster as (c, info):
        stats.update(info)
        stats["start_s"] = time.perf_counter() - t_start
        if out is not None:     # written once the cluster is there: a failed start leaves DIR as it was
            store = Store.open(out, resume=resume, force=force, inputs=inputs)
            store.set_state(state="running", spec=sp.raw, spec_source=str(sp.source), cells=len(cells),
                            done=len(records), errors=0)
        if todo:
            try:
                t_cells = time.perf_counter()
                execute(c, todo, sp, store, records, progress, on_cell,
                        Watch(c, stats["scheduler"], worker_timeout))
                stats["cells_s"] = time.perf_counter() - t_cells
            except BaseException as e:    # Ctrl-C, a lost scheduler: the saved cells stay, the state says so
                if store is not None:
                    store.set_state(state="interrupted", done=len(records),
                                    errors=sum(r["status"] != "ok" for r in records.values()))
                if isinstance(e, SweepInterrupted):
                    kept = (f"{len(records)} of {len(cells)} cells are saved in {out}: the same command with "
                            "--resume computes the others" if out is not None else "nothing was saved (no out)")
                    raise SweepInterrupted(f"{e}; {kept}") from None
                raise
    stats["wall_s"] = time.perf_counter() - t0
    from dampnet.sweep.table import frame

    df = frame(cells, records)
    if store is not None:
        t_results = time.perf_counter()
        publish_results(store, df, sp, stats)
        stats["results_s"] = time.perf_counter() - t_results
    df.attrs["sweep"] = stats
    return df


class Watch:
    """The cluster while the sweep waits on it: the scheduler still there, some worker on it."""

    def __init__(self, client, where: str, timeout_s: float, stream=None):
        self.client, self.where, self.timeout_s = client, where, timeout_s
        self.stream = stream or sys.stderr
        self.last = -math.inf           # when the workers were last counted (monotonic)
        self.empty_since: float | None = None
        self.said = False

    def lost(self) -> None:
        """SweepInterrupted when the client has lost its scheduler."""
        if self.client.status != "running":
            raise SweepInterrupted(f"the Dask scheduler ({self.where}) went away: the sweep stopped")

    def broken(self, error: Exception) -> SweepInterrupted:
        """The interruption for a connection that broke during a call (fetching a result, counting
        workers). The client may take a moment to see that its scheduler is gone, so it is given
        LOST_NOTICE_S; a scheduler still there is a broken connection, said with the error."""
        deadline = time.monotonic() + LOST_NOTICE_S
        while time.monotonic() < deadline:
            try:
                self.lost()
            except SweepInterrupted as e:
                return e
            time.sleep(0.1)
        return SweepInterrupted(f"the connection to the Dask scheduler ({self.where}) broke "
                                f"({one_line(error)}): the sweep stopped")

    def workers(self) -> int:
        self.lost()
        try:
            return len(self.client.nthreads())
        except OSError as e:             # the connection broke during the call
            raise self.broken(e) from None

    def check(self, force: bool = False) -> int | None:
        """Count the workers (at most every WATCH_EVERY_S unless `force`): a line on stderr once
        there has been none for NO_WORKER_NOTICE_S, SweepInterrupted after the timeout."""
        now = time.monotonic()
        if not force and now - self.last < WATCH_EVERY_S:
            return None
        self.last = now
        n = self.workers()
        if n:
            self.empty_since, self.said = None, False
            return n
        self.empty_since = self.empty_since if self.empty_since is not None else now
        waited = now - self.empty_since
        if waited >= self.timeout_s:
            raise SweepInterrupted(f"no worker on the Dask cluster ({self.where}) for {waited:.0f} s "
                                   f"(--worker-timeout {self.timeout_s:g}): the sweep stopped")
        if waited >= NO_WORKER_NOTICE_S and not self.said:
            self.said = True
            self.stream.write(f"dampnet sweep: no worker on the Dask cluster ({self.where}) for {waited:.0f} s: "
                              f"waiting for one, at most --worker-timeout {self.timeout_s:g} s\n")
            self.stream.flush()
        return 0

    def wait_for_workers(self) -> None:
        """Return once the cluster has a worker (SweepInterrupted after the timeout)."""
        while not self.check(force=True):
            time.sleep(min(WATCH_EVERY_S, 0.25))


def check_sources(client, source: str) -> None:
    """SweepError naming the workers whose dampnet is not this one (its source hash differs, or they
    cannot even compute it: an older dampnet)."""
    got = client.run(source_digest, on_error="return")
    bad = sorted(addr for addr, digest in got.items() if digest != source)
    if bad:
        names = ", ".join(bad[:5]) + (f" and {len(bad) - 5} more" if len(bad) > 5 else "")
        theirs = got[bad[0]]
        theirs = theirs[:12] if isinstance(theirs, str) else f"not computed: {one_line(theirs)}"
        raise SweepError(f"worker{'s' if len(bad) > 1 else ''} {names} run{'' if len(bad) > 1 else 's'} another "
                         f"dampnet than this client (source hash {theirs} there, {source[:12]} here; "
                         "dampnet.sweep.hashing): install this dampnet on every worker")


def execute(client, todo: list[Cell], spec: Spec, store: Store | None, records: dict[str, dict],
            progress: bool | None, on_cell, watch: Watch) -> None:
    """Submit `todo`, save each result as it completes (records[key] = its record)."""
    from dask.distributed import as_completed

    source = source_digest()
    watch.wait_for_workers()
    check_sources(client, source)
    client.run(warm, sorted({c.kind for c in todo}))
    shipped: dict[str, Any] = {}
    if spec.data == "ship":
        for c in todo:
            for ref in c.inputs.values():
                if ref.shippable and ref.digest not in shipped:
                    shipped[ref.digest] = client.scatter(load(ref), broadcast=True, hash=False)
    token = uuid.uuid4().hex[:8]
    # one map call (a single message to the scheduler: 4-5x faster than a submit per cell)
    futures = client.map(run_cell, [c.kind for c in todo], [c.params for c in todo],
                         [{role: shipped.get(r.digest, r) for role, r in c.inputs.items()} for c in todo],
                         [source] * len(todo), key=[f"dampnet-sweep-{c.key}-{token}" for c in todo], pure=False)
    by_key: dict[str, tuple[Any, Cell]] = {f.key: (f, c) for f, c in zip(futures, todo)}
    bar = CellProgress(len(todo), enabled=progress is not False)
    pending = dict(by_key)
    last_state = time.monotonic()
    try:
        done = as_completed([f for f, _ in by_key.values()])
        while pending:
            batch = done.next_batch(block=False)
            if not batch:
                watch.check()
                time.sleep(POLL_S)
                continue
            for f in batch:
                cell = by_key[f.key][1]
                result = outcome(f, spec.allowed_failures, watch)
                pending.pop(f.key, None)
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
        if client.status == "running":
            try:
                client.cancel([f for f, _ in pending.values()])
            except Exception:  # the cluster may be going down already
                pass
        raise
    finally:
        bar.close()
        if client.status == "running":
            for f in shipped.values():
                f.release()


def outcome(f, allowed_failures: int, watch: Watch) -> dict[str, Any]:
    """A finished future's result; a failed one's error as a result with status "error".
    SweepInterrupted for a task the cluster cancelled (the sweep never cancels one it waits for:
    the scheduler went away, or someone cancelled it) and for a worker running another dampnet."""
    if f.status == "finished":
        try:
            result = f.result()
        except (OSError, CancelledError) as e:  # the fetch broke, or the scheduler went away after the
            raise watch.broken(e) from None     # task finished (distributed's FutureCancelledError)
        if result.get("status") == "mismatch":
            raise SweepInterrupted(f"worker {result.get('worker')} runs another dampnet than this client (source "
                                   f"hash {str(result.get('source'))[:12]} there, {source_digest()[:12]} here; "
                                   "dampnet.sweep.hashing): install this dampnet on every worker")
        return result
    if f.status == "cancelled":
        watch.lost()
        raise SweepInterrupted(f"the Dask cluster ({watch.where}) cancelled a cell's task (another client, or a "
                               "scheduler restart): the sweep stopped")
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


def publish_results(store: Store, df, spec: Spec, stats: dict[str, Any]) -> None:
    """write_results; if that fails, the cells' records stay and the state says "failed" and why,
    not "running" (issue 49: a table that could not be written left a sweep that seemed alive)."""
    try:
        write_results(store, df, spec, stats)
    except BaseException as e:
        store.set_state(state="failed", error=f"writing the results: {type(e).__name__}: {e}"[:2000])
        raise


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
