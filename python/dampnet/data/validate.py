"""Checks a loaded test is complete and usable, naming the file and line of the first problem."""

from __future__ import annotations

import numpy as np

from dampnet.data.types import CONTROL_NAMES, MIN_SAMPLES, REQUIRED, DataError, DynoTest
from dampnet.schema import show


def check_test(test: DynoTest, where: str, header_lines: int = 1,
               column_names: dict[str, str] | None = None, lines: np.ndarray | None = None) -> DynoTest:
    """Raise DataError unless `test` has strictly increasing time, no NaN, enough samples.

    `where` names the file; `header_lines` maps sample index k to file line
    k + header_lines + 1, unless `lines` gives each sample's file line (files with blank
    lines); `column_names` maps channel -> column name for messages.
    """
    cols = {k: show(v) for k, v in (column_names or {}).items()}

    def line(k: int) -> int:
        return int(lines[k]) if lines is not None and k < len(lines) else k + header_lines + 1

    t = np.asarray(test.time, dtype=np.float64)
    if t.ndim != 1:
        raise DataError(f"{where}: time: expected a 1-D series, got shape {t.shape}")
    n = t.shape[0]
    if n < MIN_SAMPLES:
        raise DataError(f"{where}: too few samples: expected at least {MIN_SAMPLES}, got {n}")
    for name in REQUIRED:
        if name not in test.channels:
            raise DataError(f"{where}: missing channel {cols.get(name, show(name))}: expected "
                            f"{', '.join(REQUIRED)} and a control channel (voltage or current)")
    if test.control_name not in CONTROL_NAMES:
        raise DataError(f"{where}: control {show(test.control_name)}: expected 'voltage' or 'current'")
    if test.control_name not in test.channels:
        raise DataError(f"{where}: missing control channel {cols.get(test.control_name, show(test.control_name))}")
    series = {"time": t, **test.channels}
    for name, x in series.items():
        x = np.asarray(x)
        if x.shape != (n,):
            raise DataError(f"{where}: channel {cols.get(name, show(name))}: expected {n} samples, got {x.shape}")
        bad = ~np.isfinite(x)
        if bad.any():
            k = int(np.argmax(bad))
            raise DataError(f"{where}: line {line(k)}, column {cols.get(name, show(name))}: "
                            f"expected a finite number, got {show(x[k])}")
    d = np.diff(t)
    if (d <= 0).any():
        k = int(np.argmax(d <= 0)) + 1
        what = "duplicated" if d[k - 1] == 0 else "decreasing"
        raise DataError(f"{where}: line {line(k)}, column {cols.get('time', show('time'))}: "
                        f"{what} time {show(t[k])} after {show(t[k - 1])}: expected strictly increasing time")
    return test
