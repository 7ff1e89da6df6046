"""A checked DynoTest from SI channel arrays: time, control, sign conventions (every single-file reader's last step).

Shared by the text and .mat readers (dampnet.data.readers) and the lab-file readers
(dampnet.data.lab); see dampnet.data.readers for the options.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dampnet.data.types import CONTROL_NAMES, DataError, DynoTest
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
    if derive_velocity and "velocity" not in columns and "displacement" in columns and n > 2:
        columns["velocity"] = np.gradient(columns["displacement"], time)
        colnames["velocity"] = "(derived from displacement)"
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
