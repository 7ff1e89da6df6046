"""Issue 49, items 4 and 5: Ctrl-C and SIGTERM end `dampnet train --restarts 4 --workers 2` at once,
workers included, at any moment, and leave nothing behind: no process, no hand-off pickle in
$TMPDIR, no leaked semaphore, no half-written model, no traceback (dampnet.signals).

Before: Ctrl-C hung the parent in 2 runs of 5 (locks of the process pool cut mid-way, or
shutdown waiting for the fits under way), SIGTERM left the pickle and the workers, and every
worker printed a KeyboardInterrupt traceback.

Cost: one uninterrupted run (the module's reference time T, 6-12 s on 2 cores) and 10 runs
signalled at random moments in [1.5 s, 0.9 T], two at a time: 2 tests of about 15-35 s (there
were 20 runs in 4 tests until the suite's time had to fall; the 10 kept are the first two
chunks' seeds).
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from dampnet.data import write_dataset
from dampnet.rig import generate
from dampnet.training import restarts

TRAIN = ["--restarts", "4", "--workers", "2", "--algorithm", "lm", "--max-epochs", "30", "--decimate", "10",
         "--hidden", "4", "--quiet", "--valve", "off"]   # one way: valve auto's second training adds nothing here
#: the bound of the issue: every run ends this long after the signal [s]
END_WITHIN_S = 10.0
#: before this, the interpreter may still be importing dampnet.cli (Python's own Ctrl-C then) [s]
EARLIEST_S = 1.5
CHUNKS, PER_CHUNK = 2, 5
#: runs signalled at once in a test
CONCURRENT = 2


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("signals") / "quick"
    write_dataset(generate("quick", seed=0), folder)
    return folder


def _train(dataset: Path, work: Path) -> tuple[subprocess.Popen, Path]:
    """`dampnet train` in its own process group (a terminal's Ctrl-C reaches the whole group), with
    its own $TMPDIR so that a pickle left behind is seen."""
    tmp = work / "tmp"
    tmp.mkdir(parents=True)
    proc = subprocess.Popen([sys.executable, "-m", "dampnet.cli", "train", str(dataset), *TRAIN,
                             "--out", str(work / "model")], cwd=work, env={**os.environ, "TMPDIR": str(tmp)},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    return proc, tmp


def _group(pgid: int) -> list[int]:
    """The live (not zombie) processes of process group `pgid`."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        if int(fields[2]) == pgid and fields[0] != "Z":
            found.append(int(stat.parent.name))
    return found


@pytest.fixture(scope="module")
def full_run_s(dataset, tmp_path_factory) -> float:
    """How long the run takes uninterrupted; it succeeds and leaves no pickle."""
    work = tmp_path_factory.mktemp("uninterrupted")
    t0 = time.monotonic()
    proc, tmp = _train(dataset, work)
    _, err = proc.communicate(timeout=300)
    took = time.monotonic() - t0
    assert proc.returncode == 0, err
    assert (work / "model" / "model.json").is_file() and not list(tmp.iterdir())
    return took


#: what _interrupted says of a run that had ended before its signal (nothing was tested)
ENDED_BEFORE = "ended before the signal"


def _interrupted(dataset: Path, work: Path, at_s: float, sig: int) -> str | None:
    """Send `sig` to the run's process group `at_s` after its start; what went wrong, or None."""
    proc, tmp = _train(dataset, work)
    time.sleep(at_s)
    if proc.poll() is not None:
        proc.communicate()
        return ENDED_BEFORE
    os.killpg(proc.pid, sig)
    t0 = time.monotonic()
    try:
        _, err = proc.communicate(timeout=END_WITHIN_S)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        return f"still running {END_WITHIN_S:g} s after the signal"
    while _group(proc.pid) and time.monotonic() - t0 < END_WITHIN_S:
        time.sleep(0.05)
    left = _group(proc.pid)
    for pid in left:
        os.kill(pid, signal.SIGKILL)
    expected = {signal.SIGINT: (130, "dampnet: interrupted"), signal.SIGTERM: (143, "dampnet: terminated")}[sig]
    problems = []
    if left:
        problems.append(f"processes {left} alive {END_WITHIN_S:g} s after the signal")
    finished = (work / "model" / "model.json").is_file()
    if proc.returncode == -sig and finished and not err.strip():
        pass    # came as Python shut down, the run's work done: the signal's own action, rightly
    elif proc.returncode == -sig and err.strip().splitlines()[-1:] == [expected[1]]:
        pass    # the run stopped and said so, then the signal's default action ended the process (a
        #         shell reports the same as for 128 + the signal; seen once in about 80 signalled runs)
    elif proc.returncode != 0 and (proc.returncode, err.strip().splitlines()[-1:]) != (expected[0], [expected[1]]):
        problems.append(f"exit {proc.returncode}, stderr ending {err.strip()[-300:]!r}")
    if "Traceback" in err or "leaked" in err:
        problems.append(f"stderr: {err.strip()[-600:]!r}")
    if list(tmp.iterdir()):
        problems.append(f"left in $TMPDIR: {sorted(p.name for p in tmp.iterdir())}")
    if (work / "model").exists() and not finished:
        problems.append("a half-written model folder")
    if set(os.listdir(work)) - {"tmp", "model"}:
        problems.append(f"left beside the model: {sorted(set(os.listdir(work)) - {'tmp', 'model'})}")
    return "; ".join(problems) or None


@pytest.mark.parametrize("chunk", range(CHUNKS))
def test_a_signal_at_a_random_moment_ends_the_run_at_once_and_leaves_nothing(chunk, dataset, full_run_s, tmp_path):
    """Ctrl-C (SIGINT) or SIGTERM, chosen at random, at PER_CHUNK random moments of the run: start-up,
    the workers importing, fitting, handing back their models, the evaluation, the writing."""
    rng = random.Random(49_000 + chunk)
    plan = [(rng.uniform(EARLIEST_S, max(EARLIEST_S, 0.9 * full_run_s)), rng.choice([signal.SIGINT, signal.SIGTERM]))
            for _ in range(PER_CHUNK)]

    def one(k: int) -> str | None:
        at, sig = plan[k]
        try:
            return _interrupted(dataset, tmp_path / f"run{k}", at, sig)
        except Exception as e:  # noqa: BLE001 - reported with the moment
            return repr(e)

    # two runs at a time (each its own process group and $TMPDIR): the driver mostly waits
    with ThreadPoolExecutor(max_workers=CONCURRENT) as pool:
        problems = list(pool.map(one, range(PER_CHUNK)))
    failures, tested = [], 0
    for (at, sig), problem in zip(plan, problems):
        if problem == ENDED_BEFORE:
            continue
        tested += 1
        if problem:
            failures.append(f"{signal.Signals(sig).name} at {at:.2f} s (of {full_run_s:.1f} s): {problem}")
    assert not failures, "\n".join(failures)
    assert tested >= PER_CHUNK - 1, f"only {tested} of {PER_CHUNK} runs were still running at their signal"


def test_a_killed_parents_hand_off_file_is_removed_by_the_next_run(tmp_path, monkeypatch):
    """SIGKILL cannot be caught: the hand-off pickle of a parent killed outright stays, and the next
    restart run removes it (its name holds the dead parent's pid); a live process's file, and files
    of other names, are kept. Cost: 0.1 s."""
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    monkeypatch.setattr("tempfile.tempdir", None)
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = tmp_path / f"{restarts.HANDOFF_PREFIX}{dead.pid}-abc_123.pickle"
    live = tmp_path / f"{restarts.HANDOFF_PREFIX}{os.getppid()}-def456.pickle"
    other = tmp_path / "dampnet-restarts-notes.txt"
    for f in (stale, live, other):
        f.write_bytes(b"x")
    with restarts._handoff_file({"payload": 1}) as path:
        assert Path(path).parent == tmp_path and Path(path).name.startswith(f"{restarts.HANDOFF_PREFIX}{os.getpid()}-")
        assert not stale.exists() and live.exists() and other.exists()
    assert not Path(path).exists()


@pytest.mark.parametrize("terminated", [False, True], ids=["SIGINT", "SIGTERM"])
def test_a_signal_a_c_extension_turned_into_its_import_error_ends_the_run_as_the_signal(terminated, monkeypatch, capsys):
    """A signal that arrives while a C extension initialises comes back as that extension's own
    ImportError('initialization failed'), raised from the interrupt (pybind11; a fresh-clone suite
    run saw it once, SIGINT while scipy's HiGHS module initialised, in the random-moment test
    above): the CLI ends as for the signal itself, its one line and status. An import error with no
    interrupt behind it still propagates. Cost: < 0.1 s."""
    import argparse

    from dampnet import cli, signals

    stop = signals.Terminated() if terminated else KeyboardInterrupt()

    def interrupted_import(args):
        try:
            raise stop
        except KeyboardInterrupt as e:
            raise ImportError("initialization failed") from e

    def broken_import(args):
        raise ImportError("No module named 'nowhere'")

    def parser_with(handler):
        p = argparse.ArgumentParser()
        p.set_defaults(handler=handler, version=False)
        return p

    monkeypatch.setattr(cli, "build_parser", lambda: parser_with(interrupted_import))
    assert cli.main([]) == (signals.TERMINATED_STATUS if terminated else signals.INTERRUPTED_STATUS)
    assert capsys.readouterr().err.strip().splitlines()[-1] == ("dampnet: terminated" if terminated else "dampnet: interrupted")
    monkeypatch.setattr(cli, "build_parser", lambda: parser_with(broken_import))
    with pytest.raises(ImportError, match="nowhere"):
        cli.main([])


SWALLOWED = r"""
import os, signal, sys, time, weakref
from dampnet import signals
signals.terminate_as_exception()
sig = signal.SIGTERM if sys.argv[1] == "SIGTERM" else signal.SIGINT
class A: pass
def cb(ref):  # a weakref callback, as importlib's module-lock clean-up is: what it raises is dropped
    os.kill(os.getpid(), sig)
    x = 0
    for _ in range(100): x += 1  # the handler runs at one of these bytecodes, inside the callback
a = A(); r = weakref.ref(a, cb)
t0 = time.monotonic()
try:
    del a
    while time.monotonic() - t0 < 5.0: pass
    print("not stopped")
except signals.Terminated:
    print("terminated", time.monotonic() - t0)
except KeyboardInterrupt:
    print("interrupted", time.monotonic() - t0)
"""


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
def test_a_signal_raised_inside_a_weakref_callback_is_delivered_again(sig):
    """A signal whose exception Python would print and drop (raised inside a weakref callback: the
    fresh-clone suite's random-moment test once hit importlib's module-lock callback, and the run
    went on to the end) is delivered again once the callback has returned (signals'
    unraisablehook): the run stops within a second (measured ~7 ms) and prints no 'Exception
    ignored'; without the hook it ran its 5 s and printed the dropped traceback. Cost: 0.3 s."""
    out = subprocess.run([sys.executable, "-c", SWALLOWED, sig], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    word, took = out.stdout.split()
    assert word == {"SIGINT": "interrupted", "SIGTERM": "terminated"}[sig], out.stdout
    assert float(took) < 1.0, out.stdout
    assert out.stderr == "", out.stderr
