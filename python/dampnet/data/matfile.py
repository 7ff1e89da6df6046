"""MATLAB .mat files (v4 to v7.2) read by scipy in a child process.

scipy's reader is partly C (Cython) and some malformed files crash it with a
segmentation fault (scipy 1.17: a 531-byte mutated v5 file, kept as a test). A
reader of user files must not take the interpreter down, so `load_variables`
runs `scipy.io.loadmat` in a forked child and receives the variables through an
.npz file (no pickle): a crash, a hang (MAX_SECONDS) or an exception in the child
is a DataError in the parent. Without fork (Windows) it runs in process.
"""

from __future__ import annotations

import json
import os
import signal
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from dampnet.data.types import DataError
from dampnet.schema import show

#: longest a .mat file may take to read [s]
MAX_SECONDS = 60.0


class NonNumeric:
    """A variable that is not a numeric array (struct, cell, text): its description only."""

    def __init__(self, dtype: str):
        self.dtype = dtype


def _loadmat(path: str) -> dict:
    from scipy.io import loadmat

    with warnings.catch_warnings():
        # "returned data may be corrupt" (VAX/Cray byte orders) and the like: refused, not loaded
        warnings.simplefilter("error")
        m = loadmat(path)
    return {k: v for k, v in m.items() if not k.startswith("__")}


def _split(m: dict) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """Numeric arrays, and the dtype description of everything else."""
    numeric, other = {}, {}
    for k, v in m.items():
        a = np.asarray(v)
        if np.issubdtype(a.dtype, np.number):
            numeric[k] = a
        else:
            other[k] = str(a.dtype)
    return numeric, other


def load_variables(path: Path) -> dict[str, np.ndarray | NonNumeric]:
    """The variables of a .mat file (name -> array, or NonNumeric); DataError if unreadable."""
    where = f"{path}: not a readable MATLAB v4-v7.2 .mat file"
    if not hasattr(os, "fork"):
        try:
            numeric, other = _split(_loadmat(str(path)))
        except Exception as e:  # scipy raises several types for a bad file
            raise DataError(f"{where}: {show(str(e))}") from None
    else:
        numeric, other = _load_in_child(path, where)
    out: dict[str, np.ndarray | NonNumeric] = dict(numeric)
    out.update({k: NonNumeric(d) for k, d in other.items()})
    return out


def _quiet_crash() -> None:
    """In the child: a fatal signal just ends it (no faulthandler dump, no inherited handler
    such as a fuzzer's reporting the child's crash as its own); the parent reports it."""
    import faulthandler

    faulthandler.disable()
    for sig in (signal.SIGSEGV, signal.SIGBUS, signal.SIGFPE, signal.SIGILL, signal.SIGABRT):
        signal.signal(sig, signal.SIG_DFL)


def _load_in_child(path: Path, where: str) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    import scipy.io  # noqa: F401  (imported once here, not in every child)

    with tempfile.TemporaryDirectory(prefix="dampnet-mat-") as tmp:
        arrays, info = Path(tmp) / "vars.npz", Path(tmp) / "info.json"
        pid = os.fork()
        if pid == 0:  # the child: read, write, and leave without running the parent's exit handlers
            code = 1
            try:
                _quiet_crash()
                try:
                    numeric, other = _split(_loadmat(str(path)))
                    np.savez(arrays, **{f"v{i}": a for i, a in enumerate(numeric.values())})
                    info.write_text(json.dumps({"names": list(numeric), "other": other}))
                    code = 0
                except Exception as e:
                    info.write_text(json.dumps({"error": show(str(e))}))
                    code = 3
            finally:
                os._exit(code)
        status = _wait(pid)
        if os.WIFSIGNALED(status):
            raise DataError(f"{where}: the MATLAB reader (scipy) crashed on it "
                            f"(signal {os.WTERMSIG(status)})")
        try:
            d = json.loads(info.read_text())
        except (OSError, ValueError):
            raise DataError(f"{where}: the MATLAB reader (scipy) stopped on it "
                            f"(exit status {os.WEXITSTATUS(status)})") from None
        if "error" in d:
            raise DataError(f"{where}: {d['error']}")
        with np.load(arrays, allow_pickle=False) as z:
            numeric = {name: z[f"v{i}"] for i, name in enumerate(d["names"])}
        return numeric, d["other"]


def _wait(pid: int) -> int:
    """The child's wait status; killed (SIGKILL) after MAX_SECONDS."""
    deadline = time.monotonic() + MAX_SECONDS
    delay = 1e-4
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            return status
        if time.monotonic() > deadline:
            os.kill(pid, signal.SIGKILL)
            return os.waitpid(pid, 0)[1]
        time.sleep(delay)
        delay = min(delay * 2, 0.01)
