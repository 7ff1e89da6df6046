"""ASAM MDF 3.x / 4.x through asammdf: every numeric channel of every channel group with its
group's master (time) channel, so groups recorded at different rates keep their own time base
(dampnet.data.lab.assemble resamples them onto one). Runs in a child process.

A channel's unit is its own, or when that is empty its conversion's (MDF4: the conversion's unit
applies then; several loggers write it only there; asammdf's get_channel_unit reads it)."""

from __future__ import annotations

import numpy as np


def read(path: str) -> tuple[dict[str, np.ndarray], dict]:
    from asammdf import MDF

    mdf = MDF(path)
    try:
        arrays: dict[str, np.ndarray] = {}
        channels = []
        for gi, group in enumerate(mdf.groups):
            master = mdf.masters_db.get(gi)
            tkey = None
            for ci, ch in enumerate(group.channels):
                if ci == master:
                    continue
                sig = mdf.get(group=gi, index=ci)
                data = np.asarray(sig.samples)
                if data.dtype.kind not in "biuf" or data.ndim != 1:
                    continue
                if tkey is None:
                    tkey = f"t{gi}"
                    arrays[tkey] = np.asarray(sig.timestamps, dtype=np.float64)
                key = f"c{len(channels)}"
                arrays[key] = data.astype(np.float64)
                unit = str(sig.unit or "").strip() or str(mdf.get_channel_unit(group=gi, index=ci) or "")
                channels.append({"name": sig.name, "group": str(gi), "unit": unit,
                                 "array": key, "time": tkey})
    finally:
        mdf.close()
    return arrays, {"channels": channels}
