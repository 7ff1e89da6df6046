"""The ranges of a run's numeric settings and the size a run may reach: the one place for these
checks of `dampnet simulate`, `study` and `vehicle` and of the Python entry points they call
(`Road.sample`, the full-vehicle maneuvers). A setting out of range or a run too large is refused
up front, naming the option, its unit and the range or limit, instead of allocating until
MemoryError or failing deep inside numpy.

The physical plausibility of a run's state (travel, wheel to road, damper speed, roll and pitch)
is the runtime's: `PLAUSIBLE` (dampnet.h DN_PLAUSIBLE_LIST), checked at every step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from dampnet import _core
from dampnet.data.types import CONTROL_MAX

#: values one run may hold: steps x the values each step keeps (state and report). 1e8 float64
#: values are 800 MB: a quarter-car run of 2.5 million steps, a full-car run of 1 million.
MAX_RUN_VALUES = 100_000_000
#: values per step of a quarter-car run (QuarterCar.simulate: state, report, neural features)
QUARTER_CAR_VALUES = len(_core.STATE_NAMES) + len(_core.STEP_OUTPUT_FIELDS) - 1 + _core.MAX_INPUTS
#: values per step of a full-car run (FullCar.simulate: state, per-corner and body reports, road)
FULL_CAR_VALUES = (len(_core.FULLCAR_STATE_NAMES) + len(_core.FULLCAR_CORNERS) *
                   (len(_core.FULLCAR_OUT_CORNER_FIELDS) + 3) + len(_core.FULLCAR_OUT_FIELDS) + 1)
#: the physical bounds of the runtime's state [SI units]: {name: (value, doc)} (DN_PLAUSIBLE_LIST)
PLAUSIBLE = _core.PLAUSIBLE_BOUNDS


@dataclass(frozen=True)
class Range:
    """A numeric setting's range: lo < x (lo_open) or lo <= x, and x <= hi, in `unit`."""

    lo: float
    hi: float
    unit: str
    lo_open: bool = False

    def text(self) -> str:
        return f"{'(' if self.lo_open else '['}{self.lo:g}, {self.hi:g}] {self.unit}"


#: the loop's step: from a 1 MHz loop to 10 ms (beyond it the 11 Hz wheel hop is under-resolved)
STEP_S = Range(1e-6, 0.01, "s")
#: forward speed: the full car's limit (dn_fullcar_params.speed <= 100 m/s)
SPEED_M_S = Range(0.0, 100.0, "m/s", lo_open=True)
SPEED_KMH = Range(0.0, 360.0, "km/h", lo_open=True)
#: the switching laws' command filter time constant (0: unfiltered)
COMMAND_TAU_S = Range(0.0, 10.0, "s")
#: a passive control (dampnet.data.types.CONTROL_MAX: the one control limit, the channel map's too)
CONTROL_V = Range(-CONTROL_MAX, CONTROL_MAX, "V")
#: a random road's seed (numpy's SeedSequence takes any integer >= 0; the rough road uses seed + 1)
SEED = Range(0, 2**32 - 2, "")


def check_number(option: str, value, rng: Range) -> float:
    """value as a float within rng; ValueError "OPTION: expected a finite number in RANGE, got X"."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    ok = math.isfinite(v) and (v > rng.lo if rng.lo_open else v >= rng.lo) and v <= rng.hi
    if not ok:
        raise ValueError(f"{option}: expected a finite number in {rng.text()}, got {value!r}")
    return v


def check_seed(option: str, value) -> int:
    """A seed: an integer in SEED's range; ValueError naming the option otherwise."""
    if isinstance(value, bool) or not isinstance(value, int) or not SEED.lo <= value <= SEED.hi:
        raise ValueError(f"{option}: expected an integer in [{SEED.lo}, {SEED.hi}], got {value!r}")
    return value


def check_run_size(steps: float, values_per_step: int, what: str, hint: str) -> int:
    """The number of steps as an int when steps x values_per_step <= MAX_RUN_VALUES; ValueError
    naming the run (`what`), its size, the limit and what to change (`hint`) otherwise. `steps`
    may be a float of any size (computed as duration / dt before anything is allocated)."""
    total = steps * values_per_step
    if not total <= MAX_RUN_VALUES:   # NaN and inf too
        raise ValueError(f"{what}: {steps:.3g} steps x {values_per_step} values = {total:.3g}, beyond the "
                         f"limit of {MAX_RUN_VALUES:.0e} values a run may hold (dampnet.sim.limits."
                         f"MAX_RUN_VALUES, {8 * MAX_RUN_VALUES / 1e6:.0f} MB): {hint}")
    return int(steps)
