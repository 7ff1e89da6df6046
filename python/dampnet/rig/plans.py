"""Test plans for the virtual dyno: which tests to run, with what excitation and control.

`thesis`: Table 2 of the reference thesis, 12 frequencies 0.25-3 Hz x 15
voltages 0-5 V (180 tests, numbered T001-T180 in Table 2's order), sine of
1 inch amplitude (2-inch stroke), sampled at the dyno's 5 kHz.

Two full cycles: the Intercomp dyno exported 10,000 samples per test (2 s at
5 kHz), which is half a cycle at 0.25 Hz. The rig keeps the 5 kHz rate and
lengthens short tests: a test has max(samples, ceil(min_cycles * fs / f))
samples, so 0.25 Hz tests run 8 s (40,000 samples), 0.5 Hz 4 s, 0.75 Hz 2.67 s,
and tests at 1 Hz and above keep 10,000 samples (2-6 cycles).

`quick` (for tests): 0.25, 1 and 3 Hz x 0, 2.25 and 5 V (9 tests) - spans the
frequency and voltage ranges and keeps the thesis's 2.25 V hold-out; same
amplitude and rate, 2,500 samples minimum (still two cycles per test).

Other plans: a JSON file, e.g.
  {"name": "mine", "frequencies_hz": [0.5, 2], "amplitudes_m": [0.0254, 0.0127],
   "voltages_v": [0, 2.5, 5], "sample_rate_hz": 5000, "samples": 10000, "min_cycles": 2,
   "excitation": "sine", "control": {"waveform": "constant"}}
Or an explicit list of sines (what `dampnet plan-tests` writes), instead of the grid:
  {"name": "extra", "tests": [{"frequency_hz": 15, "amplitude_m": 0.02, "control": 5.0}, ...],
   "min_cycles": 3, "samples": 2500}
each test a sine of `frequency_hz` [Hz] and `amplitude_m` [m] at the constant control level
`control` [V] (optional `test_id`, default T001...); `about` (any JSON object) is kept in the
dataset's meta and not used.
excitation: "sine" (every frequency x amplitude x voltage) or "random"
(band-limited random displacement, `amplitudes_m` = RMS, `band_hz` = [lo, hi],
`duration_s`; frequency_hz is recorded as 0). control.waveform: "constant"
or "steps" (switch every `period_s` among `levels_v`, starting at the nominal).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

from dampnet.rig.truth import INCH, TABLE2_VOLTAGE_V

#: the rig's sample rate [Hz] (a plan's default; track replays are upsampled to it)
RATE_HZ = 5000.0
THESIS_FREQUENCIES_HZ = tuple(0.25 * k for k in range(1, 13))


@dataclass
class Plan:
    """A test plan (SI units)."""

    name: str
    frequencies_hz: list[float] = field(default_factory=list)
    amplitudes_m: list[float] = field(default_factory=list)
    voltages_v: list[float] = field(default_factory=list)
    sample_rate_hz: float = RATE_HZ
    samples: int = 10000
    min_cycles: float = 2.0
    excitation: str = "sine"
    band_hz: list[float] = field(default_factory=lambda: [0.5, 5.0])
    duration_s: float = 4.0
    control: dict = field(default_factory=lambda: {"waveform": "constant"})
    #: explicit sines [{frequency_hz, amplitude_m, control, test_id?}] instead of the grid (None: the grid)
    tests: list[dict] | None = None
    #: free description (what planned the tests), kept in the dataset's meta
    about: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.tests is not None:
            self.tests = _check_tests(self.name, self.tests)
            if self.excitation != "sine":
                raise ValueError(f"plan {self.name}: tests: explicit tests are sines; excitation must be 'sine'")
            if not self.voltages_v:   # the control levels (what the effects step among)
                self.voltages_v = sorted({t["control"] for t in self.tests})
            if not self.amplitudes_m:
                self.amplitudes_m = sorted({t["amplitude_m"] for t in self.tests})
            if not self.frequencies_hz:
                self.frequencies_hz = sorted({t["frequency_hz"] for t in self.tests})
        if not isinstance(self.about, dict):
            raise ValueError(f"plan {self.name}: about: expected a JSON object")
        if self.excitation not in ("sine", "random"):
            raise ValueError(f"plan {self.name}: excitation: expected 'sine' or 'random', got {self.excitation!r}")
        if self.control.get("waveform", "constant") not in ("constant", "steps"):
            raise ValueError(f"plan {self.name}: control.waveform: expected 'constant' or 'steps'")
        if not self.voltages_v or not self.amplitudes_m:
            raise ValueError(f"plan {self.name}: expected at least one voltage and one amplitude")
        if self.excitation == "sine" and (not self.frequencies_hz or min(self.frequencies_hz) <= 0):
            raise ValueError(f"plan {self.name}: frequencies_hz: expected positive frequencies for sines")
        if self.sample_rate_hz <= 0 or self.samples < 10:
            raise ValueError(f"plan {self.name}: expected sample_rate_hz > 0 and samples >= 10")

    def n_samples(self, frequency_hz: float | None) -> int:
        """Samples of a test: at least `samples` and at least `min_cycles` full cycles."""
        if self.excitation == "random":
            return max(self.samples, int(math.ceil(self.duration_s * self.sample_rate_hz)))
        return max(self.samples, int(math.ceil(self.min_cycles * self.sample_rate_hz / frequency_hz - 1e-9)) + 1)

    def specs(self) -> list[dict]:
        """One dict per test: test_id, frequency_hz, amplitude_m, voltage_v, n."""
        out = []
        if self.tests is not None:
            for t in self.tests:
                out.append({"frequency_hz": t["frequency_hz"], "amplitude_m": t["amplitude_m"],
                            "voltage_v": t["control"], "n": self.n_samples(t["frequency_hz"])})
            width = max(3, len(str(len(out))))
            for i, (s, t) in enumerate(zip(out, self.tests), start=1):
                s["test_id"] = t.get("test_id") or f"T{i:0{width}d}"
            return out
        freqs = self.frequencies_hz if self.excitation == "sine" else [None]
        for f in freqs:
            for a in self.amplitudes_m:
                for v in self.voltages_v:
                    out.append({"frequency_hz": f, "amplitude_m": a, "voltage_v": float(v),
                                "n": self.n_samples(f)})
        width = max(3, len(str(len(out))))
        for i, s in enumerate(out, start=1):
            s["test_id"] = f"T{i:0{width}d}"
        return out

    def to_dict(self) -> dict:
        return asdict(self)


TEST_KEYS = ("frequency_hz", "amplitude_m", "control", "test_id")


def _check_tests(name: str, tests) -> list[dict]:
    """Explicit tests, checked: a list of {frequency_hz > 0, amplitude_m > 0, control, test_id?};
    ValueError naming the test and the field."""
    if not isinstance(tests, list) or not tests:
        raise ValueError(f"plan {name}: tests: expected a non-empty list of "
                         "{frequency_hz, amplitude_m, control} objects")
    out, ids = [], set()
    for i, t in enumerate(tests):
        where = f"plan {name}: tests[{i}]"
        if not isinstance(t, dict):
            raise ValueError(f"{where}: expected an object {{frequency_hz, amplitude_m, control}}, got {t!r:.60}")
        unknown = sorted(set(t) - set(TEST_KEYS))
        if unknown:
            raise ValueError(f"{where}: unknown key(s) {unknown}: expected {', '.join(TEST_KEYS)}")
        row = {}
        for k in ("frequency_hz", "amplitude_m", "control"):
            if k not in t:
                raise ValueError(f"{where}.{k}: missing (expected {', '.join(TEST_KEYS[:3])})")
            v = t[k]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"{where}.{k}: expected a finite number, got {v!r:.60}")
            if k != "control" and v <= 0:
                raise ValueError(f"{where}.{k}: expected a positive number, got {v!r}")
            row[k] = float(v)
        if "test_id" in t:
            tid = t["test_id"]
            if not isinstance(tid, str) or not tid or not all(c.isalnum() or c in "-_" for c in tid):
                raise ValueError(f"{where}.test_id: expected letters, digits, '-' or '_', got {tid!r:.60}")
            if tid in ids:
                raise ValueError(f"{where}.test_id: {tid!r} appears twice")
            ids.add(tid)
            row["test_id"] = tid
        out.append(row)
    return out


def thesis_plan() -> Plan:
    return Plan(name="thesis", frequencies_hz=list(THESIS_FREQUENCIES_HZ), amplitudes_m=[INCH],
                voltages_v=list(TABLE2_VOLTAGE_V))


def quick_plan() -> Plan:
    return Plan(name="quick", frequencies_hz=[0.25, 1.0, 3.0], amplitudes_m=[INCH],
                voltages_v=[0.0, 2.25, 5.0], samples=2500)


def load_plan(plan) -> Plan:
    """A Plan from 'thesis', 'quick', a Plan, a dict, or a JSON file path."""
    if isinstance(plan, Plan):
        return plan
    if isinstance(plan, dict):
        return Plan(**plan)
    if plan == "thesis":
        return thesis_plan()
    if plan == "quick":
        return quick_plan()
    path = Path(plan)
    if not path.is_file():
        raise ValueError(f"plan {plan!r}: expected 'thesis', 'quick' or a JSON plan file")
    try:
        d = json.loads(path.read_text())
    except json.JSONDecodeError as e:
        raise ValueError(f"{path}: line {e.lineno}: expected a JSON plan ({e.msg})") from None
    known = set(Plan.__dataclass_fields__)
    unknown = set(d) - known
    if unknown:
        raise ValueError(f"{path}: unknown plan key(s) {sorted(unknown)}: expected some of {sorted(known)}")
    d.setdefault("name", path.stem)
    try:
        return Plan(**d)
    except TypeError as e:
        raise ValueError(f"{path}: {e}") from None
