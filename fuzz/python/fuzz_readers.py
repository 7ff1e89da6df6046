"""atheris harness over dampnet's Python readers: any bytes give a loaded, valid object or
the project's own error (DataError, ModelError), never another exception or a hang.

The first byte picks the reader (so one harness and one corpus cover them all):

  0  dataset directory: manifest.csv + one test CSV (the rest split by a length byte)
  1  single text file with unit-bearing columns (read_text)
  2  MATLAB .mat file (read_mat with a fixed mapping)
  3  model.json (MlpModel.load)
  4  dataset meta.json (read_dataset_dir over a valid manifest and test)

Run (from the repository root, in the project's venv with the `fuzz` extra):
  python fuzz/python/fuzz_readers.py fuzz/python/corpus -runs=10000000 -max_len=4096
See fuzz/python/README.md for the recorded long run.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import atheris

import numpy as np

from dampnet import schema  # noqa: F401  (loaded, so _instrument_dampnet covers it)
from dampnet.data import DataError, load_dataset
from dampnet.data.fileformat import read_dataset_dir
from dampnet.data.readers import read_mat, read_text
from dampnet.data.validate import check_test
from dampnet.model import MlpModel, ModelError


def _instrument_dampnet() -> int:
    """Coverage instrumentation of every function of the loaded dampnet modules, in place.

    (atheris.instrument_imports skips modules of an editable install, whose finder is a
    custom loader; instrumenting the functions after import works for either install.)"""
    import inspect
    import types

    done = 0
    for name, mod in list(sys.modules.items()):
        if not name.startswith("dampnet") or not isinstance(mod, types.ModuleType):
            continue
        for obj in list(vars(mod).values()):
            funcs = [obj] if inspect.isfunction(obj) else (
                [f for f in vars(obj).values() if inspect.isfunction(f)] if inspect.isclass(obj) else [])
            for f in funcs:
                if f.__module__ == name and not getattr(f, "_dn_fuzz_instrumented", False):
                    atheris.instrument_func(f)
                    f._dn_fuzz_instrumented = True
                    done += 1
    return done

# tmpfs when there is one: the harness writes a file or two per input
_BASE = "/dev/shm" if os.path.isdir("/dev/shm") and os.access("/dev/shm", os.W_OK) else None
WORK = Path(tempfile.mkdtemp(prefix="dampnet-fuzz-", dir=_BASE))
DATASET = WORK / "ds"
DATASET.mkdir()
SINGLE = WORK / "single.csv"
MATFILE = WORK / "single.mat"
MODEL = WORK / "model.json"

VALID_MANIFEST = b"test_id,file,frequency_hz,amplitude_m,voltage_v\nt1,t1.csv,1,0.01,0\n"
VALID_TEST = b"time_s,displacement_m,velocity_m_s,force_n,voltage_v\n" + b"".join(
    b"%g,%g,%g,%g,0\n" % (k * 1e-3, 0.01 * np.sin(k / 3), 0.01 * np.cos(k / 3), 100 * np.cos(k / 3))
    for k in range(12))
MAT_MAPPING = {"displacement_mm": "x:0", "velocity_mm_s": "x:1", "force_n": "x:2", "voltage_v": "u"}

EXPECTED = (DataError, ModelError)


def _write(path: Path, data: bytes) -> None:
    with open(path, "wb") as f:
        f.write(data)


def _check_dataset(ds) -> None:
    """A loaded dataset must be complete: every test passes the checks the reader applies."""
    assert ds.tests, "a dataset without tests was returned"
    for t in ds.tests:
        check_test(t, "fuzz")
    assert isinstance(ds.meta, dict)


def one_input(data: bytes) -> None:
    if not data:
        return
    target, rest = data[0] % 5, data[1:]
    try:
        if target == 0:
            n = rest[0] * 16 if rest else 0
            _write(DATASET / "manifest.csv", rest[1:1 + n])
            _write(DATASET / "t1.csv", rest[1 + n:])
            (DATASET / "meta.json").unlink(missing_ok=True)
            _check_dataset(read_dataset_dir(DATASET))
        elif target == 1:
            _write(SINGLE, rest)
            _check_dataset(load_dataset(SINGLE, voltage=1.0))
            read_text(SINGLE, dt=1e-3, current=0.5, motion_positive="compression")
        elif target == 2:
            _write(MATFILE, rest)
            check_test(read_mat(MATFILE, mapping=MAT_MAPPING, dt=1e-3), "fuzz")
        elif target == 3:
            _write(MODEL, rest)
            MlpModel.load(MODEL).validate()
        else:
            _write(DATASET / "manifest.csv", VALID_MANIFEST)
            _write(DATASET / "t1.csv", VALID_TEST)
            _write(DATASET / "meta.json", rest)
            _check_dataset(read_dataset_dir(DATASET))
    except EXPECTED as e:
        msg = str(e)
        assert "\n" not in msg, f"multi-line error: {msg[:300]!r}"
        assert len(msg) < 2000, f"a {len(msg)}-character error: {msg[:300]!r}"
        assert "np.float64(" not in msg and "np.int64(" not in msg, f"numpy repr in: {msg[:300]!r}"


def main() -> None:
    _instrument_dampnet()
    atheris.Setup(sys.argv, one_input)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
