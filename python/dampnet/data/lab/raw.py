"""A lab file's channels as its own library gives them, before any channel map or unit is applied.

Each format's module (tdms, mdf, rpc) has a `read(path) -> (arrays, head)` run in a child
process (dampnet.data.child): `head["channels"]` lists {name, group, unit, array, time | dt, t0}
with `array` (and `time`) naming entries of `arrays`. `read_raw` turns that into a RawFile.
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dampnet.data.child import run_isolated
from dampnet.data.types import DataError

#: file extension -> (format, the Python module it needs, its PyPI package, the reader's words)
FORMATS = {
    ".tdms": ("tdms", "nptdms", "nptdms", "the TDMS reader (nptdms)"),
    ".mf4": ("mdf", "asammdf", "asammdf", "the MDF reader (asammdf)"),
    ".mdf": ("mdf", "asammdf", "asammdf", "the MDF reader (asammdf)"),
    ".mf3": ("mdf", "asammdf", "asammdf", "the MDF reader (asammdf)"),
    ".rsp": ("rpc", "rpc3", "rpc3-file", "the RPC III reader (rpc3-file)"),
    ".drv": ("rpc", "rpc3", "rpc3-file", "the RPC III reader (rpc3-file)"),
    ".rpc": ("rpc", "rpc3", "rpc3-file", "the RPC III reader (rpc3-file)"),
    ".tim": ("rpc", "rpc3", "rpc3-file", "the RPC III reader (rpc3-file)"),
}
LAB_SUFFIXES = tuple(FORMATS)
#: the pip extra that installs every lab-file library
EXTRA = "lab"
#: longest a lab file may take to read [s]: BASE + PER_MB per megabyte. asammdf spins on some
#: malformed files (a 2.4 kB mutated MDF4 found by fuzz_lab ran past 60 s); a real file reads
#: far faster than 2 s/MB
READ_SECONDS_BASE = 15.0
READ_SECONDS_PER_MB = 2.0


def is_lab_file(path: Path) -> bool:
    return Path(path).suffix.lower() in FORMATS


@dataclass
class RawChannel:
    """One channel of a file: samples in the file's unit; time from `time` [s] or t0 + k dt."""

    name: str
    group: str
    unit: str
    data: np.ndarray
    time: np.ndarray | None = None   # explicit time stamps [s] (MDF masters)
    dt: float | None = None          # sample interval [s] (TDMS wf_increment, RPC DELTA_T)
    t0: float = 0.0                  # time of the first sample [s]

    @property
    def label(self) -> str:
        """The channel as a user names it in a channel map: 'group/name' when grouped."""
        return f"{self.group}/{self.name}" if self.group else self.name

    def times(self) -> np.ndarray | None:
        """The time of each sample [s], or None if the file gives none."""
        if self.time is not None:
            return self.time
        if self.dt is None:
            return None
        return self.t0 + self.dt * np.arange(self.data.shape[0])


@dataclass
class RawFile:
    path: Path
    format: str
    channels: list[RawChannel]

    def groups(self) -> list[str]:
        return list(dict.fromkeys(c.group for c in self.channels))


def require(module: str, package: str, path, doing: str = "reading it") -> None:
    """DataError naming the pip extra unless `module` can be imported (checked before forking)."""
    if importlib.util.find_spec(module) is None:
        raise DataError(f"{path}: {doing} needs the Python package {package}: "
                        f"pip install 'dampnet[{EXTRA}]'")


def read_raw(path: Path) -> RawFile:
    """The channels of a TDMS, MDF or RPC III file (by extension); DataError if unreadable."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise DataError(f"{path}: extension {suffix or '(none)'}: expected one of {', '.join(LAB_SUFFIXES)}")
    if not path.is_file():
        raise DataError(f"{path}: file not found")
    fmt, module, package, reader = FORMATS[suffix]
    require(module, package, path)
    importlib.import_module(module)   # once, here: each child inherits it instead of importing it
    from dampnet.data.lab import mdf, rpc, tdms

    fn = {"tdms": tdms.read, "mdf": mdf.read, "rpc": rpc.read}[fmt]
    limit = READ_SECONDS_BASE + READ_SECONDS_PER_MB * path.stat().st_size / 1e6
    arrays, head = run_isolated(fn, path, f"{path}: not a readable {fmt.upper()} file", reader, limit)
    chans = []
    for c in head["channels"]:
        chans.append(RawChannel(name=str(c["name"]), group=str(c.get("group", "")), unit=str(c.get("unit", "")),
                                data=np.asarray(arrays[c["array"]], dtype=np.float64),
                                time=None if c.get("time") is None else np.asarray(arrays[c["time"]], np.float64),
                                dt=c.get("dt"), t0=float(c.get("t0") or 0.0)))
    if not chans:
        raise DataError(f"{path}: no numeric channels: expected displacement, force and the other dyno channels")
    return RawFile(path=path, format=fmt, channels=chans)
