"""`dampnet export --fmu` as files (issue 29): the description names the data `dampnet train`
trained on (meta["data"], not "unknown data"); a missing parent directory is created as for the
other exports (atomic_write_bytes), with the umask's mode; the build's scratch directory is in
the system's temporary directory and a killed export's is removed by the next export, nothing
left beside the output."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import time

import pytest
from fmpy import read_model_description

from dampnet.cli import main
from dampnet.data import write_dataset
from dampnet.outputs import umask_mode
from dampnet.rig import generate

PLAN = {"name": "tiny", "frequencies_hz": [0.5, 1.5], "amplitudes_m": [0.0254],
        "voltages_v": [0.0, 2.25, 5.0], "samples": 600}


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A model trained by `dampnet train` on a tiny rig dataset (2 epochs: the metadata matters)."""
    root = tmp_path_factory.mktemp("trained")
    write_dataset(generate(PLAN, seed=5), root / "data")
    assert main(["train", str(root / "data"), "--out", str(root / "m"), "--quiet", "--max-epochs", "2",
                 "--hidden", "3", "--holdout-voltage", "none", "--valve", "off"]) == 0
    return root / "m"


@pytest.fixture
def scratch(tmp_path, monkeypatch):
    """The system's temporary directory for this test: tmp_path/tmp."""
    d = tmp_path / "tmp"
    d.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(d))
    monkeypatch.setenv("TMPDIR", str(d))
    return d


def test_the_description_names_the_training_data(trained, tmp_path, scratch, capsys):
    """The data `dampnet train` recorded (its source and test count) is in the description; the
    FMU lands in a parent directory that did not exist, readable as any file the user writes,
    and nothing else is left (no scratch directory, no temporary file)."""
    data = json.loads((trained / "model.json").read_text())["meta"]["data"]
    out = tmp_path / "nodir" / "sub" / "d.fmu"
    assert main(["export", str(trained), "--fmu", str(out)]) == 0, capsys.readouterr().err
    description = read_model_description(str(out)).description
    assert "unknown data" not in description
    assert f"trained on {data['source']} ({data['n_tests']} tests)" in description, description
    assert (out.stat().st_mode & 0o777) == umask_mode()
    assert sorted(p.name for p in out.parent.iterdir()) == ["d.fmu"]
    assert list(scratch.iterdir()) == []


def test_a_killed_export_leaves_nothing_the_next_one_does_not_clean(trained, tmp_path, scratch):
    """kill -9 during the compilation: no FMU and nothing beside it; its scratch directory (in
    the temporary directory, marked with its pid) is removed by the next export, which succeeds."""
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    cmd = [sys.executable, "-m", "dampnet.cli", "export", str(trained), "--fmu", str(out_dir / "d.fmu")]
    proc = subprocess.Popen(cmd, env={**os.environ, "TMPDIR": str(scratch)}, start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not list(scratch.glob(".fmu.dampnet-tmp-*/fmu/sources/fmu2.cpp")):
            assert proc.poll() is None, "the export ended before it could be killed"
            time.sleep(0.05)
        time.sleep(0.3)  # into the compilation
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    left = list(scratch.iterdir())
    assert len(left) == 1 and left[0].name.startswith(f".fmu.dampnet-tmp-{proc.pid}-"), left
    assert list(out_dir.iterdir()) == []
    assert main(["export", str(trained), "--fmu", str(out_dir / "d.fmu")]) == 0
    assert list(scratch.iterdir()) == [] and sorted(p.name for p in out_dir.iterdir()) == ["d.fmu"]
