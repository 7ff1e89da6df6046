"""dampnet as a user gets it from `pip install .`: the wheel built from this tree, installed
(not editable) into a fresh virtual environment, once per test session.

The fresh environment gets dampnet only from the wheel. Its heavy dependencies (numpy, scipy,
matplotlib, torch, ...) are borrowed from the project's .venv through a .pth line naming that
site-packages directory: a directory named in a .pth file is only appended to sys.path (the
.pth files inside it are not run), so the project's editable-install hook never loads, and the
wheel's `dampnet` package, found first in the fresh site-packages, is the only `dampnet`
(dampnet.__path__ holds that one directory, so no submodule can come from the source tree).
test_wheel_install.py checks this resolution before trusting any command run here.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
from dataclasses import dataclass
from pathlib import Path

from cbuild import BUILD, ROOT, build_lock, run
from dampnet.export.fmu.build import FLAGS_ENV


@dataclass(frozen=True)
class WheelEnv:
    wheel: Path     # the built .whl
    venv: Path      # the fresh virtual environment
    python: Path    # its interpreter
    site: Path      # its site-packages, where the wheel's dampnet lives
    env: dict       # environment for commands: the venv's bin first, no PYTHONPATH

    def dampnet(self, *args, cwd: Path, timeout: float = 900) -> subprocess.CompletedProcess:
        """Run the installed `dampnet` console script (not `python -m`: that would put cwd on
        sys.path) in cwd; returns the finished process whatever its exit status."""
        return subprocess.run([str(self.venv / "bin" / "dampnet"), *map(str, args)], cwd=cwd,
                              env=self.env, capture_output=True, text=True, timeout=timeout)

    def python_code(self, code: str, cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess:
        return subprocess.run([str(self.python), "-c", code], cwd=cwd, env=self.env,
                              capture_output=True, text=True, timeout=timeout)


_CACHE: dict[str, WheelEnv] = {}


def wheel_env(tmp_path_factory) -> WheelEnv:
    """The session's wheel install (built on first use; shared by every test module, and by the
    processes of a parallel run: the first builds it in their common temporary folder under a lock,
    the others wait for it and use it)."""
    if "env" not in _CACHE:
        if os.environ.get("PYTEST_XDIST_WORKER"):
            root = tmp_path_factory.getbasetemp().parent / "wheel-shared"
            with build_lock(root):
                if not (root / "done").is_file():
                    shutil.rmtree(root, ignore_errors=True)
                    _CACHE["env"] = _build(root)
                    (root / "done").write_text("built\n")
                else:
                    _CACHE["env"] = _built(root)
        else:
            _CACHE["env"] = _build(tmp_path_factory.mktemp("wheel"))
    return _CACHE["env"]


def _build(root: Path) -> WheelEnv:
    # No build isolation: the project's build tools, and its CMake build directory
    # (build/{wheel_tag}, shared with the editable install), so the C++ is not recompiled.
    # locked: the processes of a parallel run share build/{wheel_tag}
    with build_lock(BUILD / "wheel"):
        run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-index",
             "-q", "-w", root / "dist", ROOT], timeout=1800)
    wheels = sorted((root / "dist").glob("dampnet-*.whl"))
    assert len(wheels) == 1, wheels
    venv = root / "venv"
    run([sys.executable, "-m", "venv", "--without-pip", venv])
    python = venv / "bin" / "python"
    run([sys.executable, "-m", "pip", "--python", python, "install", "-q", "--no-deps", "--no-index",
         wheels[0]])
    site = Path(run([python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"])
                .stdout.strip())
    borrowed = sorted({sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]})
    (site / "_dampnet_test_borrowed_deps.pth").write_text("\n".join(borrowed) + "\n")
    return _built(root)


def _built(root: Path) -> WheelEnv:
    """The WheelEnv of a wheel already built and installed under `root` by `_build`."""
    wheels = sorted((root / "dist").glob("dampnet-*.whl"))
    venv = root / "venv"
    python = venv / "bin" / "python"
    site = Path(run([python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"])
                .stdout.strip())
    # (without the suite's quick FMU compile, FLAGS_ENV: the wheel builds FMUs as users get them)
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP", "VIRTUAL_ENV", FLAGS_ENV)}
    env.update(VIRTUAL_ENV=str(venv), PATH=f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}",
               MPLBACKEND="Agg")
    return WheelEnv(wheel=wheels[0], venv=venv, python=python, site=site, env=env)
