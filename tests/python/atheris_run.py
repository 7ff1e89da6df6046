"""The CI-sized run of an atheris harness (fuzz/python/), shared by the fuzz tests."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path


def ran_all(log: str, runs: int) -> bool:
    """Whether libFuzzer's log says it did `runs` runs: it checks the count between mutation
    batches, so it may stop a few past it ("Done 3003 runs" for -runs=3000); fewer is an early
    stop."""
    done = re.search(r"^Done (\d+) runs", log, re.MULTILINE)
    return bool(done) and int(done.group(1)) >= runs


def atheris_ci_run(harness: Path, corpus: Path, tmp_path: Path, runs: int, max_len: int,
                   env: dict | None = None) -> None:
    """`runs` executions of `harness` from a copy of the seed `corpus` (libFuzzer adds what it
    finds to its first corpus directory: the kept one stays fixed), seed 1, no input slower than
    10 s, `env` added to the environment; fails with the fuzzer's last lines on a crash, a timeout
    or an early stop."""
    work = tmp_path / "corpus"
    shutil.copytree(corpus, work)
    proc = subprocess.run(
        [sys.executable, str(harness), str(work), f"-runs={runs}", "-seed=1", f"-max_len={max_len}",
         "-timeout=10", f"-artifact_prefix={tmp_path}/", "-print_final_stats=1"],
        capture_output=True, text=True, timeout=600, cwd=tmp_path, env={**os.environ, **(env or {})})
    tail = "\n".join(proc.stderr.splitlines()[-30:])
    assert proc.returncode == 0, tail
    assert ran_all(proc.stderr, runs), tail
    assert not list(tmp_path.glob("crash-*")) and not list(tmp_path.glob("timeout-*"))
