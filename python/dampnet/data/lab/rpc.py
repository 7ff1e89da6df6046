"""MTS RPC III (drive files .drv, response files .rsp, .rpc, .tim) through rpc3-file: every
channel with its unit (UNITS.CHAN_n), sharing the file's DELTA_T [s]. Runs in a child process.

rpc3-file can also write RPC III (`rpc3.write`): `dampnet rig --replay` writes its drive files
with it (dampnet.rig.replay)."""

from __future__ import annotations

import numpy as np


def read(path: str) -> tuple[dict[str, np.ndarray], dict]:
    import rpc3

    rpc3.progressbar = False   # the library's tqdm bar, on by default
    chans, _params = rpc3.read(path)
    arrays: dict[str, np.ndarray] = {}
    channels = []
    for c in chans or []:
        key = f"c{len(channels)}"
        arrays[key] = np.asarray(c.data, dtype=np.float64)
        channels.append({"name": c.name, "group": "", "unit": str(c.unit or ""), "array": key,
                         "dt": float(c.dt), "t0": float(c.x0 or 0.0)})
    return arrays, {"channels": channels}
