"""A checked DynoTest from SI channel arrays: time, control, sign conventions (every single-file reader's last step).

Shared by the text and .mat readers (dampnet.data.readers) and the lab-file readers
(dampnet.data.lab); see dampnet.data.readers for the options.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dampnet.data.derivative import EDGE_S, velocity_from_displacement
from dampnet.data.types import CONTROL_NAMES, MIN_SAMPLES, DataError, DynoTest
from dampnet.data.validate import check_test
from dampnet.schema import show

_SIGNED_MOTION = ("displacement", "velocity", "acceleration")
#: the sign conventions of motion and force: positive in extension or in compression
CONVENTIONS = ("extension", "compression")


def _sign(value: str, what: str) -> float:
    if value not in CONVENTIONS:
        raise DataError(f"{what}={show(value)}: expected 'extension' or 'compression'")
    return 1.0 if value == "extension" else -1.0


def apply_convention(channels: dict[str, np.ndarray], motion_positive: str = "extension",
                     force_positive: str = "extension") -> dict[str, np.ndarray]:
    """Flip signs so motion is positive in extension and force positive resisting extension."""
    sm = _sign(motion_positive, "motion_positive")
    sf = _sign(force_positive, "force_positive")
    for k in list(channels):
        if k in _SIGNED_MOTION and sm < 0:
            channels[k] = -channels[k]
        if k == "force" and sf < 0:
            channels[k] = -channels[k]
    return channels


#: velocity of a file without a velocity channel (issue 49, item 17): dampnet.data.derivative
#: (a zero-phase low-pass at 50 Hz, central differences, EDGE_S cut at each end). Measured
#: (tests/python/test_data_lab.py) against the analytic derivative of sines at 1, 8 and 20 Hz at 1
#: and 5 kHz: at most 0.08 % of the peak without noise, 0.25 % with 2 um of displacement noise,
#: edges cut; the 20 ms moving average it replaces was 4.6 % low at 8 Hz, 27 % at 20 Hz, and
#: 4-100 % wrong at the ends. With the virtual rig's 25 um of noise any 20 Hz-wide derivative
#: carries about 0.5-1 mm/s of noise (1-3 % of a 1 Hz, 25 mm sine's peak): a bandwidth, not a bias.


def _with_derived_velocity(where: str, columns: dict, time: np.ndarray, colnames: dict, lines, meta: dict | None):
    """The columns, time, line numbers and meta with the velocity derived from the displacement
    (dampnet.data.derivative.velocity_from_displacement) and EDGE_S cut at each end."""
    x, label = columns["displacement"], colnames.get("displacement", "displacement")
    if x.size < MIN_SAMPLES:
        return columns, time, lines, meta     # check_test names the short test
    v, cut, info = velocity_from_displacement(np.asarray(x, np.float64), np.asarray(time, np.float64))
    if x.size - 2 * cut < MIN_SAMPLES:
        raise DataError(f"{where}: channel {show(label)} (displacement): {x.size} samples: expected at least "
                        f"{MIN_SAMPLES + 2 * cut} to derive the velocity (no velocity channel: {EDGE_S:g} s "
                        "is cut at each end)")
    keep = slice(cut, x.size - cut)
    columns = {k: np.asarray(c)[keep] for k, c in columns.items()}
    columns["velocity"] = v[keep]
    colnames["velocity"] = f"(derived from {label})"
    meta = {**(meta or {}), "velocity": {"from": label, **info}}
    return columns, np.asarray(time)[keep], None if lines is None else lines[keep], meta


def build_test(where: str, columns: dict[str, np.ndarray], colnames: dict[str, str], *,
               header_lines: int = 1, lines: np.ndarray | None = None, test_id: str | None = None, voltage: float | None = None,
               current: float | None = None, dt: float | None = None, t0: float = 0.0,
               motion_positive: str = "extension", force_positive: str = "extension",
               frequency_hz: float | None = None, amplitude_m: float | None = None,
               derive_velocity: bool = False, meta: dict | None = None) -> DynoTest:
    """A checked DynoTest from SI channel arrays (one of them may be 'time')."""
    columns = dict(columns)
    n = len(next(iter(columns.values())))
    if "time" in columns:
        time = columns.pop("time")
    elif dt is not None:
        if not dt > 0:
            raise DataError(f"{where}: dt={show(dt)}: expected a positive sample interval [s]")
        time = t0 + dt * np.arange(n)
    else:
        raise DataError(f"{where}: missing a time column (time_s, time_ms, ...): expected one, "
                        "or pass dt= the sample interval [s]")
    if derive_velocity and "velocity" not in columns and "displacement" in columns:
        columns, time, lines, meta = _with_derived_velocity(where, columns, time, colnames, lines, meta)
        n = len(time)
    present = [c for c in CONTROL_NAMES if c in columns]
    if voltage is not None and current is not None:
        raise DataError(f"{where}: both voltage= and current= given: expected one control")
    if len(present) == 2:
        raise DataError(f"{where}: both voltage and current columns: expected one control column")
    if present:
        control_name = present[0]
        nominal = float(np.median(columns[control_name]))
    elif voltage is not None or current is not None:
        control_name = "voltage" if voltage is not None else "current"
        nominal = float(voltage if voltage is not None else current)
        columns[control_name] = np.full(n, nominal)
    else:
        raise DataError(f"{where}: missing control column: expected voltage_v or current_a "
                        "(any unit), or pass voltage= or current= for a constant control")
    columns = apply_convention(columns, motion_positive, force_positive)
    test = DynoTest(test_id=test_id or Path(where).stem, time=np.asarray(time, np.float64),
                    channels={k: np.asarray(v, np.float64) for k, v in columns.items()},
                    frequency_hz=frequency_hz, amplitude_m=amplitude_m, control_nominal=nominal,
                    control_name=control_name, meta=dict(meta or {}))
    return check_test(test, where, header_lines=header_lines, column_names=colnames, lines=lines)


def velocity_summary(tests: list[DynoTest]) -> dict:
    """{"velocity_derived": {method, bandwidth_hz, edge_cut_s, tests}} when some tests' velocity was
    derived from their displacement (their meta["velocity"]), else {}: the dataset's summary."""
    derived = [t for t in tests if "velocity" in t.meta]
    if not derived:
        return {}
    first = derived[0].meta["velocity"]
    return {"velocity_derived": {"method": first["method"],
                                 "bandwidth_hz": sorted({t.meta["velocity"]["bandwidth_hz"] for t in derived}),
                                 "edge_cut_s": sorted({t.meta["velocity"]["edge_cut_s"] for t in derived}),
                                 "tests": [t.test_id for t in derived]}}
