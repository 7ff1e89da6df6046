"""MATLAB .mat files (v4 to v7.2) read by scipy in a child process.

scipy's reader is partly C (Cython) and some malformed files crash it with a
segmentation fault (scipy 1.17: a 531-byte mutated v5 file, kept as a test). A
reader of user files must not take the interpreter down, so `load_variables`
runs `scipy.io.loadmat` in a forked child and receives the variables as an .npz
through a pipe (no pickle): a crash, a hang (MAX_SECONDS) or an exception in the
child is a DataError in the parent. Without fork (Windows) it runs in process.
"""

from __future__ import annotations

import io
import json
import os
import select
import signal
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

    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: read, send, and leave without running the parent's exit handlers
        code = 1
        try:
            os.close(r)
            _quiet_crash()
            arrays = io.BytesIO()
            try:
                numeric, other = _split(_loadmat(str(path)))
                np.savez(arrays, **{f"v{i}": a for i, a in enumerate(numeric.values())})
                head = {"names": list(numeric), "other": other}
            except Exception as e:
                head = {"error": show(str(e))}
            h = json.dumps(head).encode()
            with os.fdopen(w, "wb") as f:
                f.write(len(h).to_bytes(8, "little") + h + arrays.getvalue())
            code = 0
        finally:
            os._exit(code)
    os.close(w)
    payload, timed_out = _read_all(r, pid)
    status = os.waitpid(pid, 0)[1]
    if timed_out:
        raise DataError(f"{where}: the MATLAB reader (scipy) took longer than {MAX_SECONDS:g} s on it")
    if os.WIFSIGNALED(status):
        raise DataError(f"{where}: the MATLAB reader (scipy) crashed on it (signal {os.WTERMSIG(status)})")
    try:
        n = int.from_bytes(payload[:8], "little")
        head = json.loads(payload[8:8 + n])
    except ValueError:
        raise DataError(f"{where}: the MATLAB reader (scipy) stopped on it "
                        f"(exit status {os.WEXITSTATUS(status)})") from None
    if "error" in head:
        raise DataError(f"{where}: {head['error']}")
    with np.load(io.BytesIO(payload[8 + n:]), allow_pickle=False) as z:
        numeric = {name: z[f"v{i}"] for i, name in enumerate(head["names"])}
    return numeric, head["other"]


def _read_all(fd: int, pid: int) -> tuple[bytes, bool]:
    """Everything the child writes to `fd` until it exits; (data, True) after killing it at MAX_SECONDS."""
    chunks, deadline = [], time.monotonic() + MAX_SECONDS
    try:
        while True:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([fd], [], [], left)[0]:
                os.kill(pid, signal.SIGKILL)
                return b"", True
            chunk = os.read(fd, 1 << 20)
            if not chunk:
                return b"".join(chunks), False
            chunks.append(chunk)
    finally:
        os.close(fd)
