"""The channel map: which channel of a lab file is displacement, velocity, force, control, temperature.

A small TOML file, `dampnet-channels.toml`, beside the data (in the folder of files, or beside
a single file), or the same content given as options (`channel_map=` a path, a dict or a
ChannelMap; the CLI's --channel-map FILE):

    [channels]                      # dampnet channel = the file's channel name
    displacement = "Disp"           # TDMS: "Group/Channel", or "Channel" if only one group has it
    force = "Force"
    velocity = "Vel"                # optional: differentiated from displacement when absent
    voltage = "Command"             # or current = "Coil"; or a constant in [control]
    temperature = "Oil Temp"        # optional
    time = "Time"                   # optional: a time channel instead of the file's time base

    [units]                         # only for channels the file stores without a unit
    voltage = "V"

    [convention]                    # the rig's signs (dampnet: + in extension)
    motion_positive = "extension"   # or "compression"
    force_positive = "extension"    # force + when the damper resists extension

    [control]
    voltage = 2.0                   # a constant control [V] (or current = ... [A]) without a control channel

Without a map, channels are matched by their names' words (Force, Disp, Velocity, Temp,
Voltage, Current), and a file whose names do not say is refused naming its channels.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dampnet.data.testbuild import CONVENTIONS
from dampnet.data.types import CONTROL_MAX, CONTROL_NAMES, DataError
from dampnet.schema import parse_toml, read_text, show

#: the channel map's file name, looked for beside the data
MAP_FILE = "dampnet-channels.toml"
#: dampnet channels a map may name
MAP_CHANNELS = ("time", "displacement", "velocity", "force", "voltage", "current", "temperature")
TABLES = ("channels", "units", "convention", "control")
#: a channel map is a few lines: a larger file is not one
MAX_CHANNEL_MAP_BYTES = 1 << 20


@dataclass
class ChannelMap:
    """A parsed channel map (see the module doc); `source` names where it came from in messages."""

    channels: dict[str, str] = field(default_factory=dict)
    units: dict[str, str] = field(default_factory=dict)
    motion_positive: str = "extension"
    force_positive: str = "extension"
    control: dict[str, float] = field(default_factory=dict)
    source: str = "the channel map"

    @classmethod
    def from_dict(cls, d: Any, source: str = "the channel map") -> "ChannelMap":
        """A checked ChannelMap from the TOML's tables; DataError naming `source` and the key."""
        if not isinstance(d, dict):
            raise DataError(f"{source}: expected tables {', '.join(TABLES)}, got {show(d)}")
        unknown = sorted(set(d) - set(TABLES))
        if unknown:
            raise DataError(f"{source}: unknown table(s) {', '.join(map(show, unknown))}: expected "
                            f"{', '.join(TABLES)}")
        chans = _strings(d.get("channels", {}), f"{source}: [channels]", MAP_CHANNELS)
        units = _strings(d.get("units", {}), f"{source}: [units]", MAP_CHANNELS)
        conv = _strings(d.get("convention", {}), f"{source}: [convention]", ("motion_positive", "force_positive"))
        for k, v in conv.items():
            if v not in CONVENTIONS:
                raise DataError(f"{source}: [convention] {k} = {show(v)}: expected 'extension' or 'compression'")
        control = d.get("control", {})
        if not isinstance(control, dict):
            raise DataError(f"{source}: [control]: expected a table, got {show(control)}")
        ctl = {}
        for k, v in control.items():
            if k not in CONTROL_NAMES:
                raise DataError(f"{source}: [control] {show(k)}: expected voltage (V) or current (A)")
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not abs(v) <= CONTROL_MAX:
                unit = "V" if k == "voltage" else "A"
                raise DataError(f"{source}: [control] {k} = {show(v)}: expected a finite number from "
                                f"{-CONTROL_MAX:g} to {CONTROL_MAX:g} {unit}")
            ctl[k] = float(v)
        if len(ctl) > 1:
            raise DataError(f"{source}: [control]: expected one of voltage or current, got both")
        named = [c for c in CONTROL_NAMES if c in chans]
        if len(named) > 1:
            raise DataError(f"{source}: [channels]: expected one control channel (voltage or current), got both")
        if named and ctl:
            raise DataError(f"{source}: [channels] {named[0]} and [control] both give the control: expected one")
        return cls(channels=chans, units=units, motion_positive=conv.get("motion_positive", "extension"),
                   force_positive=conv.get("force_positive", "extension"), control=ctl, source=source)


def _strings(table: Any, where: str, keys: tuple[str, ...]) -> dict[str, str]:
    if not isinstance(table, dict):
        raise DataError(f"{where}: expected a table of names, got {show(table)}")
    out = {}
    for k, v in table.items():
        if k not in keys:
            raise DataError(f"{where}: unknown key {show(k)}: expected some of {', '.join(keys)}")
        if not isinstance(v, str) or not v.strip():
            raise DataError(f"{where} {k}: expected a non-empty string, got {show(v)}")
        out[k] = v.strip()
    return out


def load_channel_map(path: str | os.PathLike) -> ChannelMap:
    """The channel map of a TOML file; DataError naming the file (and line) otherwise."""
    path = Path(path)
    text = read_text(path, DataError, "a UTF-8 TOML channel map", max_bytes=MAX_CHANNEL_MAP_BYTES)
    d = parse_toml(text, str(path), DataError, "a valid TOML channel map")
    return ChannelMap.from_dict(d, str(path))


def resolve_channel_map(data_path: Path, channel_map: Any) -> ChannelMap | None:
    """The map given (ChannelMap, dict, or a TOML path), else MAP_FILE beside `data_path`, else None."""
    if isinstance(channel_map, ChannelMap):
        return channel_map
    if isinstance(channel_map, dict):
        return ChannelMap.from_dict(channel_map, "channel_map=")
    if channel_map is not None:
        return load_channel_map(channel_map)
    folder = data_path if data_path.is_dir() else data_path.parent
    beside = folder / MAP_FILE
    return load_channel_map(beside) if beside.is_file() else None
