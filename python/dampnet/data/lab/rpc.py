"""MTS RPC III (drive files .drv, response files .rsp, .rpc, .tim) through rpc3-file: every
channel with its unit (UNITS.CHAN_n), sharing the file's DELTA_T [s]. Runs in a child process.

rpc3-file can also write RPC III (`rpc3.write`): `dampnet rig --replay` writes its drive files
with it (dampnet.rig.replay)."""

from __future__ import annotations

import numpy as np


def read(path: str) -> tuple[dict[str, np.ndarray], dict]:
    import rpc3

    rpc3.rpc3.progressbar = False   # the library's tqdm bar, on by default (a global of its module rpc3.rpc3)
    chans, _params = rpc3.read(path)
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
