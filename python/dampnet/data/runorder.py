"""The run order a dataset states (issue 50): the order its tests were run in, when the data say it.

A dataset states its run order with one of two optional manifest columns (docs/data-formats.md):

  run_order  a number per test: the order the tests were run in (1, 2, 3, ...; gaps and a start
             other than 1 are fine, the numbers are only compared)
  started    each test's start time stamp: an ISO 8601 date-time (2026-03-14T09:26:53) or a
             number of seconds on any one clock

Every test must have it (an empty cell in some tests states nothing). Without either, the dataset
has no run order: the manifest's order is the order it lists the tests in, often sorted by
frequency or control, and a drift along it cannot be told from a dependence on them. The virtual
rig states the order it ran its tests in (a `run_order` column).
"""

from __future__ import annotations

from datetime import datetime

import numpy as np

RUN_ORDER_COLUMN = "run_order"
STARTED_COLUMN = "started"


def parse_started(cell: str) -> float:
    """A `started` cell as seconds: a number as given, an ISO 8601 date-time as POSIX seconds
    (naive times on one clock: only differences are used); ValueError otherwise."""
    text = str(cell).strip()
    try:
        v = float(text)
    except ValueError:
        try:
            d = datetime.fromisoformat(text)
        except ValueError:
            raise ValueError(f"expected an ISO 8601 date-time (2026-03-14T09:26:53) or a number of seconds, "
                             f"got {text[:60]!r}") from None
        return d.timestamp() if d.tzinfo is not None else (d - datetime(1970, 1, 1)).total_seconds()
    if not np.isfinite(v):
        raise ValueError(f"expected a finite number of seconds, got {text[:60]!r}")
    return v


def stated_run_order(tests) -> tuple[np.ndarray | None, str]:
    """(each test's place in the run order, scaled to [0, 1] between the first test run and the
    last; or None, source or reason). The place comes from `run_order` (the numbers' ranks: a
    campaign's place, not its clock) or else `started` (the time stamps themselves: a drift is
    in time), whichever every test states."""
    tests = list(tests)
    if not tests:
        return None, "no tests"
    for key, what in ((RUN_ORDER_COLUMN, "the manifest's run_order column"),
                      (STARTED_COLUMN, "the tests' start time stamps (started)")):
        vals = [t.meta.get(key) for t in tests]
        if any(v is None or v == "" for v in vals):
            continue
        if key == STARTED_COLUMN:
            x = np.asarray([parse_started(v) for v in vals], dtype=np.float64)
        else:
            raw = np.asarray([float(v) for v in vals], dtype=np.float64)
            x = np.argsort(np.argsort(raw, kind="stable"), kind="stable").astype(np.float64)
        span = float(np.ptp(x)) if len(x) > 1 else 0.0
        if span <= 0:
            return None, f"{what} gives every test the same place"
        return (x - x.min()) / span, what
    return None, ("no run order stated: neither a run_order column nor start time stamps (started) for every "
                  "test; the manifest's order is the order it lists the tests in (often sorted by frequency or "
                  "control), not the order they were run in")


def run_positions(tests) -> np.ndarray:
    """Each test's place in [0, 1]: the stated run order, else the dataset's order (what the
    run-order fix, dampnet.data.artefacts.remove_run_order_drift, applies the drift along)."""
    pos, _ = stated_run_order(tests)
    if pos is not None:
        return pos
    n = len(list(tests))
    return np.arange(n) / (n - 1) if n > 1 else np.zeros(n)
