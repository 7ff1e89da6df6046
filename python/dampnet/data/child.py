"""Run a file-format library's reader in a forked child, so a crash in it cannot take dampnet down.

Readers of user files built on libraries with C parts (scipy's MATLAB reader, asammdf) can
crash on a malformed file with a segmentation fault (scipy 1.17: a 531-byte mutated v5 .mat
file, kept as a test). `run_isolated(fn, path, where, reader)` runs `fn(path)` in a forked
child, which returns (arrays, head): numeric arrays by name and a JSON-able dict. They come
back through a pipe as JSON + .npz (no pickle). A crash, a hang (MAX_SECONDS) or an exception
in the child is a DataError in the parent naming `where` and the `reader`. Without fork
(Windows) `fn` runs in process.
"""

from __future__ import annotations

import io
import json
import os
import select
import signal
import time
from pathlib import Path
from typing import Callable

import numpy as np

from dampnet.data.types import DataError
from dampnet.schema import show

#: longest a file may take to read [s]
MAX_SECONDS = 60.0

Reader = Callable[[str], "tuple[dict[str, np.ndarray], dict]"]


def run_isolated(fn: Reader, path: Path, where: str, reader: str,
                 max_seconds: float = MAX_SECONDS) -> tuple[dict[str, np.ndarray], dict]:
    """(arrays, head) of `fn(str(path))`, run in a child process; DataError '`where`: ...' otherwise.

    `fn` raises any exception for a bad file; its message (at most MAX_ECHO characters) follows
    `where`. `reader` names the library in messages ("the MATLAB reader (scipy)"); a child still
    reading after `max_seconds` is killed.
    """
    if not hasattr(os, "fork"):
        try:
            return fn(str(path))
        except Exception as e:  # the libraries raise many types for a bad file
            raise DataError(f"{where}: {show(str(e))}") from None
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: read, send, and leave without running the parent's exit handlers
        code = 1
        try:
            os.close(r)
            _quiet_crash()
            _quiet_output()
            payload = io.BytesIO()
            try:
                arrays, head = fn(str(path))
                names = list(arrays)
                np.savez(payload, **{f"v{i}": np.asarray(arrays[k]) for i, k in enumerate(names)})
                head = {"names": names, "head": head}
            except Exception as e:
                head = {"error": show(str(e)) if str(e) else type(e).__name__}
            h = json.dumps(head, default=str).encode()
            with os.fdopen(w, "wb") as f:
                f.write(len(h).to_bytes(8, "little") + h + payload.getvalue())
            code = 0
        finally:
            os._exit(code)
    os.close(w)
    data, timed_out = _read_all(r, pid, max_seconds)
    status = os.waitpid(pid, 0)[1]
    if timed_out:
        raise DataError(f"{where}: {reader} took longer than {max_seconds:g} s on it")
    if os.WIFSIGNALED(status):
        raise DataError(f"{where}: {reader} crashed on it (signal {os.WTERMSIG(status)})")
    try:
        n = int.from_bytes(data[:8], "little")
        head = json.loads(data[8:8 + n])
    except ValueError:
        raise DataError(f"{where}: {reader} stopped on it (exit status {os.WEXITSTATUS(status)})") from None
    if "error" in head:
        raise DataError(f"{where}: {head['error']}")
    with np.load(io.BytesIO(data[8 + n:]), allow_pickle=False) as z:
        arrays = {name: z[f"v{i}"] for i, name in enumerate(head["names"])}
    return arrays, head["head"]


def _quiet_crash() -> None:
    """In the child: a fatal signal just ends it (no faulthandler dump, no inherited handler
    such as a fuzzer's reporting the child's crash as its own); the parent reports it."""
    import faulthandler

    faulthandler.disable()
    for sig in (signal.SIGSEGV, signal.SIGBUS, signal.SIGFPE, signal.SIGILL, signal.SIGABRT):
        signal.signal(sig, signal.SIG_DFL)


def _quiet_output() -> None:
    """In the child: the libraries' own logging and prints (asammdf's "ERROR - Expected ##FH block",
    nptdms's warnings) go nowhere; what went wrong comes back as the one-line DataError."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.dup2(devnull, 2)
    os.close(devnull)


def _read_all(fd: int, pid: int, max_seconds: float) -> tuple[bytes, bool]:
    """Everything the child writes to `fd` until it exits; (data, True) after killing it at max_seconds."""
    chunks, deadline = [], time.monotonic() + max_seconds
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
