"""Column names that carry units ('force_lbf', 'disp (mm)', 'mm/s', 'kN') -> channel and SI conversion.

A column name is a quantity and a unit: ``force_lbf``, ``velocity_in_s``,
``displacement [mm]``, ``F (kN)``, ``time_ms``; or a bare unit (``mm``,
``mm/s``, ``kN``) whose dimension names the channel. `parse_column` returns
the channel and the affine map (scale, offset) to SI: si = scale * x + offset.
"""

from __future__ import annotations

import re

from dampnet.data.types import DataError
from dampnet.schema import show

#: longest column name parsed (a header cell is a quantity and a unit, never an essay)
MAX_COLUMN_NAME = 100

#: an inch [m], a pound-force [N] (exact by definition), standard gravity [m/s^2]
INCH = 0.0254
LBF = 4.4482216152605
G = 9.80665

# unit spelling (normalised: lower case, '/' and '_' and ' ' removed, '^' dropped) -> (dimension, scale, offset)
_UNITS: dict[str, tuple[str, float, float]] = {}


def _add(dim: str, names: str, scale: float, offset: float = 0.0) -> None:
    for n in names.split():
        _UNITS[n] = (dim, scale, offset)


_add("time", "s sec secs second seconds", 1.0)
_add("time", "ms msec", 1e-3)
_add("time", "us usec", 1e-6)
_add("time", "min", 60.0)
_add("length", "m meter meters metre", 1.0)
_add("length", "mm", 1e-3)
_add("length", "cm", 1e-2)
_add("length", "um micron", 1e-6)
_add("length", "in inch inches", INCH)
_add("length", "ft", 0.3048)
_add("velocity", "mps", 1.0)
_add("velocity", "mms", 1e-3)
_add("velocity", "cms", 1e-2)
_add("velocity", "ins ips inps inpers", INCH)
_add("velocity", "fts", 0.3048)
_add("acceleration", "ms2 mss", 1.0)
_add("acceleration", "mms2", 1e-3)
_add("acceleration", "ins2", INCH)
_add("acceleration", "g", G)
_add("force", "n newton newtons", 1.0)
_add("force", "kn", 1e3)
_add("force", "lbf lb lbs", LBF)
_add("force", "kgf", G)
_add("force", "kip", 1e3 * LBF)
_add("voltage", "v volt volts", 1.0)
_add("voltage", "mv", 1e-3)
_add("current", "a amp amps ampere", 1.0)
_add("current", "ma", 1e-3)
_add("temperature", "c degc celsius", 1.0)
_add("temperature", "f degf fahrenheit", 5.0 / 9.0, -32.0 * 5.0 / 9.0)
_add("temperature", "k kelvin", 1.0, -273.15)

# quantity spelling -> channel
_QUANTITIES = {
    "time": "time", "t": "time",
    "displacement": "displacement", "disp": "displacement", "position": "displacement",
    "pos": "displacement", "x": "displacement", "stroke": "displacement",
    "velocity": "velocity", "vel": "velocity", "speed": "velocity", "dx": "velocity", "xdot": "velocity",
    "force": "force", "f": "force", "load": "force",
    "voltage": "voltage", "volt": "voltage", "u": "voltage",
    "current": "current", "i": "current",
    "temperature": "temperature", "temp": "temperature",
    "acceleration": "acceleration", "accel": "acceleration", "acc": "acceleration",
}

CHANNEL_DIMENSION = {
    "time": "time", "displacement": "length", "velocity": "velocity", "force": "force",
    "voltage": "voltage", "current": "current", "temperature": "temperature",
    "acceleration": "acceleration",
}
_DIM_CHANNEL = {v: k for k, v in CHANNEL_DIMENSION.items()}

# Velocity and acceleration unit spellings that a ms-vs-m/s ambiguity makes special.
_VELOCITY_FORMS = re.compile(r"^(.*?)(?:/|_per_|_|p)(s|sec)(\^?2)?$")


def _norm_unit(u: str, dim_hint: str | None) -> tuple[str, float, float] | None:
    """(dimension, scale, offset) of a unit spelling, or None. 'm_s' is m/s unless the
    quantity is time (then 'ms' is milliseconds)."""
    u = u.strip().lower().replace("°", "deg").replace("²", "^2")
    if not u:
        return None
    m = _VELOCITY_FORMS.match(u)
    if m and m.group(1) and not (dim_hint == "time" and u in ("ms", "m_s")):
        base = _UNITS.get(m.group(1).strip("_/ "))
        if base and base[0] == "length":
            return ("acceleration" if m.group(3) else "velocity"), base[1], 0.0
    key = re.sub(r"[\s_/^\-]", "", u)
    if key == "ms" and dim_hint in ("velocity", None) and u != "ms":
        return "velocity", 1.0, 0.0
    return _UNITS.get(key)


def parse_column(name: str, where: str = "") -> tuple[str, float, float]:
    """Channel name and (scale, offset) to SI for a column header; DataError if unknown.

    Examples: 'force_lbf' -> ('force', 4.448..., 0); 'displacement (mm)' ->
    ('displacement', 1e-3, 0); 'mm/s' -> ('velocity', 1e-3, 0);
    'temperature_f' -> ('temperature', 5/9, -17.78).
    """
    prefix = f"{where}: " if where else ""
    raw = name.strip()
    if len(raw) > MAX_COLUMN_NAME:  # also bounds the candidate search below, O(len^2)
        raise DataError(f"{prefix}column {show(name)}: expected a column name of at most "
                        f"{MAX_COLUMN_NAME} characters")
    low = raw.lower()
    # form 1: 'quantity (unit)' or 'quantity [unit]'
    m = re.match(r"^([a-z_ ]+?)\s*[\(\[]\s*(.+?)\s*[\)\]]$", low)
    candidates: list[tuple[str | None, str]] = []
    if m:
        candidates.append((m.group(1).strip(), m.group(2)))
    else:
        # form 2: 'quantity_unit...' split at each underscore or space
        for k in [i for i, c in enumerate(low) if c in "_ "]:
            candidates.append((low[:k], low[k + 1:]))
        # form 3: bare unit
        candidates.append((None, low))
    for qty, unit in candidates:
        chan = _QUANTITIES.get(qty.replace(" ", "_")) if qty is not None else None
        if qty is not None and chan is None:
            continue
        hint = CHANNEL_DIMENSION.get(chan) if chan else None
        u = _norm_unit(unit, hint)
        if u is None:
            continue
        dim, scale, offset = u
        if chan is None:
            chan = _DIM_CHANNEL.get(dim)
        elif CHANNEL_DIMENSION[chan] != dim:
            continue
        return chan, scale, offset
    raise DataError(f"{prefix}column {show(name)}: expected a quantity with a known unit, such as "
                    "'force_n', 'force_lbf', 'displacement_mm', 'velocity_in_s', 'time_s', "
                    "'voltage_v', 'current_a', 'temperature_c', or a bare unit such as 'mm/s' or 'kN'")


def unit_to_si(unit: str, channel: str, where: str = "") -> tuple[float, float]:
    """(scale, offset) to SI of a unit string as a logger stores it ('lbf', 'in/s', 'mm', 'kN',
    '°F', 'mA') for `channel`; DataError naming `where` if the unit is unknown or of another
    dimension (a force channel in 'mm')."""
    prefix = f"{where}: " if where else ""
    if len(unit) > MAX_COLUMN_NAME:
        raise DataError(f"{prefix}unit {show(unit)}: expected a unit of at most {MAX_COLUMN_NAME} characters")
    dim = CHANNEL_DIMENSION.get(channel)
    if dim is None:
        raise DataError(f"{prefix}channel {show(channel)}: expected one of {', '.join(CHANNEL_DIMENSION)}")
    u = _norm_unit(unit, dim)
    if u is None:
        raise DataError(f"{prefix}unit {show(unit)}: not a known unit of {channel} ({dim}), expected e.g. "
                        f"{_EXAMPLES[dim]}")
    if u[0] != dim:
        raise DataError(f"{prefix}unit {show(unit)} is a {u[0]} unit: expected a {dim} unit for {channel}, "
                        f"e.g. {_EXAMPLES[dim]}")
    return u[1], u[2]


def quantity_of_name(name: str) -> str | None:
    """The channel a logger's channel name says it is ('Force' -> force, 'Disp' -> displacement,
    'Oil Temp' -> temperature), from its words; None when no word, or words of two channels."""
    words = [w for w in re.split(r"[^a-z]+", name.lower()) if w]
    found = {_QUANTITIES[w] for w in words if w in _QUANTITIES and len(w) > 1}
    return found.pop() if len(found) == 1 else None


_EXAMPLES = {
    "time": "'s', 'ms'", "length": "'m', 'mm', 'in'", "velocity": "'m/s', 'mm/s', 'in/s'",
    "force": "'N', 'kN', 'lbf'", "voltage": "'V', 'mV'", "current": "'A', 'mA'",
    "temperature": "'degC', '°F', 'K'", "acceleration": "'m/s^2', 'g'",
}
