"""Output directories: what `--force` may replace, crash-safe replacement, stale temporaries.

Every command that writes a directory (train: a model, rig: a dataset, demo: a run)
builds it in a hidden staging directory next to the output and swaps it in:

  check_output_dir(out, kind, inputs, force)   refuse (OutputError, one line) unless allowed
  with staged_dir(out) as tmp: ...write tmp...  then publish: `out` becomes tmp's contents

Rules (issue 14, item 5): `--force` replaces only an output of the same kind,
recognised by its marker (KIND_MARKERS); never an input of the same command,
nor `.`, nor a parent of the working directory or of an input.

Crash safety: the swap is one renameat2(RENAME_EXCHANGE) on Linux, so a kill at
any moment leaves the old or the new output at `out`. Where the exchange is not
available, the old output is moved into the staging directory and the new one
renamed into place; a kill between those two renames is repaired by the next run
(`clean_stale` moves the old output back). Staging directories are named
`.<out>.dampnet-tmp-<pid>-<random>` and hold a marker naming their process; the
next run removes those whose process is gone (same host only: provably stale).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import json
import math
import os
import re
import shutil
import socket
import stat
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator

import numpy as np

#: the marker file inside every staging directory (pid, host, output name)
STAGING_MARKER = "dampnet-staging.json"
_STAGING_NAME = re.compile(r"^\..+\.dampnet-tmp-(\d+)-[A-Za-z0-9_]+$")

#: what an output directory of each kind holds, in words (for messages)
KIND_MARKERS = {
    "model": "model.json",
    "dataset": "manifest.csv and a meta.json written by dampnet",
    "demo": "summary.json of a dampnet demo",
    "sweep": "sweep.json of a dampnet sweep",
    "export-target": "dampnet-export.json of a `dampnet export --target` folder",
}


class OutputError(FileExistsError, ValueError):
    """An output path that dampnet must not write or replace (one-line message).

    A FileExistsError for the callers that catch the plain "exists" refusal, and a
    ValueError like the project's other bad-input errors."""


# -- what may be replaced ---------------------------------------------------------

def is_kind(path: Path, kind: str) -> bool:
    """True if the directory `path` holds a dampnet output of `kind` (by its marker file)."""
    path = Path(path)
    if kind == "model":
        return (path / "model.json").is_file()
    if kind == "dataset":
        meta = _json_object(path / "meta.json")
        return (path / "manifest.csv").is_file() and str(meta.get("generator", "")).startswith("dampnet")
    if kind == "demo":
        return str(_json_object(path / "summary.json").get("schema", "")).startswith("dampnet.demo/")
    if kind == "sweep":
        return str(_json_object(path / "sweep.json").get("schema", "")).startswith("dampnet.sweep/")
    if kind == "export-target":
        return str(_json_object(path / "dampnet-export.json").get("schema", "")).startswith("dampnet.export-target/")
    raise ValueError(f"unknown output kind {kind!r}")


def _json_object(path: Path) -> dict:
    try:
        d = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return {}
    return d if isinstance(d, dict) else {}


def check_not_input(out: Path, inputs: Iterable[str | os.PathLike], what: str = "output",
                    inside: bool = False) -> None:
    """OutputError if `out` is an input, contains one, or is `.` or a parent of the working directory;
    with `inside`, also if it is inside an input directory (for a command that hashes its input
    directories whole, as a sweep does: its own output would change them)."""
    real = Path(out).resolve()
    cwd = Path.cwd().resolve()
    if real == cwd or cwd.is_relative_to(real):
        raise OutputError(f"{out}: is the current directory or one of its parents: refusing to use it as "
                          f"the {what} (name a new directory)")
    for inp in inputs:
        if inp is None:
            continue
        ip = Path(inp).resolve()
        if ip == real or ip.is_relative_to(real):
            raise OutputError(f"{out}: is an input of this command ({inp}) or contains it: refusing to "
                              f"write the {what} there")
        if inside and ip.is_dir() and real.is_relative_to(ip):
            raise OutputError(f"{out}: is inside an input directory of this command ({inp}): writing the "
                              f"{what} there would change that input; name a directory outside it")


def check_output_dir(out: str | os.PathLike, kind: str, inputs: Iterable[str | os.PathLike] = (),
                     force: bool = False) -> Path:
    """`out` as a Path if a `kind` output may be written there; OutputError (one line) otherwise.

    A missing `out` is fine. An existing one needs `force`, must be a real directory
    (not a symlink) holding an output of the same kind, and must not be an input,
    `.` or a parent of the working directory or of an input.
    """
    out = Path(out)
    check_not_input(out, inputs, f"{kind} directory")
    clean_stale(out.parent)  # first: a killed two-rename swap puts the old output back here
    if not os.path.lexists(out):
        return out
    if not force:
        raise OutputError(f"{out}: exists; refusing to overwrite (use --force)")
    if out.is_symlink() or not out.is_dir():
        raise OutputError(f"{out}: exists and is not a directory: refusing to replace it even with --force")
    if not is_kind(out, kind):
        raise OutputError(f"{out}: exists and is not a dampnet {kind} directory (no {KIND_MARKERS[kind]}): "
                          "refusing to replace it even with --force")
    return out


def check_replaceable_file(path: str | os.PathLike) -> None:
    """OutputError unless what is at `path` (if anything) is a file an output may replace: a regular
    file, not a symlink, a device, a FIFO or a socket (replacing `/dev/null` by a file, as root,
    breaks the machine; writing through a link writes where the link points), and not a file of a
    dataset folder (one holding manifest.csv: its tests and manifest are inputs, issue 49)."""
    p = Path(path)
    try:
        st = os.lstat(p)
    except FileNotFoundError:
        return
    except OSError as e:
        raise OutputError(f"{path}: cannot be inspected ({e.strerror}): refusing to write it") from None
    if stat.S_ISLNK(st.st_mode):
        raise OutputError(f"{path}: is a symbolic link: refusing to replace it or write through it "
                          "(name the file itself)")
    if stat.S_ISDIR(st.st_mode):
        raise OutputError(f"{path}: is a directory: expected a file name")
    if not stat.S_ISREG(st.st_mode):
        kind = ("a character device" if stat.S_ISCHR(st.st_mode) else "a block device" if stat.S_ISBLK(st.st_mode)
                else "a FIFO" if stat.S_ISFIFO(st.st_mode) else "a socket" if stat.S_ISSOCK(st.st_mode)
                else "not a regular file")
        raise OutputError(f"{path}: is {kind}: refusing to replace it even with --force (name a regular file)")
    if (p.parent / "manifest.csv").is_file():
        raise OutputError(f"{path}: is a file of the dataset folder {p.parent} (it holds manifest.csv): refusing "
                          "to replace it even with --force (write outputs outside datasets)")


def check_output_file(path: str | os.PathLike, inputs: Iterable[str | os.PathLike] = ()) -> Path:
    """`path` as a Path unless writing it would overwrite an input of the command (OutputError).

    Refused: the input itself, an existing file inside an input directory (e.g.
    `--json MODEL/model.json`) or beside an input model.json or manifest.csv (the folder is the
    input), a directory, and anything `check_replaceable_file` refuses (links, devices, FIFOs,
    sockets, files of a dataset folder).
    """
    p = Path(path)
    real = p.resolve()
    for inp in inputs:
        if inp is None:
            continue
        ip = Path(inp).resolve()
        folder = ip if ip.is_dir() else ip.parent if ip.name in ("model.json", "manifest.csv") else None
        if real == ip or (folder is not None and real.is_relative_to(folder) and os.path.lexists(p)):
            raise OutputError(f"{path}: is an input of this command ({inp}) or a file of one: refusing "
                              "to overwrite it")
    check_replaceable_file(p)
    return p


def check_output_files(outputs: dict[str, str | os.PathLike | None], inputs: Iterable[str | os.PathLike] = (),
                       force: bool = False) -> dict[str, Path]:
    """All the output files of one command ({option: path}, None: not asked for), checked together
    before anything is written: none is an input (`check_output_file`), no two name the same file,
    each is absent or `force`. {option: Path} of those given; OutputError (one line) otherwise."""
    inputs = [i for i in inputs if i is not None]
    out: dict[str, Path] = {}
    seen: dict[Path, str] = {}
    for option, path in outputs.items():
        if not path:
            continue
        try:
            p = check_output_file(path, inputs)
        except OutputError as e:
            raise OutputError(f"{option} {e}") from None
        real = p.resolve()
        if real in seen:
            raise OutputError(f"{seen[real]} and {option} name the same file {path}: give each output its own")
        if os.path.lexists(p) and not force:
            raise OutputError(f"{option} {path}: exists; refusing to overwrite (use --force)")
        seen[real] = option
        out[option] = p
    return out


def check_report_dir(out: str | os.PathLike, inputs: Iterable[str | os.PathLike] = ()) -> Path:
    """`out` as a Path if a report (index.html, pictures, JSON) may be written into it.

    Checked before the work that fills it, so a bad --report fails at once: refused if it
    exists and is not a directory, is an input or contains one, or is `.` or a parent of
    the working directory. Existing files of the same names in it are replaced (each one
    atomically, via `staged_files`); other files in it are left alone.
    """
    out = Path(out)
    if os.path.lexists(out) and (out.is_symlink() or not out.is_dir()):
        raise OutputError(f"{out}: exists and is not a directory: expected a directory for the report")
    check_not_input(out, inputs, "report directory")
    return out


def check_run_dir(out: str | os.PathLike, files: Iterable[str], marker: str, schema: str,
                  inputs: Iterable[str | os.PathLike] = (), force: bool = False) -> Path:
    """For commands that write named `files` into a directory that may hold other things
    (simulate, study): OutputError unless that is allowed.

    `out` must not be an input directory, nor inside one, nor the folder holding an input file
    (a model's model.json, a road's CSV), nor a dataset or model folder of any run (it holds
    manifest.csv or model.json: issue 49 found `simulate --out DATA --force` writing into a
    dataset); a file of this run that exists needs `force`, and `force` replaces only a
    previous run of the same command, recognised by `marker` (a JSON file of `files`) whose
    "schema" starts with `schema`.
    """
    out = Path(out)
    real = out.resolve()
    files = list(files)
    for inp in inputs:
        if inp is None:
            continue
        ip = Path(inp).resolve()
        holds = real == ip or (ip.is_file() and real == ip.parent) or (ip.is_dir() and real.is_relative_to(ip))
        if holds or any((real / f) == ip for f in files):
            raise OutputError(f"{out}: is or holds an input of this command ({inp}): refusing to write this "
                              "run's files there (name another --out)")
    for marker_file, what in (("manifest.csv", "a dataset"), ("model.json", "a model")):
        if (out / marker_file).is_file():
            raise OutputError(f"{out}: is {what} folder (it holds {marker_file}): refusing to write this run's "
                              "files there even with --force (name another --out)")
    existing = [out / f for f in files if os.path.lexists(out / f)]
    if not existing:
        return out
    if not force:
        raise OutputError(f"{existing[0]}: exists; refusing to overwrite (use --force)")
    if not str(_json_object(out / marker).get("schema", "")).startswith(schema):
        raise OutputError(f"{out}: holds {existing[0].name} but not a previous run of this command "
                          f"({marker} with schema {schema}...): refusing to overwrite it even with --force")
    return out


# -- staging and the swap ---------------------------------------------------------

def _checkpoint(step: str) -> None:
    """Called between the steps of a replacement; the crash-safety tests make it kill the process."""


@contextmanager
def staged_dir(out: str | os.PathLike) -> Iterator[Path]:
    """A fresh directory to build `out` in; on a clean exit it replaces `out` (crash-safe).

    On an exception nothing at `out` changes and the staging directory is removed.
    """
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    clean_stale(out.parent)
    container = Path(tempfile.mkdtemp(prefix=f".{out.name}.dampnet-tmp-{os.getpid()}-", dir=out.parent))
    try:
        (container / STAGING_MARKER).write_text(json.dumps(
            {"pid": os.getpid(), "host": socket.gethostname(), "out": out.name}))
        new = container / "new"
        new.mkdir()
        yield new
        _checkpoint("staged")
        publish(new, out, container)
        _checkpoint("published")
    finally:
        shutil.rmtree(container, ignore_errors=True)


@contextmanager
def staged_files(out: str | os.PathLike) -> Iterator[Path]:
    """A staging directory inside `out` for files that then replace their namesakes in `out`
    one by one (os.replace each: every file is the old or the new one, never half-written).

    Files are moved in sorted order with "metrics.json" and "*.json" last, so a run's
    marker appears only when its data are in place. A killed run's staging directory
    is removed by the next run (`clean_stale`).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    clean_stale(out)
    container = Path(tempfile.mkdtemp(prefix=f".files.dampnet-tmp-{os.getpid()}-", dir=out))
    try:
        (container / STAGING_MARKER).write_text(json.dumps(
            {"pid": os.getpid(), "host": socket.gethostname(), "out": ""}))
        new = container / "new"
        new.mkdir()
        yield new
        for f in sorted(os.listdir(new), key=lambda n: (n.endswith(".json"), n)):
            os.replace(new / f, out / f)
            _checkpoint(f"moved {f}")
    finally:
        shutil.rmtree(container, ignore_errors=True)


def publish(new: Path, out: Path, container: Path) -> None:
    """Make `out` the directory `new` (the old `out`, if any, ends up inside `container`)."""
    if not os.path.lexists(out):
        os.rename(new, out)
        return
    try:
        exchange(new, out)
        _checkpoint("exchanged")
        return
    except OSError:  # no renameat2 or no RENAME_EXCHANGE on this filesystem
        pass
    os.rename(out, container / "old")
    _checkpoint("old moved")
    try:
        os.rename(new, out)
    except BaseException:
        os.rename(container / "old", out)  # a failure (not a kill) puts the old output back at once
        raise


_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def exchange(a: Path, b: Path) -> None:
    """Swap the directory entries `a` and `b` atomically (Linux renameat2); OSError if unavailable."""
    fn = _renameat2()
    if fn is None:
        raise OSError("renameat2 is not available")
    if fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) != 0:
        err = ctypes.get_errno()
        raise OSError(err, os.strerror(err), str(b))


_libc_renameat2 = False


def _renameat2():
    global _libc_renameat2
    if _libc_renameat2 is False:
        _libc_renameat2 = None
        try:
            libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
            fn = libc.renameat2
            fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
            fn.restype = ctypes.c_int
            _libc_renameat2 = fn
        except (OSError, AttributeError):
            pass
    return _libc_renameat2


# -- stale temporaries ------------------------------------------------------------

def clean_stale(parent: str | os.PathLike) -> list[Path]:
    """Remove staging directories in `parent` left by killed dampnet runs; returns them.

    Only directories named like ours, holding our marker with the pid in their name,
    written on this host by a process that no longer exists. If such a run was killed
    between its two renames (no exchange available), its output is missing and the
    old one is inside: that one is moved back first.
    """
    removed = []
    try:
        entries = list(os.scandir(parent))
    except OSError:
        return removed
    host = socket.gethostname()
    for e in entries:
        m = _STAGING_NAME.match(e.name)
        if not m or not e.is_dir(follow_symlinks=False):
            continue
        info = _json_object(Path(e.path) / STAGING_MARKER)
        if info.get("pid") != int(m.group(1)) or info.get("host") != host or pid_alive(info["pid"]):
            continue
        out = Path(parent) / str(info.get("out", ""))
        old = Path(e.path) / "old"
        if info.get("out") and "/" not in str(info["out"]) and old.is_dir() and not os.path.lexists(out):
            os.rename(old, out)
        shutil.rmtree(e.path, ignore_errors=True)
        removed.append(Path(e.path))
    return removed


def pid_alive(pid: int) -> bool:
    """Whether a process with this id exists (this one, or one of another user, counts)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


# -- writing files ------------------------------------------------------------------------------

def umask_mode(mode: int = 0o666) -> int:
    """`mode` less the process's umask: what open() gives a new file (mkstemp gives 0600)."""
    mask = os.umask(0)
    os.umask(mask)
    return mode & ~mask


def atomic_write_bytes(path: str | os.PathLike, data: bytes | Callable[[Any], None],
                       overwrite: bool = False) -> Path:
    """Write `data` (bytes, or a function writing to a binary file) to `path` via a temporary
    file in the same directory and a rename: never half-written, and with the mode a plain
    open() would give (0666 less the umask), not mkstemp's 0600.

    Refuses (FileExistsError) to replace an existing file unless overwrite.
    """
    p = Path(path)
    if os.path.lexists(p) and not overwrite:
        raise FileExistsError(f"{p}: exists; refusing to overwrite (use --force)")
    check_replaceable_file(p)  # the last line of defence: the commands check before their work
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
    try:
        os.fchmod(fd, umask_mode())
        with os.fdopen(fd, "wb") as f:
            if callable(data):
                data(f)
            else:
                f.write(data)
        os.replace(tmp, p)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return p


def atomic_write_text(path: str | os.PathLike, text: str, overwrite: bool = False) -> Path:
    """atomic_write_bytes of `text` in UTF-8."""
    return atomic_write_bytes(path, text.encode("utf-8"), overwrite)


def jsonable(obj: Any, default: Callable[[Any], Any] | None = None) -> Any:
    """obj with numpy arrays and scalars as Python lists and numbers, tuples as lists, dict keys as
    strings, paths as strings and NaN/Inf as None (JSON has no NaN). Other objects pass through
    (json.dumps then refuses them) unless `default` converts them."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v, default) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v, default) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist(), default)
    if isinstance(obj, bool) or obj is None or isinstance(obj, str):
        return obj
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, (np.integer, int)):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    return default(obj) if default is not None else obj


def json_text(obj: Any, default: Callable[[Any], Any] | None = None) -> str:
    """The one JSON form of dampnet's outputs: jsonable(obj), indent 1, a final newline."""
    return json.dumps(jsonable(obj, default), indent=1, allow_nan=False) + "\n"


def write_json(path: str | os.PathLike, obj: Any, overwrite: bool = False) -> Path:
    """JSON (NaN/Inf written as null) atomically; an existing file only with overwrite."""
    return atomic_write_text(path, json_text(obj), overwrite)
