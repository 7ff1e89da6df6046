"""Restarts: train N times from different seeds, keep the model that fits the control levels best
and strays least between them (issue 18, robust training; issue 33, the combined score).

Why: a dyno campaign runs each test at one of a few control levels (voltages), so the network
sees the control input at a handful of values and is free in between. Early stopping watches
random samples, which all lie on those levels, so it cannot see a network that wiggles between
them; the held-out level (2.25 V) then lands in a wiggle for some seeds. Measured on the
5-frequency x 8-voltage plan (LM, 120 epochs, bench/experiments/restarts_seed_spread.py): held-out
NRMSE 0.0054-0.117 over seeds 0-9 with the same validation error.

What a restart run does (`train_restarts`, `train_dataset(..., restarts=N)`):
 1. Seeds: restart 0 uses `seed` itself (so its fit is exactly `restarts=1`'s), restart k the
    seed `restart_seeds` derives from (seed, k) (numpy SeedSequence, below 2^31).
 2. Every restart is scored on the training levels only (never the hold-out tests), in
    processes (`workers`, default the local cores, or this process for small problems, see
    SMALL_RESTARTS; one torch thread each). Parallel and serial
    runs give the same fits, scores and kept model (every fit runs with one thread).
 3. The restart with the lowest score is kept (the earliest on a tie); model.meta["restarts"]
    records every restart's seed, score and per-gap or per-level scores, and which was kept.
    The kept model is bit for bit `train_dataset(..., seed=its seed, restarts=1, threads=1)`.
 4. With `average` = K > 1 (interpolation score only), the K lowest-scored restarts are kept and
    averaged into one network of K times the width (dampnet.training.ensemble.average_networks: their
    mean output, exactly); meta["restarts"]["averaged"] lists them. Why: seeds scatter, and their
    mean less: on the demo's data (BR, 30 hidden) pairs of seeds are 2.17x the noise floor on the
    hold-out against 2.41x for one seed, and a single 60-hidden network 2.77x (bench/RESULTS.md
    "Inside the envelope"). The width must fit the runtime's DN_MAX_HIDDEN (384 in the Python module).

The scores (`restart_score`):
  "combined" (default): each restart is the ordinary full fit, scored by the root-sum-square of
      its held-back error (`held_back_nrmse`: its RMS error on the rows its fit held back, its
      validation and test rows, over the force range of the training samples: how well it fits
      the tested levels) and its interpolation score (next: how it behaves between them). A
      level between the tested ones sees both. It needs two training levels; it costs N fits.
  "interpolation": each restart is the ordinary full fit, scored by how far it strays,
      between adjacent training levels, from the smooth interpolation of its own predictions at
      those levels: on the training samples' kinematics, the model is evaluated at every level
      and at 1/4, 1/2 and 3/4 of every gap (the control-derived inputs, e.g. voltage_lag, set to
      the same value), the monotone cubic (PCHIP) through its values at the levels is the
      reference, and the score is the RMS difference at the gap points over the force range of
      the training samples. It needs two training levels; it costs N fits.
  "lolo": leave-one-level-out validation, the scheme issue 18 proposed: for each restart seed,
      fits on the training levels with one interior level withheld (LOLO_LEVELS interior levels,
      spread over them, never the lowest or highest: they cannot be interpolated), each scored by
      its NRMSE on the withheld level, the mean ranking the seeds; then the best seed's full fit
      is the model. It needs three training levels; it costs N x min(LOLO_LEVELS, interior) + 1
      fits.

Why "combined" is the default (issue 33, bench/LOG.md "Two restarts on the thesis plan"): with the
control prior (the default since issue 33) every network follows the smooth curve between the
levels, so what tells restarts apart is how well they fit the levels, which the interpolation score
does not see. On the thesis plan one single training in three settles in a worse minimum (4 V held
out: 0.0061-0.0068 against 0.0039-0.0040; validation NRMSE 0.0035-0.0036 against 0.0027-0.0028).
Over twenty 4 V fits the held-back error ranks the held-out error (Spearman 0.84), the
interpolation score does not (-0.10): two restarts ranked by it kept the worse one in 8 seeds of 10
(median 0.68x the lookup table, worse than one training's 0.60x), by the combined score in 2
(0.51x). On the 5 x 8 plan (LM, 3 restarts, every 4th sample, 120 epochs, seeds 0-6) the combined
score kept a restart held out better than the interpolation score's choice in 3 seeds of 7 and the
same one in the others (tests/python/test_train_restarts.py has seed 4). Without the prior (issue
18's case) the bend between levels is several times the held-back differences, and the combined
score keeps what the interpolation score kept (the same test file).

Why a full fit's score and not "lolo" (measured on the 5 x 8 plan, 80 LM fits of 10 base seeds x 8
restarts, and their leave-one-level-out fits; bench/LOG.md "Restarts"): a leave-one-level-out
fit is a different network from the full fit of the same seed (LM follows the data to a different
minimum), so its score says little about the model that is kept: Spearman 0.1-0.4 between a seed's
LOLO score and its full fit's held-out NRMSE, whichever levels are withheld, and the kept models'
spread stays 2-4x at 4-8 restarts. Keeping the LOLO fit itself instead throws a level of data
away and is worse on the hold-out (2-7x). Warm-starting the full fit from the best LOLO fit loses
what was scored (Spearman 0.1-0.5). The interpolation score judges the very model that is kept
and correlates with its held-out error (Spearman 0.75 on the 5 x 8 plan, 0.91 on the quick plan,
where no level is interior and LOLO cannot run at all), at a third of LOLO's cost.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import sys
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Callable

import numpy as np

from dampnet.data import DataError
from dampnet.signals import Deferred, children_ignore_interrupt, worker_ignores_interrupt
# the restart options' defaults and words live in the options table (dampnet.training.settings)
from dampnet.training.settings import BR_MAX_ROWS, DEFAULT_RESTARTS, DEFAULT_SCORE, RESTART_ROWS_BUDGET, SCORES

#: the fewest automatic restarts when the score can run
MIN_AUTO_RESTARTS = 1
#: how many interior levels the "lolo" score withholds, one per fit
LOLO_LEVELS = 2
#: the scores that rank each restart's own full fit (the kept model is the fit that was scored)
FULL_FIT_SCORES = ("combined", "interpolation")
#: where in each gap between adjacent training levels the interpolation score looks
GAP_FRACTIONS = (0.25, 0.5, 0.75)
#: training samples (evenly spaced) whose kinematics the interpolation score uses
SCORE_ROWS = 4000
#: below this many training rows x weights, workers=None runs the restarts in this process: starting
#: the worker processes (spawn, importing torch) costs ~3 s, more than such fits take (measured: the
#: quick plan at 4272 rows x 151 weights, 6 restarts, 3.9 s in one process and 4.5 s in two; the
#: demo's quick plan at 16359 rows, 15.5 s and 11.4 s)
SMALL_RESTARTS = 1_000_000


def check_average(average: Any, restarts: int, hidden, score: str = DEFAULT_SCORE) -> int:
    """`average` (restarts averaged into one network) as an int in 1..restarts whose averaged
    width fits the runtime; ValueError naming the field otherwise."""
    from dampnet.training.ensemble import check_width
    from dampnet.training.settings import option

    average = option("average", average)
    if average == 1:
        return 1
    if average > restarts:
        raise ValueError(f"average (--average): {average} restarts averaged, but only {restarts} restart(s) "
                         f"trained: train at least {average} (--restarts; 'auto' trains 1 when the training tests "
                         "have fewer than two control levels)")
    if score not in FULL_FIT_SCORES:
        raise ValueError(f"average: averaging keeps the best-scored full fits, which the {score!r} score does not "
                         f"train; use restart_score {' or '.join(repr(x) for x in FULL_FIT_SCORES)}")
    hidden = tuple(int(h) for h in hidden)
    if len(hidden) != 1:
        raise ValueError(f"average: only one-hidden-layer networks add up to one network; hidden is {hidden}")
    check_width([hidden[0]] * int(average))
    return int(average)


def check_restarts(restarts: Any, workers: Any = None, score: str = DEFAULT_SCORE) -> int:
    """`restarts` as an int in 1..MAX_RESTARTS; ValueError naming the field and its range otherwise
    (also for workers, score: dampnet.training.settings.OPTIONS)."""
    from dampnet.training.settings import option

    restarts = option("restarts", restarts)
    option("workers", workers)
    if score not in SCORES:
        raise ValueError(f"restart_score: expected one of {', '.join(SCORES)}, got {score!r}")
    return int(restarts)


def restart_seeds(seed: int, n: int) -> list[int]:
    """The seeds of n restarts: `seed` itself, then one derived from (seed, k) for each k >= 1."""
    return [int(seed)] + [int(np.random.SeedSequence([int(seed) & 0xFFFFFFFF, k]).generate_state(1)[0] & 0x7FFFFFFF)
                          for k in range(1, n)]


def training_levels(prep) -> list[float]:
    """The distinct nominal control levels of the training samples, ascending."""
    lv = prep.level[np.isfinite(prep.level)]
    return sorted({float(x) for x in np.unique(lv)})


def lolo_levels(levels: list[float], k: int = LOLO_LEVELS) -> list[float]:
    """Up to k interior levels (not the lowest or highest), spread evenly over the interior ones."""
    interior = levels[1:-1]
    if len(interior) <= k:
        return list(interior)
    idx = sorted({int(round(i)) for i in np.linspace(0, len(interior) - 1, k)})
    return [interior[i] for i in idx]


def auto_algorithm(rows: int) -> tuple[str, str]:
    """What `dampnet train` trains with without --algorithm, for `rows` training rows
    (training_rows): ("br" or "lm", why)."""
    from dampnet.training.settings import ALGORITHM_NAMES

    if rows <= BR_MAX_ROWS:
        return "br", f"{rows:,} training rows, at most {BR_MAX_ROWS:,}: {ALGORITHM_NAMES['br']}"
    return "lm", f"{rows:,} training rows, over {BR_MAX_ROWS:,}: {ALGORITHM_NAMES['lm']}"


def auto_restarts(ds, holdout_voltage=None, holdout_tests=(), features=None,
                  score: str = DEFAULT_SCORE, decimate: int | None = None,
                  average: int = 1, algorithm: str = "lm", rows: int | None = None) -> tuple[int, str | None]:
    """What `dampnet train` runs without --restarts: (1, why not) when `ds`'s training tests do not
    allow `score`; with Bayesian regularisation `average` (at least 1: its seeds agree, BR_MAX_ROWS);
    else DEFAULT_RESTARTS, fewer (not below MIN_AUTO_RESTARTS, nor `average`) when
    the training rows times the restarts would exceed RESTART_ROWS_BUDGET, with a note saying so.
    `rows`: the training rows when the caller has counted them (training_rows), else counted here."""
    from dampnet.features import FEATURES, default_features

    if not ds.tests:
        return 1, "no tests"
    if algorithm == "br":
        return max(1, int(average)), ("Bayesian regularisation's seeds agree, so one training per network "
                                      "averaged; --restarts N runs N")
    control = ds.tests[0].control_name
    feats = list(features) if features else default_features(ds)
    held = set(holdout_tests or ())
    levels = sorted({float(t.control_nominal) for t in ds.tests
                     if t.control_nominal is not None and t.test_id not in held
                     and not (holdout_voltage is not None and abs(t.control_nominal - holdout_voltage) <= 1e-6)})
    if not any(f in FEATURES and FEATURES[f].channel == control for f in feats):
        return 1, f"the control ({control}) is not a feature, so there are no levels to interpolate between"
    need = 3 if score == "lolo" else 2
    if len(levels) < need:
        return 1, (f"the training tests have {len(levels)} control level{'s' if len(levels) != 1 else ''} "
                   f"({', '.join(f'{x:g}' for x in levels) or 'none'}); the {score} score needs {need}")
    if rows is None:
        rows = training_rows(ds, holdout_voltage, holdout_tests, decimate)
    within = max(MIN_AUTO_RESTARTS, min(DEFAULT_RESTARTS, RESTART_ROWS_BUDGET // max(rows, 1)))
    n = max(within, int(average))
    if within >= DEFAULT_RESTARTS or n > within:
        return n, None  # the default, or what --average asks for
    return n, (f"not {DEFAULT_RESTARTS}: {rows:,} training rows, and the automatic restarts keep rows x restarts "
               f"near {RESTART_ROWS_BUDGET:,}; --restarts N runs N")


def training_rows(ds, holdout_voltage=None, holdout_tests=(), decimate: int | None = None) -> int:
    """The rows a training of `ds` fits: its training tests' samples after the decimation
    (`decimate`, or the pipeline's automatic one), without building the feature matrix."""
    from dampnet.data.preprocess import HOLDOUT_HINT, auto_decimate, decimated_rows, holdout_split

    # the pipeline's own split and decimation rule (prepare_training), and its error
    try:
        train = ds if holdout_voltage is None and not holdout_tests else \
            holdout_split(ds, holdout_voltage, list(holdout_tests or []))[0]
    except ValueError as e:
        raise DataError(f"{e} ({HOLDOUT_HINT})") from None
    if not train.tests:
        return 0
    return decimated_rows(train, int(decimate) if decimate else auto_decimate(train))


def _n_params(prep) -> int:
    sizes = [prep.X.shape[1], *prep.request.hidden, 1]
    return sum((a + 1) * b for a, b in zip(sizes[:-1], sizes[1:]))


def default_workers(n_jobs: int) -> int:
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    return max(1, min(cores, n_jobs))


# -- the interpolation score ------------------------------------------------------------------

def _control_columns(prep) -> list[int]:
    from dampnet.features import FEATURES

    return [j for j, f in enumerate(prep.features) if f in FEATURES and FEATURES[f].channel == prep.control_name]


def interpolation_score(model, prep, levels: list[float] | None = None) -> dict[str, Any]:
    """How far `model` strays between adjacent training levels from the monotone cubic through its
    own predictions at the levels: {"score": RMS over every gap point / force range, "gaps":
    {"a-b": the same per gap}} (see the module docstring)."""
    from scipy.interpolate import PchipInterpolator

    levels = training_levels(prep) if levels is None else levels
    cols = _control_columns(prep)
    if len(levels) < 2 or not cols:
        raise DataError("restarts: the interpolation score needs the control as a feature and at least two "
                        f"training control levels; the training tests have {len(levels)}")
    n = len(prep.X)
    rows = np.unique(np.linspace(0, n - 1, min(n, SCORE_ROWS)).round().astype(int))
    K = prep.X[rows].copy()

    def at(u: float) -> np.ndarray:
        K[:, cols] = u
        return np.asarray(model.predict(K), dtype=np.float64)

    F = np.array([at(u) for u in levels])
    span = float(np.ptp(prep.force)) or 1.0
    gaps, sq = {}, []
    for a, b in zip(levels[:-1], levels[1:]):
        pts = [a + (b - a) * f for f in GAP_FRACTIONS]
        ref = PchipInterpolator(levels, F, axis=0)(pts)
        d = np.array([at(u) for u in pts]) - ref
        sq.append(np.mean(d * d))
        gaps[f"{a:g}-{b:g}"] = float(np.sqrt(np.mean(d * d)) / span)
    return {"score": float(np.sqrt(np.mean(sq)) / span), "gaps": gaps}


def held_back_nrmse(model, info, prep) -> float:
    """`model`'s RMS error on the rows its fit held back (its validation and test rows: never trained
    on; all rows when it held none back) over the force range of the training samples, the
    interpolation score's span: how well it fits the tested levels."""
    from dampnet.predict import predict_force

    idx = np.concatenate([np.asarray(info.val_idx, dtype=np.int64), np.asarray(info.test_idx, dtype=np.int64)])
    if not len(idx):
        idx = np.arange(len(prep.X))
    pred = predict_force(model, prep.X[idx], None if prep.xd is None else prep.xd[idx],
                         **({} if prep.xd is None else {"v": prep.v[idx], "u": prep.u[idx]}))
    span = float(np.ptp(prep.force)) or 1.0
    return float(np.sqrt(np.mean((pred - prep.force[idx]) ** 2)) / span)


def ranking_score(score: str, res: dict) -> float:
    """A full fit's score under `score` (FULL_FIT_SCORES) from its parts: "combined" is the
    root-sum-square of its held-back error and its interpolation score, "interpolation" the latter."""
    if score == "combined":
        return float(np.hypot(res["held_back"], res["interpolation"]))
    return float(res["interpolation"])


#: what each score ranks by, for the command's summary line
SCORE_WORDS = {"combined": "held-back error and interpolation between levels",
               "interpolation": "interpolation between levels", "lolo": "leave-one-level-out NRMSE"}
#: each score in a sentence, for --restart-score's help and the demo's report
SCORE_HELP = {
    "combined": "the root-sum-square of each model's error on the training rows it held back (how well it fits "
                "the tested levels) and its interpolation score",
    "interpolation": "how far each model strays between adjacent levels from the smooth curve through its own "
                     "predictions at them",
    "lolo": "leave-one-level-out refits on interior levels, about 2x the cost and selects worse (bench/RESULTS.md)"}


#: the temporary hand-off file's name: this prefix, the parent's pid, a random part, .pickle
HANDOFF_PREFIX = "dampnet-restarts-"
#: how often the parent looks for a signal while the workers fit [s]
POLL_S = 0.1
#: how long stopped workers get to end on SIGTERM before SIGKILL [s]
STOP_WAIT_S = 3.0

# -- the jobs (run in worker processes or in-process) ---------------------------------------------

_PREP = None
#: the fit of one restart: dampnet.training.pipeline.fit_prepared, handed in by the caller (the
#: pipeline calls this module, so importing it back would make a cycle)
_FIT = None


def _init_worker(handoff: str) -> None:
    """Load what every job needs from the file _run wrote (`handoff`: the prepared samples, the fit
    and the run-time features), once per worker process."""
    import pickle

    import torch

    from dampnet.features import FEATURES, register_feature

    worker_ignores_interrupt()      # Ctrl-C reaches the whole group: the parent stops the workers
    _exit_with_parent()
    with open(handoff, "rb") as f:
        prep, fit, extra_features = pickle.load(f)
    torch.set_num_threads(1)
    for name, (unit, source, at_rest, param) in extra_features.items():
        if name not in FEATURES:
            register_feature(name, unit, source, at_rest, param)
    global _PREP, _FIT
    _PREP, _FIT = prep, fit


def _exit_with_parent() -> None:
    """End this worker as soon as the process that started it is gone. A parent killed outright
    (SIGKILL, the out-of-memory killer, a notebook kernel restarted) cannot stop its pool, and the
    workers would fit on for minutes for nobody. The parent's end of the pipe it started the worker
    through closes only when it exits or drops the worker, so a thread waits for that."""
    import threading
    from multiprocessing.connection import wait

    parent = multiprocessing.parent_process()
    if parent is None or parent.sentinel is None:
        return

    def watch() -> None:
        wait([parent.sentinel])
        os._exit(1)

    threading.Thread(target=watch, name="dampnet-restarts-parent-watch", daemon=True).start()


def _job(kind: str, seed: int, level: float | None) -> dict[str, Any]:
    """One fit of the restart run: ("full", seed) -> the model and its interpolation score;
    ("lolo", seed, level) -> the NRMSE on the withheld level of a fit without it."""
    from dampnet.training.metrics import nrmse
    fit_prepared = _FIT
    prep = _PREP
    t0 = time.perf_counter()
    if kind == "full":
        model, info = fit_prepared(prep, seed, threads=1)
        sc = interpolation_score(model, prep)
        return {"model": model, "info": info, "interpolation": sc["score"], "gaps": sc["gaps"],
                "held_back": held_back_nrmse(model, info, prep), "time_s": time.perf_counter() - t0}
    held = np.isclose(prep.level, level, rtol=0.0, atol=1e-6)
    model, info = fit_prepared(prep, seed, rows=~held, threads=1)
    from dampnet.predict import predict_force

    pred = predict_force(model, prep.X[held], None if prep.xd is None else prep.xd[held],
                         **({} if prep.xd is None else {"v": prep.v[held], "u": prep.u[held]}))
    return {"score": nrmse(pred, prep.force[held]), "time_s": time.perf_counter() - t0,
            "epochs": info.epochs}


def _extra_features(prep) -> dict[str, tuple]:
    """Features registered at run time (dampnet.features.register_feature): a spawned worker
    re-registers them."""
    from dampnet import _core
    from dampnet.features import FEATURES

    out = {}
    for f in prep.features:
        if f not in _core.FEATURE_NAMES and f in FEATURES:
            ft = FEATURES[f]
            out[f] = (ft.unit, ft.source, ft.at_rest, ft.param)
    return out


@contextlib.contextmanager
def _importable_main():
    """A spawned worker re-runs the parent's __main__ file; when that is no file (a script read
    from stdin, a notebook cell), hide its name while the workers start, so they skip it."""
    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    hide = path is not None and not os.path.isfile(path)
    if hide:
        del main.__file__
    try:
        yield
    finally:
        if hide:
            main.__file__ = path


#: why a restart worker process can die before its result, and what to do
WORKER_DIED = (
    "restarts: a worker process running the restarts in parallel died before returning its fit. If the "
    "calling script trains at its top level, put that code under `if __name__ == \"__main__\":` "
    "(each worker starts a fresh Python that imports the script, and a script that trains at import "
    "starts workers of its own, which Python refuses); otherwise the process was killed (e.g. out of "
    "memory). workers=1 runs the restarts in this process")


def _run(prep, fit, jobs: list[tuple], workers: int, done: Callable[[int, dict], None]) -> list[dict]:
    """Run `jobs` (argument tuples of _job), in-process when workers == 1; results in job order."""
    results: list[dict | None] = [None] * len(jobs)
    lean = prep.lean()
    if workers <= 1:
        global _PREP, _FIT
        old = _PREP, _FIT
        _PREP, _FIT = lean, fit
        try:
            for i, job in enumerate(jobs):
                results[i] = _job(*job)
                done(i, results[i])
        finally:
            _PREP, _FIT = old
        return results  # type: ignore[return-value]
    if getattr(multiprocessing.current_process(), "_inheriting", False):
        # This process is itself a worker still importing the calling script, which trains at its top
        # level: it could start no workers (Python refuses: multiprocessing's own test of this flag),
        # and a pool made first would leave its semaphores to the resource tracker, whose warning then
        # followed the parent's error. Stop here: the parent sees this worker die (WORKER_DIED).
        raise RuntimeError(WORKER_DIED)
    ctx = multiprocessing.get_context("spawn")  # no fork of a process with torch's threads running
    # Ctrl-C and SIGTERM only set a flag inside (dampnet.signals.Deferred): the loop stops the workers
    # itself, the hand-off file is removed, and then the signal is delivered again
    with Deferred() as stop, _handoff_file(lean, fit, _extra_features(prep)) as handoff, _importable_main():
        ex = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_init_worker,
                                 initargs=(handoff,))
        with children_ignore_interrupt():   # the workers are started by the first submit
            futures = {ex.submit(_job, *job): i for i, job in enumerate(jobs)}
        try:
            pending = set(futures)
            while pending:
                stop.check()
                finished, pending = wait(pending, timeout=POLL_S, return_when=FIRST_COMPLETED)
                for fut in finished:
                    i = futures[fut]
                    results[i] = fut.result()
                    done(i, results[i])
        except BrokenProcessPool as e:
            _stop_pool(ex)
            stop.check()        # SIGTERM to the process group ends the workers too: not their fault
            raise RuntimeError(WORKER_DIED) from e
        except BaseException:
            _stop_pool(ex)
            raise
        # every result is in: end the idle workers (waiting on their task queue, holding nothing the
        # parent needs). Their own exit, Python's teardown in a process that imported torch, takes
        # ~1.5 s, and the interpreter waits for it when this process exits (a Ctrl-C then found it
        # still waiting, 10 s and more on a loaded machine).
        _stop_pool(ex)
    return results  # type: ignore[return-value]


def _stop_pool(ex: ProcessPoolExecutor) -> None:
    """End the pool's workers now, mid-fit included (shutdown alone waits for the fits under way,
    minutes): SIGTERM each, then SIGKILL what is left after STOP_WAIT_S."""
    procs = list((getattr(ex, "_processes", None) or {}).values())
    manager = getattr(ex, "_executor_manager_thread", None)  # (shutdown forgets it: joined below)
    for p in procs:
        with contextlib.suppress(OSError, ValueError):
            p.terminate()
    ex.shutdown(wait=False, cancel_futures=True)
    deadline = time.monotonic() + STOP_WAIT_S
    for p in procs:
        with contextlib.suppress(OSError, ValueError, AssertionError):
            p.join(max(0.0, deadline - time.monotonic()))
            if p.is_alive():
                p.kill()
                p.join(1.0)
    # the workers are gone: wait for the pool's manager thread too, so that the interpreter's exit
    # does not wake it through the pipe it is closing (Python 3.11 printed "Bad file descriptor" after
    # "dampnet: terminated"). shutdown(wait=True) would not: shutdown(wait=False) above dropped the
    # executor's reference to the thread.
    if manager is not None:
        manager.join(STOP_WAIT_S)


@contextlib.contextmanager
def _handoff_file(*payload):
    """A private temporary file holding `payload` pickled, removed afterwards: what the workers load
    as they start. Handing the prepared samples (megabytes) over the spawn pipe instead blocks the
    parent until each worker has imported the main script, so the workers start one after another,
    and for ever when one dies importing it (a script without a main guard)."""
    import pickle
    import tempfile

    _remove_stale_handoffs()
    fd, path = tempfile.mkstemp(prefix=f"{HANDOFF_PREFIX}{os.getpid()}-", suffix=".pickle")
    try:
        with os.fdopen(fd, "wb") as f:
            pickle.dump(payload, f, protocol=pickle.HIGHEST_PROTOCOL)
        yield path
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path)


def _remove_stale_handoffs() -> None:
    """Remove this user's hand-off files whose process is gone: a parent killed outright (SIGKILL,
    the out-of-memory killer) cannot remove its own. The file's name holds the parent's pid."""
    import re
    import tempfile

    from dampnet.outputs import pid_alive

    folder = tempfile.gettempdir()
    pattern = re.compile(re.escape(HANDOFF_PREFIX) + r"(\d+)-\w+\.pickle\Z")
    with contextlib.suppress(OSError):
        for entry in os.scandir(folder):
            m = pattern.match(entry.name)
            if m is None or int(m.group(1)) == os.getpid():
                continue
            with contextlib.suppress(OSError):
                st = entry.stat(follow_symlinks=False)
                if entry.is_file(follow_symlinks=False) and st.st_uid == os.getuid() \
                        and not pid_alive(int(m.group(1))):
                    os.unlink(entry.path)


# -- the run --------------------------------------------------------------------------------------

def train_restarts(prep, fit_prepared: Callable, restarts: int, seed: int = 0, *, workers: int | None = None,
                   score: str = DEFAULT_SCORE,
                   progress: Callable[[dict], Any] | None = None, average: int = 1):
    """(model, info) of the best of `restarts` fits of the prepared samples (module docstring;
    with `average` > 1, the mean of the best `average` as one network, step 4).

    `fit_prepared(prep, seed, rows=None, threads=1) -> (model, info)` is one fit
    (dampnet.training.pipeline.fit_prepared; the pipeline checks the data's magnitudes first).

    `progress(record)` after every finished fit: {"done", "total", "restart", "seed", "score"
    (or the LOLO "level")}. DataError when the training tests have too few control levels for
    the score (interpolation: two; lolo: three, one of them interior).
    """
    restarts = check_restarts(restarts, workers, score)
    average = check_average(average, restarts, prep.request.hidden, score)
    levels = training_levels(prep)
    seeds = restart_seeds(seed, restarts)
    t0 = time.perf_counter()
    if score in FULL_FIT_SCORES:
        if len(levels) < 2 or not _control_columns(prep):
            raise DataError(f"restarts: scoring needs the control ({prep.control_name}) as a feature and at least "
                            f"two training control levels to interpolate between; the training tests have "
                            f"{len(levels)} ({', '.join(f'{x:g}' for x in levels) or 'none'}): use restarts=1")
        jobs = [("full", s, None) for s in seeds]
    else:
        withheld = lolo_levels(levels)
        if not withheld:
            raise DataError(f"restarts: leave-one-level-out needs an interior training control level (not the "
                            f"lowest or highest) to withhold; the training tests have {len(levels)} "
                            f"({', '.join(f'{x:g}' for x in levels) or 'none'}): use restart_score "
                            "'interpolation' or restarts=1")
        jobs = [("lolo", s, lv) for s in seeds for lv in withheld]
    total = len(jobs) + (1 if score == "lolo" else 0)
    if workers is None:
        n_workers = 1 if len(prep.X) * _n_params(prep) < SMALL_RESTARTS else default_workers(len(jobs))
    else:
        n_workers = min(int(workers), len(jobs))
    count = [0]

    def done(i: int, res: dict) -> None:
        count[0] += 1
        if progress is not None:
            kind, s, lv = jobs[i]
            rec = {"done": count[0], "total": total, "restart": seeds.index(s), "seed": s,
                   "score": ranking_score(score, res) if kind == "full" else res["score"]}
            if lv is not None:
                rec["level"] = lv
            progress(rec)

    results = _run(prep, fit_prepared, jobs, n_workers, done)
    runs = []
    if score in FULL_FIT_SCORES:
        for k, (s, res) in enumerate(zip(seeds, results)):
            runs.append({"restart": k, "seed": s, "score": round(ranking_score(score, res), 7),
                         "interpolation": round(res["interpolation"], 7), "held_back": round(res["held_back"], 7),
                         "gaps": {g: round(v, 7) for g, v in res["gaps"].items()},
                         "val_nrmse": round(res["info"].metrics.get("val", float("nan")), 7),
                         "epochs": res["info"].epochs, "time_s": round(res["time_s"], 3)})
        ranked = sorted(range(restarts), key=lambda k: (runs[k]["score"], k))
        best = ranked[0]
        model, info = results[best]["model"], results[best]["info"]
        info.restart_models = [res["model"] for res in results]
        if average > 1:
            model = _averaged(prep, [results[k]["model"] for k in ranked[:average]], info)
    else:
        per = len(withheld)
        for k, s in enumerate(seeds):
            chunk = results[k * per:(k + 1) * per]
            lv_scores = {f"{lv:g}": round(r["score"], 7) for lv, r in zip(withheld, chunk)}
            runs.append({"restart": k, "seed": s, "score": round(float(np.mean([r["score"] for r in chunk])), 7),
                         "levels": lv_scores, "time_s": round(sum(r["time_s"] for r in chunk), 3)})
        best = min(range(restarts), key=lambda k: (runs[k]["score"], k))
        t1 = time.perf_counter()
        model, info = fit_prepared(prep, seeds[best], threads=1)  # in this process, serial or not
        runs[best]["final_fit_time_s"] = round(time.perf_counter() - t1, 3)
        if progress is not None:
            progress({"done": total, "total": total, "restart": best, "seed": seeds[best], "final": True})
    for k, r in enumerate(runs):
        r["kept"] = k == best
    scores = [r["score"] for r in runs]
    model.meta["restarts"] = {
        "n": restarts, "score": score, "seed": int(seed), "kept": best, "kept_seed": seeds[best],
        **({"averaged": ranked[:average], "averaged_seeds": [seeds[k] for k in ranked[:average]]}
           if average > 1 else {}),
        "levels": levels, **({"withheld_levels": withheld} if score == "lolo" else {}),
        "score_min": min(scores), "score_max": max(scores),
        "workers": n_workers, "time_s": round(time.perf_counter() - t0, 3), "runs": runs,
    }
    return model, info


def _averaged(prep, models: list, info):
    """The models averaged into one network (dampnet.training.ensemble), with info.metrics re-measured for
    it: NRMSE on all training rows only. Each member drew its own train / validation / test split
    (its seed), so a row one member never saw another trained on: the averaged network has no
    held-out rows of its own (its hold-out is the held-out tests, as for any model)."""
    from dampnet.training.ensemble import average_networks
    from dampnet.training.metrics import nrmse
    from dampnet.predict import predict_force

    model = average_networks(models)
    pred = predict_force(model, prep.X, prep.xd, **({} if prep.xd is None else {"v": prep.v, "u": prep.u}))
    info.metrics = {"all": nrmse(pred, prep.force)}
    model.meta["metrics"] = {k: round(v, 6) for k, v in info.metrics.items()}
    return model


def summary_line(meta: dict[str, Any]) -> str:
    """Lines for the CLI: how many restarts, their score range, which was kept, and (when the
    record has it, dampnet.training.pipeline.restarts_holdout) the hold-out NRMSE's spread."""
    r = meta
    what = SCORE_WORDS.get(r["score"], r["score"])
    if r.get("averaged"):
        kept = (f"averaged the best {len(r['averaged'])} (restarts {', '.join(str(k) for k in r['averaged'])}) "
                "into one network")
    else:
        kept = f"kept restart {r['kept']} (seed {r['kept_seed']}, score {r['runs'][r['kept']]['score']:.4f})"
    line = (f"restarts: {r['n']} ({what}: {r['score_min']:.4f} to {r['score_max']:.4f}), {kept}, "
            f"{r['workers']} worker{'s' if r['workers'] != 1 else ''}, {r['time_s']:.1f} s")
    if "holdout_nrmse_min" in r:
        kept = (f"averaged ones {', '.join(format(r['runs'][k]['holdout_nrmse'], '.4f') for k in r['averaged'])}"
                if r.get("averaged") else f"kept {r['runs'][r['kept']]['holdout_nrmse']:.4f}")
        line += (f"\n  hold-out NRMSE over the restarts {r['holdout_nrmse_min']:.4f} to {r['holdout_nrmse_max']:.4f}, "
                 f"{kept} (shown after the fact; the choice never saw it)")
    if len(r.get("levels", [])) == 2:
        line += (f"\n  note: only two training control levels ({r['levels'][0]:g}, {r['levels'][1]:g}): between "
                 "them the data do not determine the model: the control prior (--control-prior, unless 0) holds it "
                 "near the straight line between them, as a lookup table interpolates, and the restarts keep the "
                 "one closest to it; test intermediate levels to know it")
    return line
