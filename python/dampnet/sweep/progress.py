"""The sweep's progress on stderr: cells done of all, errors, elapsed time and the time left.

On a terminal (stderr a TTY): a tqdm bar `sweep: 40%|####  | 12/30 [00:24<00:36, 0.5 cell/s, errors=1]`
(the time left is tqdm's estimate from the rate so far). Not on a terminal (a log, a pipe, a
batch job): one plain line at most every LOG_EVERY_S seconds,
`dampnet sweep: 12/30 cells (1 error), 24 s elapsed, about 36 s left`, and none for a sweep
faster than that. enabled=False: nothing.
"""

from __future__ import annotations

import sys
import time

LOG_EVERY_S = 10.0


class CellProgress:
    def __init__(self, total: int, enabled: bool = True, stream=None):
        self.total, self.done, self.errors = total, 0, 0
        self.stream = stream or sys.stderr
        self.t0 = self.last = time.monotonic()
        self.bar = None
        self.log = False
        if enabled and total:
            if getattr(self.stream, "isatty", lambda: False)():
                from tqdm import tqdm

                self.bar = tqdm(total=total, desc="sweep", unit="cell", file=self.stream)
            else:
                self.log = True

    def update(self, ok: bool) -> None:
        self.done += 1
        self.errors += 0 if ok else 1
        if self.bar is not None:
            if not ok:
                self.bar.set_postfix(errors=self.errors, refresh=False)
            self.bar.update(1)
        elif self.log and time.monotonic() - self.last >= LOG_EVERY_S:
            self.last = time.monotonic()
            self.stream.write(self.line() + "\n")
            self.stream.flush()

    def line(self) -> str:
        el = time.monotonic() - self.t0
        left = el / self.done * (self.total - self.done) if self.done else float("nan")
        errs = f" ({self.errors} error{'s' if self.errors != 1 else ''})" if self.errors else ""
        return (f"dampnet sweep: {self.done}/{self.total} cells{errs}, {el:.0f} s elapsed, "
                f"about {left:.0f} s left")

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None
