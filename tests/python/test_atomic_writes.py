"""Every atomic writer, made to fail half-way: the previous output survives byte for byte and
no temporary is left behind.

The failure is a real one from the operating system, whatever the writer's implementation:
a file size limit (RLIMIT_FSIZE, SIGXFSZ ignored) below the new output's size makes the
write(2) that crosses it fail with EFBIG after the bytes before it were written, as a full
disk does with ENOSPC. Library writers run in process under the limit; commands run in a
subprocess with it. A second failure point, the final rename, is covered by making
os.replace raise ENOSPC."""

from __future__ import annotations

import errno
import json
import os
import resource
import signal
import subprocess
import sys
from contextlib import contextmanager
from pathlib import Path

import pytest

from dampnet.data import load_dataset, write_dataset
from dampnet.rig import generate
from dampnet.export import write_header
from dampnet.model import MlpModel
from dampnet.modeldir import save_model_dir
from dampnet.training.pipeline import train_dataset
from dampnet.outputs import write_json

TINY_PLAN = {"name": "tiny", "frequencies_hz": [0.5, 2.0], "amplitudes_m": [0.0254],
             "voltages_v": [0.0, 2.25, 5.0], "samples": 800}
LIMIT = 2048  # bytes: every new output below is larger


@contextmanager
def file_size_limit(nbytes: int):
    old_handler = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (nbytes, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
        signal.signal(signal.SIGXFSZ, old_handler)


def snapshot(d: Path) -> dict[str, bytes]:
    """Every file under d (hidden ones included) with its contents."""
    return {p.relative_to(d).as_posix(): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    ds = generate(TINY_PLAN, seed=0)
    model, _, _ = train_dataset(ds, max_epochs=5, decimate=4, seed=0)
    metrics = {"tag": "new", "weights": model.w1.tolist()}
    src = tmp_path_factory.mktemp("src")
    save_model_dir(model, metrics, src / "model")
    write_dataset(ds, src / "data")
    return ds, model, metrics, src


@pytest.fixture
def old(tmp_path):
    """A directory holding the previous outputs, each far smaller than LIMIT."""
    d = tmp_path / "out"
    d.mkdir()
    return d


FILE_WRITERS = {
    "model.json (MlpModel.save)": lambda m, p: m.save(p, overwrite=True),
    "model.h (write_header)": lambda m, p: write_header(m, p, overwrite=True),
    "metrics.json (write_json)": lambda m, p: write_json(p, m.to_dict(), overwrite=True),
}


@pytest.mark.parametrize("name", sorted(FILE_WRITERS))
def test_a_file_writer_that_runs_out_of_space_keeps_the_old_file(tiny, old, name):
    _, model, _, _ = tiny
    target = old / "target"
    target.write_text("previous contents\n")
    before = snapshot(old)
    with pytest.raises(OSError) as e, file_size_limit(LIMIT):
        FILE_WRITERS[name](model, target)
    assert e.value.errno == errno.EFBIG
    assert snapshot(old) == before


@pytest.mark.parametrize("name", sorted(FILE_WRITERS))
def test_a_file_writer_whose_rename_fails_keeps_the_old_file(tiny, old, monkeypatch, name):
    _, model, _, _ = tiny
    target = old / "target"
    target.write_text("previous contents\n")
    before = snapshot(old)

    def disk_full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "replace", disk_full)
    monkeypatch.setattr(os, "rename", disk_full)
    with pytest.raises(OSError, match="No space left"):
        FILE_WRITERS[name](model, target)
    assert snapshot(old) == before


def test_a_model_directory_that_runs_out_of_space_keeps_the_old_model(tiny, old):
    _, model, metrics, src = tiny
    out = old / "model"
    save_model_dir(MlpModel.load(src / "model"), {"tag": "old"}, out)
    before = snapshot(old)
    with pytest.raises(OSError), file_size_limit(LIMIT):
        save_model_dir(model, metrics, out, force=True)
    assert snapshot(old) == before


def test_a_dataset_that_runs_out_of_space_keeps_the_old_dataset(tiny, old):
    ds, _, _, _ = tiny
    out = old / "data"
    write_dataset(ds.subset(ds.tests[:1]), out)
    before = snapshot(old)
    with pytest.raises(OSError), file_size_limit(LIMIT):
        write_dataset(ds, out, overwrite=True)
    assert snapshot(old) == before
    assert len(load_dataset(out).tests) == 1


# -- commands (a subprocess each: the limit applies to the whole process) --------------------

def run_limited(argv: list[str], cwd: Path) -> subprocess.CompletedProcess:
    code = ("import resource, signal, sys\n"
            "from dampnet.cli import main\n"
            "signal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n"
            f"resource.setrlimit(resource.RLIMIT_FSIZE, ({LIMIT}, resource.RLIM_INFINITY))\n"
            f"sys.exit(main({argv!r}))\n")
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True,
                          timeout=600)


def _command_keeps_old(argv, old, expected_files):
    before = snapshot(old)
    assert set(before) >= set(expected_files)
    proc = run_limited(argv, old)
    assert proc.returncode != 0, proc.stdout[-2000:]
    assert snapshot(old) == before, proc.stderr[-2000:]
    return proc


def test_simulate_that_runs_out_of_space_keeps_the_previous_run(tiny, old):
    _, _, _, src = tiny
    argv = ["simulate", str(src / "model"), "--road", "impulse", "--out", str(old / "run")]
    assert run_limited_ok(argv, old)  # the first run, without the limit
    _command_keeps_old(argv + ["--force", "--damping", "low"], old,
                       ["run/metrics.json", "run/run.npz", "run/time_history.png"])


def test_evaluate_json_that_runs_out_of_space_keeps_the_previous_report(tiny, old):
    _, _, _, src = tiny
    (old / "report.json").write_text(json.dumps({"previous": True}) + "\n")
    _command_keeps_old(["evaluate", str(src / "model"), str(src / "data"), "--no-lookup",
                        "--json", str(old / "report.json"), "--force"], old, ["report.json"])


def test_diagnose_json_that_runs_out_of_space_keeps_the_previous_diagnosis(tiny, old):
    _, _, _, src = tiny
    (old / "diagnosis.json").write_text(json.dumps({"previous": True}) + "\n")
    _command_keeps_old(["diagnose", str(src / "model"), str(src / "data"), "--surrogates", "2",
                        "--json", str(old / "diagnosis.json")], old, ["diagnosis.json"])


def run_limited_ok(argv, cwd) -> bool:
    """The same command without the limit succeeds (so the failure above is the limit's)."""
    proc = subprocess.run([sys.executable, "-m", "dampnet.cli", *argv], cwd=cwd, capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return True
