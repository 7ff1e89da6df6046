"""`dampnet sweep` and its cluster (issue 29): a scheduler killed mid-sweep stops it as "interrupted"
(one line, no traceback, non-zero exit) and --resume continues; a cluster without workers is said
on stderr and given up after --worker-timeout; --scheduler takes a Dask scheduler file; a worker
running another dampnet is refused by name; cells are keyed on dampnet's source hash (a changed
dampnet computes them again); integer columns read back from the CSV as integers.

The killed scheduler is a real `dask scheduler` process with a worker process, on the loopback
interface only, started by the test; the other tests share one embedded cluster of one worker.
Tiny sweeps: linear dampers on short roads (a tenth of a second a cell)."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import needs

for _module in ("dask.distributed", "pandas", "pyarrow"):
    needs.need_module(_module)

import pandas as pd  # noqa: E402

from dampnet.cli import main  # noqa: E402
from dampnet.sweep import SweepError, run  # noqa: E402
from dampnet.sweep import hashing  # noqa: E402
from dampnet.sweep.runner import SweepInterrupted, session  # noqa: E402

#: 12 cells of about 0.3 s each on one worker: time to kill the scheduler in the middle
SLOW = ("[simulation]\nmodels = ['linear:1500']\nroads = ['iso:B']\nroad_seeds = [0, 1, 2, 3, 4, 5]\n"
        "road_length_m = 600.0\nspeeds = [5.0, 8.0]\n")
SMALL = {"simulation": {"models": ["linear:1500", "linear:2500"], "roads": ["impulse"]}}


@pytest.fixture(scope="module")
def client():
    with session(workers=1) as (c, info):
        assert info == {"scheduler": "local", "workers": 1}
        yield c


def start(args: list[str], log: Path) -> subprocess.Popen:
    """A process in its own group (killed with its children at the end), output to `log`."""
    with open(log, "wb") as f:
        return subprocess.Popen(args, stdout=f, stderr=subprocess.STDOUT, start_new_session=True)


def stop(p: subprocess.Popen) -> None:
    if p.poll() is None:
        os.killpg(p.pid, signal.SIGKILL)
    p.wait(timeout=30)


def wait_for(cond, what: str, timeout: float = 60.0, procs=()) -> None:
    deadline = time.monotonic() + timeout
    while not cond():
        for p in procs:
            assert p.poll() is None, f"{p.args[:3]} ended (exit {p.returncode}) while waiting for {what}"
        assert time.monotonic() < deadline, f"no {what} after {timeout} s"
        time.sleep(0.05)


def test_a_killed_scheduler_interrupts_the_sweep_and_resume_continues(client, tmp_path):
    spec = tmp_path / "s.toml"
    spec.write_text(SLOW)
    sched_file, out = tmp_path / "scheduler.json", tmp_path / "o"
    scheduler = start([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", "0",
                       "--no-dashboard", "--scheduler-file", str(sched_file)], tmp_path / "scheduler.log")
    procs = [scheduler]
    try:
        wait_for(sched_file.exists, "scheduler file", procs=procs)
        procs.append(start([sys.executable, "-m", "distributed.cli.dask_worker", "--scheduler-file", str(sched_file),
                            "--host", "127.0.0.1", "--nthreads", "1", "--no-dashboard"], tmp_path / "worker.log"))
        sweep = subprocess.Popen([sys.executable, "-m", "dampnet.cli", "sweep", str(spec), "--scheduler",
                                  str(sched_file), "--out", str(out), "--quiet"],
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
        procs.append(sweep)
        wait_for(lambda: len(list((out / "cells").glob("*.json"))) >= 2, "2 finished cells", procs=procs)
        os.kill(scheduler.pid, signal.SIGKILL)
        _, err = sweep.communicate(timeout=120)
    finally:
        for p in procs:
            stop(p)
    assert sweep.returncode == 2, err
    assert "Traceback" not in err and err.count("\n") == 1, err
    assert err.startswith("dampnet: error: the Dask scheduler") and "went away" in err, err
    assert f"are saved in {out}: the same command with --resume computes the others" in err, err
    saved = [json.loads(p.read_text()) for p in (out / "cells").glob("*.json")]
    state = json.loads((out / "sweep.json").read_text())
    assert state["state"] == "interrupted" and state["done"] == len(saved) and 2 <= len(saved) < 12, state
    assert all(r["status"] == "ok" for r in saved)          # no "cancelled" rows: those cells were not run
    assert not (out / "results.parquet").exists()
    df = run(spec, client=client, out=out, resume=True, progress=False)
    assert df.attrs["sweep"]["reused"] == len(saved) and df.attrs["sweep"]["computed"] == 12 - len(saved)
    assert len(df) == 12 and (df["status"] == "ok").all()
    assert json.loads((out / "sweep.json").read_text())["state"] == "complete"


class _Client:
    """A client that notices its scheduler is gone `after` seconds after the connection broke."""

    def __init__(self, after: float):
        self.broke, self.after = time.monotonic(), after

    @property
    def status(self) -> str:
        return "closed" if time.monotonic() - self.broke >= self.after else "running"

    def nthreads(self):
        raise ConnectionResetError(104, "Connection reset by peer")


class _Future:
    status = "finished"

    def result(self):
        raise ConnectionResetError(104, "Connection reset by peer")


def test_a_connection_broken_before_the_client_notices_is_the_scheduler_going_away(monkeypatch):
    """CI once saw the killed scheduler as a ConnectionResetError fetching a finished cell's result:
    the client had not yet noticed. Such an error waits for the client's notice; a scheduler that
    stays is a broken connection, said with its error."""
    import dampnet.sweep.runner as runner

    watch = runner.Watch(_Client(after=0.3), "tcp://here:1", 60.0)
    with pytest.raises(SweepInterrupted, match=r"^the Dask scheduler \(tcp://here:1\) went away"):
        runner.outcome(_Future(), 3, watch)
    watch = runner.Watch(_Client(after=0.3), "tcp://here:1", 60.0)
    with pytest.raises(SweepInterrupted, match="went away"):
        watch.check(force=True)
    monkeypatch.setattr(runner, "LOST_NOTICE_S", 0.2)
    watch = runner.Watch(_Client(after=math.inf), "tcp://here:1", 60.0)
    with pytest.raises(SweepInterrupted, match=r"connection to the Dask scheduler \(tcp://here:1\) broke "
                                               r"\(ConnectionResetError.*Connection reset by peer\)"):
        runner.outcome(_Future(), 3, watch)


def test_a_cluster_without_workers_says_so_and_stops_after_the_timeout(tmp_path, capsys, monkeypatch):
    from dask.distributed import LocalCluster

    import dampnet.sweep.runner as runner

    monkeypatch.setattr(runner, "NO_WORKER_NOTICE_S", 0.5)
    spec = tmp_path / "s.toml"
    spec.write_text("[simulation]\nmodels = ['linear:1500']\nroads = ['impulse', 'bump']\n")
    with LocalCluster(n_workers=0, processes=False, host="127.0.0.1", protocol="tcp", dashboard_address=None) as empty:
        capsys.readouterr()
        rc = main(["sweep", str(spec), "--scheduler", empty.scheduler_address, "--out", str(tmp_path / "o"),
                   "--worker-timeout", "2", "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2, err
    assert len(err) == 2 and "Traceback" not in "".join(err), err
    assert err[0].startswith("dampnet sweep: no worker on the Dask cluster") and "--worker-timeout 2 s" in err[0]
    assert err[1].startswith("dampnet: error: no worker on the Dask cluster") and "(--worker-timeout 2)" in err[1]
    assert "0 of 2 cells are saved" in err[1] and "--resume" in err[1]
    assert json.loads((tmp_path / "o" / "sweep.json").read_text())["state"] == "interrupted"
    for bad in ("0", "-1", "nan"):
        rc = main(["sweep", str(spec), "--out", str(tmp_path / "x"), "--worker-timeout", bad])
        err = capsys.readouterr().err
        assert rc == 2 and err.count("\n") == 1 and "--worker-timeout: expected a number of seconds > 0" in err, err
    assert not (tmp_path / "x").exists()


def test_a_scheduler_file_names_the_cluster(client, tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text("[simulation]\nmodels = ['linear:1500']\nroads = ['impulse']\n")
    good = tmp_path / "scheduler.json"
    good.write_text(json.dumps({"type": "Scheduler", "address": client.scheduler.address}))
    capsys.readouterr()
    assert main(["sweep", str(spec), "--scheduler", str(good), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["scheduler"] == str(good) and summary["workers"] == 1 and summary["ok"] == 1
    for name, text, fragment in [("a.json", "{\"type\": \"Scheduler\"}", "not a Dask scheduler file"),
                                 ("b.json", "not json", "cannot read it as a Dask scheduler file"),
                                 ("missing.json", None, "cannot read it as a Dask scheduler file")]:
        f = tmp_path / name
        if text is not None:
            f.write_text(text)
        rc = main(["sweep", str(spec), "--scheduler", str(f), "--out", str(tmp_path / "x")])
        err = capsys.readouterr().err
        assert rc == 2 and err.count("\n") == 1 and f"--scheduler {f}: {fragment}" in err, err
    assert not (tmp_path / "x").exists()


def set_workers_source(client, value):
    """Set every worker's cached source hash (None: compute it again); returns the old ones."""
    return client.run(lambda: (lambda h, old: (setattr(h, "_source", value), old)[1])(
        __import__("dampnet.sweep.hashing", fromlist=["_source"]),
        __import__("dampnet.sweep.hashing", fromlist=["_source"])._source))


def test_a_worker_running_another_dampnet_is_refused_by_name(client, tmp_path, monkeypatch):
    import dampnet.sweep.runner as runner

    old = set_workers_source(client, "0" * 64)
    try:
        (addr,) = old
        with pytest.raises(SweepError) as e:
            run(SMALL, client=client, out=tmp_path / "o", progress=False)
        msg = str(e.value)
        assert msg.startswith(f"worker {addr} runs another dampnet than this client (source hash 000000000000 "
                              f"there, {hashing.source_digest()[:12]} here") and "\n" not in msg, msg
        assert json.loads((tmp_path / "o" / "sweep.json").read_text())["state"] == "interrupted"
        # a worker that joins after the first check: it checks itself before each cell
        monkeypatch.setattr(runner, "check_sources", lambda client, source: None)
        with pytest.raises(SweepInterrupted) as e:
            run(SMALL, client=client, out=tmp_path / "p", progress=False)
        pid = client.run(os.getpid)[addr]
        assert str(e.value).startswith(f"worker {os.uname().nodename}:{pid} runs another dampnet") or \
            f":{pid} runs another dampnet" in str(e.value), str(e.value)
        assert not list((tmp_path / "p" / "cells").glob("*.json"))
    finally:
        client.run(lambda: setattr(__import__("dampnet.sweep.hashing", fromlist=["_source"]), "_source",
                                   old[next(iter(old))]))


def test_the_cells_are_keyed_on_dampnet_s_source_hash(client, tmp_path, monkeypatch):
    first = run(SMALL, client=client, out=tmp_path / "o", progress=False)
    again = run(SMALL, client=client, out=tmp_path / "o", resume=True, progress=False)
    assert again.attrs["sweep"]["reused"] == 2 and list(again["cell"]) == list(first["cell"])
    # another commit of dampnet (its __version__ unchanged): every cell is computed again
    old = set_workers_source(client, "f" * 64)
    try:
        monkeypatch.setattr(hashing, "_source", "f" * 64)
        other = run(SMALL, client=client, out=tmp_path / "o", resume=True, progress=False)
    finally:
        client.run(lambda: setattr(__import__("dampnet.sweep.hashing", fromlist=["_source"]), "_source",
                                   old[next(iter(old))]))
    assert other.attrs["sweep"]["computed"] == 2 and other.attrs["sweep"]["reused"] == 0
    assert not set(other["cell"]) & set(first["cell"])
    key = hashing.cell_key("simulation", {"speed": 1.0}, {})
    monkeypatch.setattr(hashing, "_source", "e" * 64)
    assert hashing.cell_key("simulation", {"speed": 1.0}, {}) != key


def test_integer_columns_are_integers_in_the_csv(client, tmp_path):
    """seed (training rows only), road_seed (simulation rows on a random road only), epochs: the
    rows of the other kind leave them empty; a seed above 2**53 (not a float) comes back exactly."""
    big = 2**53 + 1
    spec = {"training": {"datasets": ["rig:quick"], "seeds": [big], "decimate": 50, "max_epochs": 2},
            "simulation": {"models": ["linear:1500"], "roads": ["iso:A", "impulse"], "road_seeds": [big],
                           "road_length_m": 20.0}}
    df = run(spec, client=client, out=tmp_path / "o", progress=False)
    assert (df["status"] == "ok").all(), df[["status", "error"]]
    back = pd.read_csv(tmp_path / "o" / "results.csv", dtype_backend="numpy_nullable")
    for col in ("seed", "data_seed", "road_seed", "epochs"):
        assert str(back[col].dtype) == "Int64" and str(df[col].dtype) == "Int64", (col, back[col].dtype)
        assert back[col].tolist() == df[col].tolist(), col
    assert back["seed"].tolist() == [big, pd.NA, pd.NA] and back["road_seed"].tolist() == [pd.NA, big, pd.NA]
    text = (tmp_path / "o" / "results.csv").read_text()
    assert text.count(f",{big},") == 2 and str(big - 1) not in text      # not through a float
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "o" / "results.parquet"), df, check_dtype=False)
