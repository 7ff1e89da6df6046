"""Loaders for the two real MR-damper data sets kept (read-only) in ../shared/data.

Both are loaded as Datasets with their control input; nothing is copied.
Where the data live: $DAMPNET_SHARED_DATA, else <project root>/../shared/data.

utfsm_mr_damper_mts (`load_utfsm`): 30 sine tests on an MTS machine, files
  preprocessed/<amp>mm<freq>Hz<current>A.txt ('x' = decimal point), columns
  t [s], x [mm], dx [mm/s], F [N], no header. Control: coil current [A],
  constant per test (from the name). Velocity was differentiated by the
  authors, not measured. The rig's sign convention is not documented; the
  data are loaded as recorded (pass motion_positive/force_positive to flip).

labcontrol_mr_damper (`load_labcontrol`): sine tests on a small shaking
  table, MATLAB files with x_F = [position mm, velocity mm/s, force N] and Ts.
  Control voltage per series is inferred (README, from Ensaios.ods):
  ensaio<k>.1 -> 0 V, ensaio<k>.2.2 -> 0.8712 V, ensaio.B.* -> 1.98 V,
  ensaio.A.* -> 3.212 V. Other files (ensaio<k>.mat, ensaio<k>.2.mat,
  validation and simulation files) have no stated voltage and are skipped,
  listed in meta['skipped']. Frequency and amplitude are estimated from the
  displacement (spectral peak; half the 1-99 % range) and marked so in test.meta.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from dampnet.data.excitation import estimate_sine
from dampnet.data.readers import read_mat, read_text
from dampnet.data.types import DataError, Dataset, DynoTest

UTFSM = "utfsm_mr_damper_mts"
LABCONTROL = "labcontrol_mr_damper"

_UTFSM_NAME = re.compile(r"^(?P<amp>[0-9x]+)mm(?P<freq>[0-9x]+)Hz(?P<cur>[0-9x]+)A$")
LABCONTROL_VOLTAGES = ((re.compile(r"^ensaio\d+\.1$"), 0.0), (re.compile(r"^ensaio\d+\.2\.2$"), 0.8712),
                       (re.compile(r"^ensaio\.B\.\d+$"), 1.98), (re.compile(r"^ensaio\.A\.\d+$"), 3.212))


def shared_data_dir() -> Path:
    """The shared real-data directory ($DAMPNET_SHARED_DATA or <project>/../shared/data)."""
    env = os.environ.get("DAMPNET_SHARED_DATA")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[3].parent / "shared" / "data"


def _dir(name: str, root) -> Path:
    d = Path(root) if root is not None else shared_data_dir()
    d = d / name
    if not d.is_dir():
        raise DataError(f"{d}: not found: expected the {name} data set (set DAMPNET_SHARED_DATA)")
    return d


def _num(s: str) -> float:
    return float(s.replace("x", "."))


def load_utfsm(root=None, **options) -> Dataset:
    """The UTFSM MTS sine tests (30) as a current-controlled Dataset (SI units)."""
    d = _dir(UTFSM, root) / "preprocessed"
    files = sorted(d.glob("*.txt"))
    if not files:
        raise DataError(f"{d}: no .txt files: expected 30 preprocessed tests")
    tests = []
    for f in files:
        m = _UTFSM_NAME.match(f.stem)
        if not m:
            raise DataError(f"{f}: file name: expected <amp>mm<freq>Hz<current>A, e.g. 25mm0x5Hz0x75A")
        t = read_text(f, columns=["time_s", "displacement_mm", "velocity_mm_s", "force_n"],
                      current=_num(m["cur"]), test_id=f.stem, frequency_hz=_num(m["freq"]),
                      amplitude_m=_num(m["amp"]) * 1e-3, **options)
        t.meta.update({"velocity": "differentiated by the authors", "source_file": str(f)})
        tests.append(t)
    return Dataset(tests=tests, source=str(d), meta={
        "name": UTFSM, "damper": "MR damper, MTS uniaxial machine (UTFSM, Chile)", "license": "MIT",
        "control": "coil current [A], constant per test, from the file name",
        "sign_convention": "as recorded (not documented by the authors)"})


def _estimate_sine(t: DynoTest) -> tuple[float, float]:
    f, amp, _ = estimate_sine(t.channels["displacement"], t.dt)
    return f, amp


def labcontrol_voltage(stem: str) -> float | None:
    """The inferred control voltage [V] of a Labcontrol file stem, or None if not stated."""
    for pat, v in LABCONTROL_VOLTAGES:
        if pat.match(stem):
            return v
    return None


def load_labcontrol(root=None, **options) -> Dataset:
    """The Labcontrol shaking-table sine tests with an inferred voltage, as a Dataset (SI units)."""
    d = _dir(LABCONTROL, root)
    mapping = {"displacement_mm": "x_F:0", "velocity_mm_s": "x_F:1", "force_n": "x_F:2"}
    tests, skipped = [], []
    for f in sorted(d.glob("*.mat")):
        stem = f.name[:-4]
        v = labcontrol_voltage(stem)
        if v is None:
            skipped.append(f.name)
            continue
        t = read_mat(f, mapping=mapping, dt="Ts", voltage=v, test_id=stem, **options)
        t.frequency_hz, t.amplitude_m = _estimate_sine(t)
        t.meta.update({"frequency_hz": "estimated from displacement", "amplitude_m": "estimated (half 1-99 % range)",
                       "voltage": "inferred from Ensaios.ods (README)", "source_file": str(f)})
        tests.append(t)
    if not tests:
        raise DataError(f"{d}: no ensaio*.mat files with a known voltage")
    return Dataset(tests=tests, source=str(d), meta={
        "name": LABCONTROL, "damper": "MR damper on a small shaking table (UTFPR, Brazil)", "license": "MIT",
        "control": "voltage [V], constant per series, inferred from Ensaios.ods", "skipped": skipped,
        "sign_convention": "as recorded (not documented by the authors)"})


def load_real(name: str, root=None, **options) -> Dataset:
    """Load a real data set by folder name ('utfsm_mr_damper_mts' or 'labcontrol_mr_damper')."""
    loaders = {UTFSM: load_utfsm, LABCONTROL: load_labcontrol, "utfsm": load_utfsm, "labcontrol": load_labcontrol}
    if name not in loaders:
        raise ValueError(f"unknown real data set {name!r}: expected {UTFSM} or {LABCONTROL}")
    return loaders[name](root, **options)
