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

THESIS_FREQUENCIES_HZ = tuple(0.25 * k for k in range(1, 13))


@dataclass
class Plan:
    """A test plan (SI units)."""

    name: str
    frequencies_hz: list[float]
    amplitudes_m: list[float]
    voltages_v: list[float]
    sample_rate_hz: float = 5000.0
    samples: int = 10000
    min_cycles: float = 2.0
    excitation: str = "sine"
    band_hz: list[float] = field(default_factory=lambda: [0.5, 5.0])
    duration_s: float = 4.0
    control: dict = field(default_factory=lambda: {"waveform": "constant"})

    def __post_init__(self):
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
