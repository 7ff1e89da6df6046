"""The in-memory dyno dataset: tests of time series in SI units, and the data error.

Channel names and their SI units (the only units used inside dampnet):

  displacement [m]   positive in extension (rebound)
  velocity     [m/s] positive in extension
  force        [N]   positive when the damper resists extension (tension)
  voltage      [V]   control input of a voltage-controlled damper
  current      [A]   control input of a current-controlled damper
  temperature  [degC] oil or body temperature, optional
  acceleration [m/s^2] derived by `dampnet.data.preprocess.add_acceleration`
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

#: The virtual rig's id in a dataset's meta.json "generator" field. Its value is the rig's first
#: module path; data files carry it, so it stays although the rig now lives in dampnet.rig.
RIG_GENERATOR = "dampnet.data.rig"

#: SI unit of each known channel.
CHANNEL_UNITS = {
    "time": "s",
    "displacement": "m",
    "velocity": "m/s",
    "force": "N",
    "voltage": "V",
    "current": "A",
    "temperature": "degC",
    "acceleration": "m/s^2",
}

#: The column name each known channel has in the dataset format (name_unit).
FILE_COLUMNS = {
    "time": "time_s",
    "displacement": "displacement_m",
    "velocity": "velocity_m_s",
    "force": "force_n",
    "voltage": "voltage_v",
    "current": "current_a",
    "temperature": "temperature_c",
    "acceleration": "acceleration_m_s2",
}
COLUMN_CHANNELS = {v: k for k, v in FILE_COLUMNS.items()}

CONTROL_NAMES = ("voltage", "current")
REQUIRED = ("displacement", "velocity", "force")
MIN_SAMPLES = 10
#: the largest |control| a run or a file may state, in the control's unit (V for voltage, A for
#: current): far beyond any damper's command (a semi-active damper takes 0-10 V or 0-5 A), so it
#: only refuses nonsense (a channel map's `[control] voltage = 1e308`, issue 49). The one limit:
#: dampnet.sim.limits.CONTROL_V (`simulate --u`) is read from it.
CONTROL_MAX = 1e3
#: the sample intervals [s] a lab file's time base may state: 10 MHz to 0.1 Hz (issue 49: a TDMS
#: wf_increment of 1e-300 s was taken, giving frequencies of 6e296 Hz; an RPC DELTA_T of nan)
DT_RANGE_S = (1e-7, 10.0)


class DataError(ValueError):
    """Input data are not what dampnet expects.

    The message names the file, the line or column, and what was expected,
    e.g. ``run3.csv: line 17, column force_n: expected a number, got 'abc'``.
    """


@dataclass
class DynoTest:
    """One dyno test: time series sampled at `time` [s], channels in SI units.

    `channels` maps a channel name (see `CHANNEL_UNITS`) to a 1-D float64 array
    the length of `time`. `frequency_hz` [Hz] and `amplitude_m` [m] describe a
    sine excitation (None for random or road-profile tests); `control_nominal`
    is the manifest's nominal control value ([V] or [A], per `control_name`).
    """

    test_id: str
    time: np.ndarray
    channels: dict[str, np.ndarray]
    frequency_hz: float | None = None
    amplitude_m: float | None = None
    control_nominal: float | None = None
    control_name: str = "voltage"
    meta: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return int(np.asarray(self.time).shape[0])

    @property
    def control(self) -> np.ndarray:
        """The control input channel ([V] or [A])."""
        return self.channels[self.control_name]

    @property
    def dt(self) -> float:
        """Median sample interval [s] (kept with the `time` array it was computed from: the
        diagnosis asks it thousands of times, and a median of every interval each time cost
        3 s on the thesis plan)."""
        cached = self.__dict__.get("_dt_of")
        if cached is None or cached[0] is not self.time:
            cached = (self.time, float(np.median(np.diff(self.time))))
            self.__dict__["_dt_of"] = cached
        return cached[1]

    def copy(self, **changes) -> "DynoTest":
        """A copy with its own arrays (and `changes` applied)."""
        t = replace(self, time=np.array(self.time, dtype=np.float64),
                    channels={k: np.array(v, dtype=np.float64) for k, v in self.channels.items()},
                    meta=dict(self.meta))
        return replace(t, **changes) if changes else t


@dataclass
class Dataset:
    """A list of dyno tests plus provenance.

    `source` is a path or description; `meta` holds what produced the data
    (for the virtual rig: seed, plan, effects, truth parameters, noise levels).
    """

    tests: list[DynoTest]
    source: str
    meta: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.tests)

    def __iter__(self):
        return iter(self.tests)

    def __getitem__(self, key) -> DynoTest:
        if isinstance(key, str):
            for t in self.tests:
                if t.test_id == key:
                    return t
            raise KeyError(key)
        return self.tests[key]

    @property
    def test_ids(self) -> list[str]:
        return [t.test_id for t in self.tests]

    def subset(self, tests: list[DynoTest], note: str | None = None) -> "Dataset":
        """A dataset of `tests` keeping this one's provenance."""
        meta = dict(self.meta)
        if note:
            meta["derived"] = list(meta.get("derived", [])) + [note]
        return Dataset(tests=list(tests), source=self.source, meta=meta)

    def concat(self, name: str = "force") -> np.ndarray:
        """One channel of all tests, concatenated."""
        return np.concatenate([t.channels[name] for t in self.tests]) if self.tests else np.zeros(0)
