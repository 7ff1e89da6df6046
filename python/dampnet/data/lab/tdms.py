"""LabVIEW TDMS through nptdms: every numeric channel of every group, with its unit and time base.

The unit is the channel property `unit_string` (what LabVIEW writes; `NI_UnitDescription` as a
fallback). The time base is the waveform properties `wf_increment` [s] and `wf_start_offset`
[s]; without them the file needs a time channel named in the channel map. A timestamp channel
(LabVIEW's time type) becomes seconds from its first sample. Runs in a child process.
"""

from __future__ import annotations

import numpy as np


def read(path: str) -> tuple[dict[str, np.ndarray], dict]:
    from nptdms import TdmsFile

    f = TdmsFile.read(path)
    arrays: dict[str, np.ndarray] = {}
    channels = []
    for g in f.groups():
        for c in g.channels():
            data = np.asarray(c[:])
            props = c.properties
            unit = str(props.get("unit_string", props.get("NI_UnitDescription", "")))
            if data.dtype.kind == "M":   # timestamps: seconds from the first
                data = (data - data[0]) / np.timedelta64(1, "s") if data.size else data.astype(np.float64)
                unit = "s"
            if data.dtype.kind not in "biuf" or data.ndim != 1:
                continue
            key = f"c{len(channels)}"
            arrays[key] = data.astype(np.float64)
            dt = props.get("wf_increment")
            channels.append({"name": c.name, "group": g.name, "unit": unit, "array": key,
                             "dt": None if dt is None else float(dt),
                             "t0": float(props.get("wf_start_offset", 0.0) or 0.0)})
    return arrays, {"channels": channels}
