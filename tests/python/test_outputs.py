"""Issue 14, item 5: what `--force` may replace, crash-safe replacement, stale temporaries.

The kill tests run the replacement in a subprocess whose `dampnet.outputs._checkpoint`
calls os._exit at one step, then check that the output path holds the old or the new
output (never neither), and that the next run removes the debris.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from dampnet import outputs
from dampnet.cli import main
from dampnet.data import write_dataset
from dampnet.data.types import Dataset, DynoTest
from dampnet.outputs import OutputError, check_output_dir, clean_stale

REPO = Path(__file__).resolve().parents[2]
DEFAULT_MODEL = REPO / "export" / "dn_model_default.json"


def _tiny_dataset(generator: str = "dampnet.data.rig") -> Dataset:
    t = np.arange(20) * 1e-3
    tests = [DynoTest(test_id="A", time=t, channels={
        "displacement": 0.01 * np.sin(t * 50), "velocity": 0.5 * np.cos(t * 50),
        "force": 100 * np.cos(t * 50), "voltage": np.full(20, 2.0)}, control_name="voltage")]
    return Dataset(tests=tests, source="test", meta={"generator": generator, "noise": {"force_n": 1.0}})


def _model_dir(path: Path, tag: str) -> Path:
    """A model directory whose model.json is the default model, marked by `tag` in meta."""
    path.mkdir(parents=True)
    d = json.loads(DEFAULT_MODEL.read_text())
    d["meta"] = {"tag": tag}
    (path / "model.json").write_text(json.dumps(d))
    return path


def _err(capsys, argv) -> str:
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 2, err
    assert err.startswith("dampnet: error: ") and err.count("\n") == 1, err
    return err


# -- refusals ----------------------------------------------------------------------------

def test_train_onto_its_own_dataset_is_refused_and_the_data_kept(tmp_path, capsys):
    data = tmp_path / "data"
    write_dataset(_tiny_dataset(), data)
    before = sorted(p.name for p in data.iterdir())
    err = _err(capsys, ["train", str(data), "--out", str(data), "--force", "--quiet"])
    assert "is an input of this command" in err
    assert sorted(p.name for p in data.iterdir()) == before


def test_train_onto_a_parent_of_its_input_is_refused(tmp_path, capsys):
    data = tmp_path / "box" / "data"
    write_dataset(_tiny_dataset(), data)
    _model_dir(tmp_path / "box" / "m", "x")   # box holds a model.json-less tree: make it look like a model
    (tmp_path / "box" / "model.json").write_text(DEFAULT_MODEL.read_text())
    err = _err(capsys, ["train", str(data), "--out", str(tmp_path / "box"), "--force", "--quiet"])
    assert "is an input of this command" in err and (data / "manifest.csv").is_file()


@pytest.mark.parametrize("which", [".", "..", "cwd_absolute"])
def test_force_onto_the_working_directory_or_a_parent_is_refused(tmp_path, monkeypatch, capsys, which):
    work = _model_dir(tmp_path / "work", "cwd")   # even if it looks like a model
    (tmp_path / "model.json").write_text(DEFAULT_MODEL.read_text())
    monkeypatch.chdir(work)
    out = {".": ".", "..": "..", "cwd_absolute": str(work)}[which]
    err = _err(capsys, ["train", "somewhere", "--out", out, "--force", "--quiet"])
    assert "is the current directory or one of its parents" in err
    assert (work / "model.json").is_file() and not list(tmp_path.glob(".*dampnet-tmp*"))


def test_force_onto_a_directory_that_is_not_a_model_is_refused(tmp_path, capsys):
    data = tmp_path / "data"
    write_dataset(_tiny_dataset(), data)
    victim = tmp_path / "photos"
    victim.mkdir()
    (victim / "holiday.jpg").write_bytes(b"\xff\xd8")
    err = _err(capsys, ["train", str(data), "--out", str(victim), "--force", "--quiet"])
    assert "is not a dampnet model directory (no model.json)" in err
    assert (victim / "holiday.jpg").read_bytes() == b"\xff\xd8"


def test_force_onto_a_file_or_a_symlink_is_refused(tmp_path):
    f = tmp_path / "file"
    f.write_text("keep")
    target = _model_dir(tmp_path / "real", "real")
    link = tmp_path / "link"
    link.symlink_to(target)
    for out in (f, link):
        with pytest.raises(OutputError, match="is not a directory: refusing to replace it even with --force"):
            check_output_dir(out, "model", force=True)
    assert f.read_text() == "keep" and (target / "model.json").is_file()


def test_rig_force_replaces_only_a_dataset_dampnet_wrote(tmp_path, capsys):
    users = tmp_path / "users_dyno"
    write_dataset(_tiny_dataset(generator="my lab"), users)
    err = _err(capsys, ["rig", str(users), "--plan", "quick", "--force", "--no-progress"])
    assert "is not a dampnet dataset directory" in err and (users / "A.csv").is_file()
    model = _model_dir(tmp_path / "model", "m")
    err = _err(capsys, ["rig", str(model), "--plan", "quick", "--force", "--no-progress"])
    assert "is not a dampnet dataset directory" in err and (model / "model.json").is_file()


def test_rig_force_refuses_its_plan_file_directory(tmp_path, capsys):
    out = tmp_path / "ds"
    write_dataset(_tiny_dataset(), out)
    (out / "plan.json").write_text("{}")
    err = _err(capsys, ["rig", str(out), "--plan", str(out / "plan.json"), "--force", "--no-progress"])
    assert "is an input of this command" in err


def test_write_dataset_force_replaces_a_dampnet_dataset(tmp_path):
    out = tmp_path / "ds"
    write_dataset(_tiny_dataset(), out)
    ds2 = _tiny_dataset()
    ds2.tests[0].test_id = "B"
    write_dataset(ds2, out, overwrite=True)
    assert sorted(p.name for p in out.iterdir()) == ["B.csv", "manifest.csv", "meta.json"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ds"]


def test_simulate_refuses_to_write_into_its_model_or_over_a_foreign_metrics_file(tmp_path, capsys):
    model = _model_dir(tmp_path / "m", "m")
    (model / "metrics.json").write_text('{"training": 1}')
    err = _err(capsys, ["simulate", str(model), "--road", "impulse", "--out", str(model), "--force"])
    assert "holds an input of this command" in err
    other = tmp_path / "o"
    other.mkdir()
    (other / "metrics.json").write_text('{"mine": true}')
    err = _err(capsys, ["simulate", "linear:1500", "--road", "impulse", "--out", str(other), "--force"])
    assert "not a previous run of this command" in err
    assert json.loads((other / "metrics.json").read_text()) == {"mine": True}
    err = _err(capsys, ["simulate", str(model / "model.json"), "--road", "impulse", "--out", str(model)])
    assert "holds an input of this command" in err
    assert main(["simulate", "linear:1500", "--road", "impulse", "--out", str(tmp_path / "r")]) == 0
    assert main(["simulate", "linear:1500", "--road", "impulse", "--out", str(tmp_path / "r"), "--force"]) == 0
    assert not [p for p in (tmp_path / "r").iterdir() if p.name.startswith(".")]


def test_simulate_does_not_write_into_the_folder_of_its_road_csv(tmp_path, monkeypatch, capsys):
    """Issue 49, item 2, reversing this test's earlier permission: a run folder holding an input (the
    road CSV) is refused, as sweep, rig and export --target refuse theirs; a folder beside it is fine."""
    road = tmp_path / "road.csv"
    road.write_text("distance_m,elevation_m\n" + "".join(f"{0.1 * k},{0.001 * np.sin(k / 5)}\n" for k in range(400)))
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "linear:1500", "--road", "road.csv", "--speed", "10", "--out", "."]) == 2
    assert "is or holds an input of this command" in capsys.readouterr().err
    assert not (tmp_path / "metrics.json").exists() and road.is_file()
    assert main(["simulate", "linear:1500", "--road", "road.csv", "--speed", "10", "--out", "run"]) == 0
    assert (tmp_path / "run" / "metrics.json").is_file()


@pytest.mark.parametrize("command", ["evaluate", "diagnose"])
def test_json_output_onto_an_input_is_refused(tmp_path, capsys, command):
    model = _model_dir(tmp_path / "m", "m")
    before = (model / "model.json").read_text()
    data = tmp_path / "data"
    write_dataset(_tiny_dataset(), data)
    argv = [command, str(model), str(data), "--json", str(model / "model.json")]
    err = _err(capsys, argv + (["--force"] if command == "evaluate" else []))
    assert "is an input of this command" in err and (model / "model.json").read_text() == before


# -- crash safety -------------------------------------------------------------------------

KILL_SCRIPT = textwrap.dedent("""
    import json, os, sys
    from pathlib import Path
    from dampnet import outputs
    from dampnet.model import MlpModel
    from dampnet.modeldir import save_model_dir
    out, step, no_exchange = Path(sys.argv[1]), sys.argv[2], sys.argv[3] == "1"
    def checkpoint(s):
        if s == step:
            os._exit(9)
    outputs._checkpoint = checkpoint
    if no_exchange:
        def refuse(a, b):
            raise OSError("no RENAME_EXCHANGE here")
        outputs.exchange = refuse
    m = MlpModel.load(sys.argv[4])
    m.meta = {"tag": "new"}
    save_model_dir(m, {"tag": "new"}, out, force=True)
""")


def _tag(out: Path):
    return json.loads((out / "model.json").read_text())["meta"]["tag"] if (out / "model.json").is_file() else None


@pytest.mark.parametrize("step, no_exchange, seen", [
    ("staged", False, "old"),       # new model built, nothing swapped yet
    ("exchanged", False, "new"),    # swapped in one renameat2; the old one awaits removal
    ("published", False, "new"),    # done, staging not yet removed
    ("old moved", True, None),      # no exchange: between the two renames; repaired by the next run
])
def test_a_kill_at_any_step_leaves_the_old_or_the_new_model(tmp_path, step, no_exchange, seen):
    out = _model_dir(tmp_path / "m", "old")
    proc = subprocess.run([sys.executable, "-c", KILL_SCRIPT, str(out), step, "1" if no_exchange else "0",
                           str(DEFAULT_MODEL)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 9, proc.stderr  # the kill happened at that step
    assert _tag(out) == seen
    debris = [p for p in tmp_path.iterdir() if p.name.startswith(".m.dampnet-tmp-")]
    assert len(debris) == 1
    removed = clean_stale(tmp_path)        # what the next run does first
    assert removed == debris
    assert _tag(out) == (seen or "old")    # the interrupted two-rename swap is undone
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m"]


def test_the_exchange_is_atomic_on_this_filesystem(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    b.mkdir()
    (a / "x").write_text("a")
    (b / "x").write_text("b")
    outputs.exchange(a, b)
    assert (a / "x").read_text() == "b" and (b / "x").read_text() == "a"


def test_a_failed_write_keeps_the_old_model_and_leaves_no_debris(tmp_path, monkeypatch):
    from dampnet.model import MlpModel
    from dampnet.modeldir import save_model_dir

    out = _model_dir(tmp_path / "m", "old")

    def disk_full(*a, **k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr("dampnet.modeldir.write_header", disk_full)
    with pytest.raises(OSError, match="No space left"):
        save_model_dir(MlpModel.load(DEFAULT_MODEL), {}, out, force=True)
    assert _tag(out) == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["m"]


def test_a_failed_second_rename_without_exchange_puts_the_old_model_back(tmp_path, monkeypatch):
    from dampnet.model import MlpModel
    from dampnet.modeldir import save_model_dir

    out = _model_dir(tmp_path / "m", "old")
    real_rename = os.rename

    def no_exchange(a, b):
        raise OSError("no RENAME_EXCHANGE here")

    def rename(a, b):
        if Path(a).name == "new":
            raise OSError(5, "Input/output error")
        real_rename(a, b)

    monkeypatch.setattr(outputs, "exchange", no_exchange)
    monkeypatch.setattr(outputs.os, "rename", rename)
    with pytest.raises(OSError, match="Input/output error"):
        save_model_dir(MlpModel.load(DEFAULT_MODEL), {}, out, force=True)
    assert _tag(out) == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["m"]


# -- stale temporaries ----------------------------------------------------------------------

def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def _staging(parent: Path, name: str, pid: int, host: str | None = None, marker: bool = True) -> Path:
    import socket

    d = parent / f".{name}.dampnet-tmp-{pid}-abc123"
    (d / "new").mkdir(parents=True)
    (d / "new" / "big.bin").write_bytes(b"\0" * 1000)
    if marker:
        (d / outputs.STAGING_MARKER).write_text(json.dumps(
            {"pid": pid, "host": host or socket.gethostname(), "out": name}))
    return d


def test_only_provably_stale_staging_directories_are_cleaned(tmp_path):
    dead = _dead_pid()
    stale = _staging(tmp_path, "m", dead)
    alive = _staging(tmp_path, "n", os.getppid())
    other_host = _staging(tmp_path, "o", dead, host="another-machine")
    no_marker = _staging(tmp_path, "p", dead, marker=False)
    users = tmp_path / ".m.tmp-keep"
    users.mkdir()
    assert clean_stale(tmp_path) == [stale]
    assert alive.is_dir() and other_host.is_dir() and no_marker.is_dir() and users.is_dir()


def test_a_refused_next_run_cleans_the_debris_too(tmp_path, capsys):
    stale = _staging(tmp_path, "m", _dead_pid())
    _model_dir(tmp_path / "m", "old")
    err = _err(capsys, ["train", "no-such-data", "--out", str(tmp_path / "m"), "--quiet"])
    assert "exists; refusing to overwrite" in err and not stale.exists()


def test_the_next_train_cleans_a_killed_runs_debris(tmp_path, capsys):
    data = tmp_path / "data"
    write_dataset(_tiny_dataset(), data)
    stale = _staging(tmp_path, "m", _dead_pid())
    assert main(["train", str(data), "--out", str(tmp_path / "m"), "--quiet", "--max-epochs", "2",
                 "--holdout-voltage", "none", "--hidden", "2", "--decimate", "1"]) == 0
    assert not stale.exists() and (tmp_path / "m" / "model.json").is_file()


def test_iri_json_onto_its_profile_is_refused(tmp_path, capsys):
    p = tmp_path / "road.csv"
    p.write_text("distance_m,elevation_m\n" + "".join(f"{0.25 * k},{0.001 * np.sin(k)}\n" for k in range(2000)))
    before = p.read_text()
    err = _err(capsys, ["iri", str(p), "--json", str(p)])
    assert "is an input of this command" in err and p.read_text() == before
