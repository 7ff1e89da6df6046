"""Lab files written with each format's own library, named and scaled as real loggers do.

`imperial(test)` gives a dyno test's channels as an American dyno logs them ("Disp" [in],
"Vel" [in/s], "Force" [lbf], "Command" [V], "Oil Temp" [degF]); the writers put them in a
LabVIEW-style TDMS (group "Measured Data", waveform properties), an MDF4 (several channel
groups at different rates) or an RPC III file (float32, rpc3-file's writer). The same numbers go
into a CSV with unit columns (`csv_of`), so each reader is compared with dampnet's CSV reader.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from needs import need_module

INCH = 0.0254
LBF = 4.4482216152605


def imperial(test, temp_f: float = 104.0) -> dict[str, tuple[np.ndarray, str]]:
    """{channel name: (samples in the logger's unit, unit)} of a DynoTest."""
    n = len(test)
    return {"Disp": (test.channels["displacement"] / INCH, "in"),
            "Vel": (test.channels["velocity"] / INCH, "in/s"),
            "Force": (test.channels["force"] / LBF, "lbf"),
            "Command": (test.channels["voltage"].copy(), "V"),
            "Oil Temp": (np.full(n, temp_f) + np.linspace(0, 9, n), "°F")}


#: the channel map for `imperial` files
MAP = """[channels]
displacement = "Disp"
velocity = "Vel"
force = "Force"
voltage = "Command"
temperature = "Oil Temp"
"""

#: CSV column of each imperial channel (the same units, spelled as dampnet's CSV reader reads them)
CSV_COLUMNS = {"Disp": "displacement_in", "Vel": "velocity_in_s", "Force": "force_lbf", "Command": "voltage_v",
               "Oil Temp": "temperature_f"}


def csv_of(path: Path, t: np.ndarray, chans: dict[str, tuple[np.ndarray, str]]) -> Path:
    """The same channels as a CSV with unit columns (full precision)."""
    names = ["time_s"] + [CSV_COLUMNS[k] for k in chans]
    data = np.column_stack([t] + [np.asarray(v, np.float64) for v, _ in chans.values()])
    np.savetxt(path, data, delimiter=",", header=",".join(names), comments="", fmt="%.17g")
    return path


def write_tdms(path: Path, groups: dict[str, dict[str, tuple[np.ndarray, str]]], dt: float,
               properties: dict | None = None) -> Path:
    """A TDMS file, one group per run, each channel a waveform (wf_increment [s], unit_string)."""
    nptdms = need_module("nptdms", "lab")
    objs = [nptdms.RootObject({"name": path.stem})]
    for g, chans in groups.items():
        objs.append(nptdms.GroupObject(g))
        for name, (data, unit) in chans.items():
            props = {"wf_increment": dt, "wf_start_offset": 0.0, "wf_xname": "Time", "wf_xunit_string": "s"}
            if unit:
                props["unit_string"] = unit
            props.update((properties or {}).get(name, {}))
            objs.append(nptdms.ChannelObject(g, name, np.asarray(data), properties=props))
    with nptdms.TdmsWriter(str(path)) as w:
        w.write_segment(objs)
    return path


def write_mdf(path: Path, groups: list[tuple[np.ndarray, dict[str, tuple[np.ndarray, str]]]],
              version: str = "4.10") -> Path:
    """An MDF file: one channel group per (time stamps [s], channels), each with its own master."""
    asammdf = need_module("asammdf", "lab")
    m = asammdf.MDF(version=version)
    for t, chans in groups:
        m.append([asammdf.Signal(np.asarray(d, np.float64), np.asarray(t, np.float64), name=k, unit=u)
                  for k, (d, u) in chans.items()])
    m.save(str(path), overwrite=True)
    m.close()
    return path


def write_rpc(path: Path, chans: dict[str, tuple[np.ndarray, str]], dt: float, pts_per_group: int = 2048) -> Path:
    """An RPC III file (32-bit floats) through rpc3-file's own writer (`pts_per_group`: its frame
    groups' length, a power of two; the last group is padded to it)."""
    rpc3 = need_module("rpc3", "lab")
    rpc3.rpc3.progressbar = False   # its tqdm bar (a global of the module rpc3.rpc3)
    rpc3.write(str(path), [rpc3.Channel(name=k, unit=u, dt=dt, data=np.asarray(d, np.float64))
                           for k, (d, u) in chans.items()], datatype=float, overwrite=True,
               pts_per_group=pts_per_group)
    return path
