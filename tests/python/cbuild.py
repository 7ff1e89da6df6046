"""Helpers for tests that build and run C/C++ code: CMake builds of the standalone
project (cached under build/tests-*), and one-off compiles of small programs.

The suite runs in several processes (pytest-xdist): a build folder that more than one test file
uses is built under `build_lock`, so that one process builds it and the others wait and then find it
up to date (CMake's second build of an unchanged tree is a no-op)."""

from __future__ import annotations

import contextlib
import fcntl
import os
import shutil
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BUILD = ROOT / "build"


def run(cmd: list[str], cwd: Path | None = None, timeout: float = 900) -> subprocess.CompletedProcess:
    """Run a command; on failure raise with its output so the test log shows why."""
    proc = subprocess.run([str(c) for c in cmd], cwd=cwd, capture_output=True, text=True,
                          timeout=timeout)
    if proc.returncode != 0:
        raise AssertionError(f"command failed ({proc.returncode}): {' '.join(map(str, cmd))}\n"
                             f"--- stdout\n{proc.stdout[-6000:]}\n--- stderr\n{proc.stderr[-6000:]}")
    return proc


@contextlib.contextmanager
def build_lock(folder: Path):
    """Hold an exclusive lock on FOLDER (a file beside it) while building into it: the processes
    of a parallel test run build a shared folder one at a time. Released when the holder exits,
    whatever way it ends (flock)."""
    folder.parent.mkdir(parents=True, exist_ok=True)
    with open(folder.parent / f".{folder.name}.lock", "w") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def cmake_build(name: str, *defines: str, install: bool = False, target: str | list[str] | None = None) -> Path:
    """Configure and build the standalone project (or the named targets) into build/tests-NAME."""
    targets = [target] if isinstance(target, str) else list(target or [])
    bdir = BUILD / f"tests-{name}"
    gen = ["-G", "Ninja"] if shutil.which("ninja") else []
    with build_lock(bdir):
        run(["cmake", "-S", ROOT, "-B", bdir, *gen, f"-DCMAKE_INSTALL_PREFIX={bdir / 'prefix'}",
             *[f"-D{d}" for d in defines]])
        run(["cmake", "--build", bdir, "--parallel", str(os.cpu_count() or 2),
             *(["--target", *targets] if targets else [])])
        if install:
            run(["cmake", "--install", bdir])
    return bdir


def compile_program(sources: list[Path], out: Path, *, cxx: bool, include_dirs: list[Path],
                    libs: list[Path] = (), std: str | None = None, extra: list[str] = ()) -> Path:
    """Compile a small program with warnings as errors; returns the executable path."""
    compiler = os.environ.get("CXX", "g++") if cxx else os.environ.get("CC", "gcc")
    std = std or ("c++17" if cxx else "c99")
    cmd = [compiler, f"-std={std}", "-O2", "-Wall", "-Wextra", "-Werror", *extra,
           *[f"-I{d}" for d in include_dirs], *sources, "-o", out]
    for lib in libs:
        cmd += [lib, f"-Wl,-rpath,{Path(lib).parent}"]
    cmd += ["-lm"]
    run(cmd)
    return out
