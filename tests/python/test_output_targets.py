"""Issue 49's outputs and inputs: no file output ever replaces what is not a regular file, nor a
file of a dataset folder, `--force` or not (item 1): every command that writes a single file is
pointed, with --force where it has one, at a character device (a /dev/null node made in the test's
folder), a FIFO, a symbolic link and a dataset's manifest.csv, and must refuse in one line (exit 2)
before its work, the target as it was. Run folders that are datasets, models or hold an input
(item 2), export's folder and files checked before any is written (item 3), text inputs that are
not regular files (item 6), lab-folder links leaving the folder (item 15). In process but one
subprocess; about 10 s for the whole file."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from dampnet.cli import main
from dampnet.modeldir import default_model_path
from dampnet.outputs import OutputError, atomic_write_text

MODEL = str(default_model_path())


def _targets(root: Path) -> dict[str, Path]:
    """One of each kind of path an output must not replace, and what it holds."""
    out = {}
    dev = root / "null"
    try:
        os.mknod(dev, stat.S_IFCHR | 0o666, os.makedev(1, 3))  # /dev/null's numbers, in tmp
        out["device"] = dev
    except PermissionError:  # only root makes device nodes: the other kinds still run
        pass
    fifo = root / "fifo"
    os.mkfifo(fifo)
    out["fifo"] = fifo
    (root / "real.txt").write_text("the link's target\n")
    link = root / "link.json"
    link.symlink_to(root / "real.txt")
    out["symlink"] = link
    data = root / "data"
    data.mkdir()
    (data / "manifest.csv").write_text("test_id,file\nT1,T1.csv\n")
    (data / "T1.csv").write_text("time_s,displacement_m,velocity_m_s,force_n,voltage_v\n0,0,0,0,0\n")
    out["manifest"] = data / "manifest.csv"
    return out


def _state(p: Path):
    st = os.lstat(p)
    content = p.read_text() if stat.S_ISREG(st.st_mode) else None
    target = (p.resolve().read_text(), os.readlink(p)) if stat.S_ISLNK(st.st_mode) else None
    return stat.S_IFMT(st.st_mode), st.st_ino, content, target


def _commands(target: str, data: str) -> dict[str, list[str]]:
    return {
        "export --header": ["export", MODEL, "--header", target, "--force"],
        "export --onnx": ["export", MODEL, "--onnx", target, "--force"],
        "plan-tests --table": ["plan-tests", MODEL, "bump", "--budget", "1", "--table", target, "--force"],
        "plan-tests --out": ["plan-tests", MODEL, "bump", "--budget", "1", "--out", target, "--force"],
        "evaluate --json": ["evaluate", MODEL, data, "--json", target, "--force"],
        "diagnose --json": ["diagnose", MODEL, data, "--json", target],
        "compare --json": ["compare", MODEL, MODEL, data, "--json", target],
        "compare-algorithms --json": ["compare-algorithms", data, "--json", target],
        "iri --json": ["iri", data + "/T1.csv", "--json", target],
        "bench --json": ["bench", "--quick", "--json", target],
    }


@pytest.mark.parametrize("command", sorted(_commands("T", "D")))
def test_no_file_output_replaces_a_device_fifo_link_or_dataset_file(tmp_path, capsys, command):
    targets = _targets(tmp_path)
    for kind, target in targets.items():
        before = _state(target)
        argv = _commands(str(target), str(tmp_path / "data"))[command]
        assert main(argv) == 2, (command, kind)
        err = capsys.readouterr().err.strip()
        assert err.startswith("dampnet: error:") and "\n" not in err, (command, kind, err)
        assert "refusing" in err and str(target) in err, (command, kind, err)
        assert _state(target) == before, (command, kind)


def test_atomic_writes_refuse_them_too(tmp_path):
    """The writer every command goes through refuses the same targets, overwrite or not: the last
    line of defence for a command that forgot to check."""
    for kind, target in _targets(tmp_path).items():
        before = _state(target)
        with pytest.raises(OutputError, match="refusing"):
            atomic_write_text(target, "x\n", overwrite=True)
        assert _state(target) == before, kind
    plain = tmp_path / "plain.json"
    plain.write_text("old\n")
    atomic_write_text(plain, "new\n", overwrite=True)  # a regular file outside datasets: replaced
    assert plain.read_text() == "new\n"


def test_a_file_beside_an_input_model_json_is_an_input(tmp_path, capsys):
    """`--json MODEL/other.json` with the model given as MODEL/model.json: the model folder is the
    input, as when the folder itself is given."""
    from dampnet.modeldir import load_model, save_model_dir

    save_model_dir(load_model(MODEL), None, tmp_path / "m")
    beside = tmp_path / "m" / "model.h"
    before = beside.read_text()
    assert main(["export", str(tmp_path / "m" / "model.json"), "--header", str(beside), "--force"]) == 2
    assert "input" in capsys.readouterr().err
    assert beside.read_text() == before


def _listing(folder: Path) -> dict[str, str]:
    return {p.name: p.read_text() for p in sorted(folder.iterdir())}


@pytest.mark.parametrize("argv", [
    ["simulate", MODEL, "--road", "bump", "--out", "{data}", "--force"],
    ["vehicle", MODEL, "--test", "dlc", "--out", "{data}", "--force"],
    ["simulate", MODEL, "--road", "{roads}/road.csv", "--out", "{roads}", "--force"],
    ["simulate", MODEL, "--road", "bump", "--out", "{model}", "--force"],
], ids=["simulate-into-a-dataset", "vehicle-into-a-dataset", "simulate-into-its-road-folder",
        "simulate-into-a-model-folder"])
def test_a_run_folder_is_never_a_dataset_a_model_or_an_inputs_folder(tmp_path, capsys, argv):
    """Issue 49, item 2: simulate and vehicle wrote run.npz, metrics.json and plots into a dataset
    folder, and simulate into the folder of the road CSV it read; refused before the run, the
    folder unchanged."""
    from dampnet.modeldir import load_model, save_model_dir

    _targets(tmp_path)  # the dataset folder tmp_path/data
    roads = tmp_path / "roads"
    roads.mkdir()
    (roads / "road.csv").write_text("distance_m,elevation_m\n" + "".join(f"{0.1 * i},0\n" for i in range(200)))
    save_model_dir(load_model(MODEL), None, tmp_path / "model")
    folders = {"data": tmp_path / "data", "roads": roads, "model": tmp_path / "model"}
    argv = [a.format(**folders) for a in argv]
    target = next(folders[k] for k in folders if str(folders[k]) in argv[argv.index("--out") + 1])
    before = _listing(target)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "refusing to write this run's files there" in err, err
    assert _listing(target) == before


@pytest.mark.parametrize("existing", [False, True])
def test_export_checks_its_folder_and_files_before_writing_any(tmp_path, capsys, existing):
    """Issue 49, item 3: `export --target cortex-m7 --out DIR --header DIR/model.h` wrote the header,
    then refused DIR. Now refused before any byte: a file output inside the folder output, and a
    folder that is not an export folder, whichever is named first."""
    out = tmp_path / "fw"
    if existing:
        out.mkdir()
        (out / "notes.txt").write_text("mine\n")
    before = _listing(out) if existing else None
    argv = ["export", MODEL, "--target", "cortex-m7", "--out", str(out), "--header", str(out / "model.h"), "--force"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "refusing" in err or "inside the --out folder" in err, err
    assert (_listing(out) == before) if existing else not out.exists()
    if existing:  # a header outside a folder that is not an export folder: nothing written either
        other = tmp_path / "elsewhere.h"
        assert main(["export", MODEL, "--target", "cortex-m7", "--out", str(out), "--header", str(other),
                     "--force"]) == 2
        assert "not a dampnet export-target directory" in capsys.readouterr().err
        assert not other.exists() and _listing(out) == before


def test_text_inputs_are_regular_files_of_bounded_size(tmp_path):
    """Issue 49, item 6: a channel map given as /dev/zero read until memory ran out and a FIFO
    blocked for ever. Every text input (channel maps, dataset CSVs, JSON) goes through
    schema.read_text, which looks before it reads: run in a subprocess held to 1 GiB of memory and
    20 s, so that the old behaviour fails instead of taking the machine."""
    import subprocess
    import sys

    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    big = tmp_path / "big.toml"
    big.write_bytes(b"#" * ((1 << 20) + 1))
    code = f"""
import resource
resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))
from dampnet.data import DataError
from dampnet.data.lab.channelmap import load_channel_map
for path in ("/dev/zero", {str(fifo)!r}, {str(big)!r}):
    try:
        load_channel_map(path)
    except DataError as e:
        print(e)
"""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    lines = proc.stdout.strip().splitlines()
    assert proc.returncode == 0 and len(lines) == 3, (proc.stdout, proc.stderr[-2000:])
    assert "/dev/zero: is not a regular file" in lines[0]
    assert "fifo.toml: is not a regular file" in lines[1]
    assert "big.toml: 1,048,577 bytes, over the 1,048,576" in lines[2]


def test_a_lab_folder_refuses_links_that_leave_it(tmp_path, capsys):
    """Issue 49, item 15: `ln -s /etc/shadow DIR/x.mf4; dampnet evaluate M DIR` printed the target's
    first bytes. A link leaving the folder is refused unopened; one inside it is read as its file."""
    secret = tmp_path / "secret.txt"
    secret.write_text("root:*:20000:0:99999:7:::\n")
    lab = tmp_path / "lab"
    lab.mkdir()
    (lab / "x.mf4").symlink_to(secret)
    assert main(["evaluate", MODEL, str(lab)]) == 2
    err = capsys.readouterr().err
    assert "symbolic link leaving the folder" in err and "root" not in err.replace(str(tmp_path), ""), err
    from dampnet.data.lab.assemble import lab_files

    (lab / "x.mf4").unlink()
    (lab / "real.tdms").write_bytes(b"")
    (lab / "alias.tdms").symlink_to(lab / "real.tdms")
    assert [p.name for p in lab_files(lab)] == ["alias.tdms", "real.tdms"]
