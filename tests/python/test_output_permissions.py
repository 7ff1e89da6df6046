"""Files dampnet writes get the permissions a plain open() would give them: 0666 and 0777 less
the user's umask (readable by others under the usual 022), never mkstemp's private 0600 or
mkdtemp's 0700. Every writer goes through outputs.atomic_write_bytes or a staged directory;
this runs each command that writes files under two umasks and checks every file and folder."""

from __future__ import annotations

import json
import os
import stat
import subprocess
import sys
from pathlib import Path

import pytest

import needs

TINY_PLAN = {"name": "tiny", "frequencies_hz": [0.5, 2.0], "amplitudes_m": [0.0254],
             "voltages_v": [0.0, 2.25, 5.0], "samples": 800}
SWEEP = """
[training]
datasets = ["DATA"]
algorithms = ["lm"]
seeds = [0]
decimate = 4
max_epochs = 5
"""


def dampnet(cwd: Path, umask: int, *args: str) -> str:
    proc = subprocess.run([sys.executable, "-m", "dampnet.cli", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=600,
                          preexec_fn=lambda: os.umask(umask))
    assert proc.returncode == 0, f"dampnet {' '.join(map(str, args))}: exit {proc.returncode}\n{proc.stderr[-3000:]}"
    return proc.stdout


def modes(root: Path) -> dict[str, int]:
    """Every file and folder below root (root included) -> its permission bits."""
    out = {".": stat.S_IMODE(root.stat().st_mode)}
    for p in root.rglob("*"):
        if not p.is_symlink():
            out[str(p.relative_to(root))] = stat.S_IMODE(p.stat().st_mode)
    return out


def test_every_output_has_the_umasks_permissions(tmp_path):
    umask = 0o027  # not the usual 022, so the modes seen are the umask's and not a fixed 0644
    needs.need_module("dask.distributed")
    (tmp_path / "tiny.json").write_text(json.dumps(TINY_PLAN))
    dampnet(tmp_path, umask, "rig", "data", "--plan", "tiny.json", "--no-progress")
    dampnet(tmp_path, umask, "train", "data", "--out", "model", "--quiet", "--max-epochs", "10",
            "--decimate", "4", "--restarts", "1", "--valve", "off")
    dampnet(tmp_path, umask, "export", "model", "--header", "m.h", "--onnx", "m.onnx", "--fmu", "m.fmu")
    dampnet(tmp_path, umask, "plan-tests", "model", "impulse:low", "--budget", "2", "--out", "plan.json",
            "--table", "plan.csv")
    (tmp_path / "sweep.toml").write_text(SWEEP.replace("DATA", str(tmp_path / "data")))
    dampnet(tmp_path, umask, "sweep", "sweep.toml", "--out", "sweep", "--workers", "1", "--quiet")

    file_mode, dir_mode = 0o666 & ~umask, 0o777 & ~umask
    checked = 0
    for top in ("data", "model", "m.h", "m.onnx", "m.fmu", "plan.json", "plan.csv", "sweep"):
        root = tmp_path / top
        found = modes(root) if root.is_dir() else {top: stat.S_IMODE(root.stat().st_mode)}
        for name, mode in found.items():
            path = root / name if root.is_dir() else root
            want = dir_mode if path.is_dir() else file_mode
            assert mode == want, f"{top}/{name}: mode {mode:o}, expected {want:o} (umask {umask:03o})"
            checked += 1
    # the list: model.json, model.h, envelope.*, metrics.json, .onnx, sweep cells, models, sweep.json
    for must in ("model/model.json", "model/model.h", "model/envelope.npz", "model/envelope.json",
                 "model/metrics.json", "sweep/sweep.json"):
        assert (tmp_path / must).is_file(), must
    assert any((tmp_path / "sweep" / "cells").iterdir())
    assert checked > 20
