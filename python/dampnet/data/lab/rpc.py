"""MTS RPC III (drive files .drv, response files .rsp, .rpc, .tim) through rpc3-file: every
channel with its unit (UNITS.CHAN_n), sharing the file's DELTA_T [s]. Runs in a child process.

Before rpc3-file reads the data, the header is checked here (issue 49): DELTA_T a number within
dampnet.data.types.DT_RANGE_S (rpc3-file took `nan`, and a word gave a Python type error), and
DATA_TYPE one of DATA_TYPES, the two rpc3-file decodes: SHORT_INTEGER (16-bit integers, each
times its channel's SCALE.CHAN_n) and FLOATING_POINT (32-bit IEEE floats). A file longer than its
header's data (a float file whose header says SHORT_INTEGER: half the samples it holds, read as
garbage) is refused, not read with a warning.

rpc3-file can also write RPC III (`rpc3.write`): `dampnet rig --replay` writes its drive files
with it (dampnet.rig.replay)."""

from __future__ import annotations

import math
import warnings

import numpy as np

from dampnet.data.types import DT_RANGE_S, MIN_SAMPLES

#: the RPC III data types read (rpc3-file decodes these two); the header's default is SHORT_INTEGER
DATA_TYPES = ("SHORT_INTEGER", "FLOATING_POINT")
#: an RPC III header: records of a 32-byte key and a 96-byte value, NUM_PARAMS (the third) of them
_KEY, _VALUE = 32, 96


def header(path: str) -> dict[str, str]:
    """The header's parameters as text ({} when the first three records are not FORMAT,
    NUM_HEADER_BLOCKS and NUM_PARAMS: rpc3-file names what is wrong then)."""
    rec = _KEY + _VALUE
    with open(path, "rb") as f:
        first = f.read(3 * rec)
        keys = [first[i * rec: i * rec + _KEY].decode("latin-1").strip(" \0") for i in range(3)]
        if len(first) < 3 * rec or keys[2] != "NUM_PARAMS":
            return {}
        try:
            n = int(first[2 * rec + _KEY: 3 * rec].decode("latin-1").strip(" \0"))
        except ValueError:
            return {}
        data = first + f.read(rec * max(0, min(n, 4096) - 3))
    out = {}
    for i in range(len(data) // rec):
        key = data[i * rec: i * rec + _KEY].decode("latin-1").strip(" \0")
        if key:
            out[key] = data[i * rec + _KEY: (i + 1) * rec].decode("latin-1").strip(" \0")
    return out


def check_header(params: dict[str, str]) -> None:
    """ValueError naming the parameter unless DELTA_T and DATA_TYPE are ones dampnet reads right."""
    text = params.get("DELTA_T")
    try:
        dt = float(text) if text is not None else math.nan
    except ValueError:
        dt = math.nan
    if not (math.isfinite(dt) and DT_RANGE_S[0] <= dt <= DT_RANGE_S[1]):
        raise ValueError(f"DELTA_T = {text!r}: expected a sample interval from {DT_RANGE_S[0]:g} to "
                         f"{DT_RANGE_S[1]:g} s")
    kind = params.get("DATA_TYPE", "SHORT_INTEGER")
    if kind not in DATA_TYPES:
        raise ValueError(f"DATA_TYPE = {kind!r}: expected {' or '.join(DATA_TYPES)} (the types read)")
    for key in ("FRAMES", "SAMPLES"):   # rpc3-file takes the minimum of a SHORT_INTEGER file's empty
        try:                               # channels: numpy's "zero-size array to reduction operation"
            none = key in params and float(params[key]) == 0
        except ValueError:
            none = False
        if none:
            raise ValueError(f"{key} = {params[key]}: no samples: expected at least {MIN_SAMPLES}")


def read(path: str) -> tuple[dict[str, np.ndarray], dict]:
    import rpc3

    rpc3.rpc3.progressbar = False   # the library's tqdm bar, on by default (a global of its module rpc3.rpc3)
    params = header(path)
    check_header(params)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        chans, _params = rpc3.read(path)
    for w in caught:
        if "extra bytes" in str(w.message):   # rpc3-file: "File contains N extra bytes after expected data region."
            raise ValueError(f"{str(w.message).rstrip('.')} (DATA_TYPE {params.get('DATA_TYPE', 'SHORT_INTEGER')}, "
                             f"CHANNELS {params.get('CHANNELS')}, FRAMES {params.get('FRAMES')}, PTS_PER_GROUP "
                             f"{params.get('PTS_PER_GROUP')}): expected the data to end the file (a header that "
                             "does not match the data)")
    arrays: dict[str, np.ndarray] = {}
    channels = []
    for c in chans or []:
        key = f"c{len(channels)}"
        arrays[key] = np.asarray(c.data, dtype=np.float64)
        channels.append({"name": c.name, "group": "", "unit": str(c.unit or ""), "array": key,
                         "dt": float(c.dt), "t0": float(c.x0 or 0.0)})
    return arrays, {"channels": channels}


#: what `write_test` writes: dampnet channel -> (RPC channel name, unit, factor from SI); names
#: and units a drive/response file of a damper dyno carries, which dampnet reads back without a map
WRITE_CHANNELS = {"displacement": ("Displacement", "mm", 1e3), "velocity": ("Velocity", "mm/s", 1e3),
                  "force": ("Force", "N", 1.0), "voltage": ("Voltage", "V", 1.0), "current": ("Current", "A", 1.0),
                  "temperature": ("Temperature", "degC", 1.0)}


def write_test(path, test) -> None:
    """A DynoTest as an RPC III file (32-bit floats, rpc3-file's writer): displacement [mm],
    velocity [mm/s], force [N], control [V or A], temperature [degC] when recorded; DELTA_T the
    test's median sample interval. The file must not exist (rpc3-file refuses to overwrite)."""
    import rpc3

    rpc3.rpc3.progressbar = False   # its tqdm bar (a global of the module rpc3.rpc3)
    dt = float(np.median(np.diff(test.time)))
    chans = [rpc3.Channel(name=name, unit=unit, dt=dt, data=np.asarray(test.channels[ch], np.float64) * k)
             for ch, (name, unit, k) in WRITE_CHANNELS.items() if ch in test.channels]
    rpc3.write(str(path), chans, datatype=float)
