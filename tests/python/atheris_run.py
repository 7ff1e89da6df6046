"""The CI-sized run of an atheris harness (fuzz/python/), shared by the fuzz tests."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path


def atheris_ci_run(harness: Path, corpus: Path, tmp_path: Path, runs: int, max_len: int) -> None:
    """`runs` executions of `harness` from a copy of the seed `corpus` (libFuzzer adds what it
    finds to its first corpus directory: the kept one stays fixed), seed 1, no input slower than
    10 s; fails with the fuzzer's last lines on a crash, a timeout or an early stop."""
    work = tmp_path / "corpus"
    shutil.copytree(corpus, work)
    proc = subprocess.run(
        [sys.executable, str(harness), str(work), f"-runs={runs}", "-seed=1", f"-max_len={max_len}",
         "-timeout=10", f"-artifact_prefix={tmp_path}/", "-print_final_stats=1"],
        capture_output=True, text=True, timeout=600, cwd=tmp_path)
    tail = "\n".join(proc.stderr.splitlines()[-30:])
    assert proc.returncode == 0, tail
    assert f"Done {runs} runs" in proc.stderr, tail
    assert not list(tmp_path.glob("crash-*")) and not list(tmp_path.glob("timeout-*"))
