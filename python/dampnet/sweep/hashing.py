"""Content hashes of a cell's input files and the cell's key (what `--resume` compares).

A cell's key is the SHA-256 of its kind, its parameters with every input (dataset, model,
road file) replaced by the hash of its content, the sweep's schema and dampnet's source hash:
the same parameters on the same bytes give the same key wherever the files are; a changed
file, parameter or dampnet (any commit that changes its code) gives another key, so the cell
is computed again.

dampnet's source hash (source_digest): the SHA-256 of the installed package's .py files
(relative names and bytes) and of its compiled runtime (dampnet._core). `__version__` is not
enough: it is equal for every commit between two releases. The sweep also compares it with
every worker's (dampnet.sweep.runner): a worker running another dampnet is refused.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any, Mapping

#: the schema of a sweep's files (DIR/sweep.json, cells/*.json); part of every key
SCHEMA = "dampnet.sweep/1"
KEY_CHARS = 20
_CHUNK = 1 << 20


def file_digest(path: str | os.PathLike, h=None) -> str:
    """SHA-256 of a file's bytes (hex)."""
    h = h or hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(_CHUNK):
            h.update(chunk)
    return h.hexdigest()


def content_digest(path: str | os.PathLike) -> str:
    """SHA-256 of a file, or of a directory's files (relative names and bytes, in sorted order;
    hidden entries, e.g. dampnet's staging directories, are skipped)."""
    p = Path(path)
    if not p.is_dir():
        return file_digest(p)
    h = hashlib.sha256()
    for root, dirs, files in os.walk(p):
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        for name in sorted(f for f in files if not f.startswith(".")):
            f = Path(root) / name
            rel = f.relative_to(p).as_posix().encode()
            h.update(len(rel).to_bytes(8, "little") + rel)
            h.update(bytes.fromhex(file_digest(f)))
    return h.hexdigest()


def text_digest(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()


_source: str | None = None


def source_digest() -> str:
    """The SHA-256 (hex) of this process's dampnet: its .py files and its dampnet._core build
    (computed once per process: the code a process runs does not change under it)."""
    global _source
    if _source is None:
        import dampnet
        import dampnet._core

        root = Path(dampnet.__file__).resolve().parent
        h = hashlib.sha256()
        files = sorted(p for p in root.rglob("*.py") if "__pycache__" not in p.parts)
        for f in [*files, Path(dampnet._core.__file__).resolve()]:
            rel = (f.relative_to(root) if f.is_relative_to(root) else Path("_core", f.name)).as_posix().encode()
            h.update(len(rel).to_bytes(8, "little") + rel)
            h.update(bytes.fromhex(file_digest(f)))
        _source = h.hexdigest()
    return _source


def cell_key(kind: str, params: Mapping[str, Any], digests: Mapping[str, str]) -> str:
    """The cell's key: KEY_CHARS hex characters of the SHA-256 of everything that decides its result.

    `digests`: {parameter name: the content hash of the input it names}."""
    content = {k: ({"content": digests[k]} if k in digests else v) for k, v in params.items()}
    blob = json.dumps({"schema": SCHEMA, "source": source_digest(), "kind": kind, "params": content},
                      sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(blob.encode()).hexdigest()[:KEY_CHARS]
