"""atheris harness over the lab-file readers (dampnet.data.lab): any bytes give checked tests or
a one-line DataError, never another exception, a crash of the interpreter or a hang.

The first byte picks the target (one harness, one corpus: corpus_lab/):

  0  a TDMS file (nptdms), with the channel map of the seeds
  1  an MDF file (.mf4, asammdf)
  2  an RPC III file (.rsp, rpc3-file)
  3  the channel map (dampnet-channels.toml) beside a valid TDMS file

The libraries read in a child process (dampnet.data.child), so a crash there is the parent's
DataError; libFuzzer sees the parent's coverage (channel map, units, time bases, checks), not
the library's inside the child.

Run (from the repository root, in the project's venv with the `fuzz` and `lab` extras):
  python fuzz/python/fuzz_lab.py fuzz/python/corpus_lab -runs=100000 -max_len=16384
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import atheris

import asammdf  # noqa: F401  (imported once in the parent: each child process inherits it)
import nptdms  # noqa: F401
import rpc3  # noqa: F401

from dampnet.data import DataError
from dampnet.data.lab import MAP_FILE, read_lab_file
from dampnet.data.validate import check_test

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fuzz_readers import _instrument_dampnet  # noqa: E402

MAP = b"""[channels]
displacement = "Disp"
force = "Force"
voltage = "Command"
"""
_BASE = "/dev/shm" if os.path.isdir("/dev/shm") and os.access("/dev/shm", os.W_OK) else None
WORK = Path(tempfile.mkdtemp(prefix="dampnet-fuzz-lab-", dir=_BASE))
FILES = {0: WORK / "run.tdms", 1: WORK / "run.mf4", 2: WORK / "run.rsp"}
SEED_DIR = Path(__file__).resolve().parent / "corpus_lab"


def _write(path: Path, data: bytes) -> None:
    with open(path, "wb") as f:
        f.write(data)


def _valid_tdms() -> bytes:
    """The corpus's valid TDMS seed (what target 3 puts beside a fuzzed channel map)."""
    return (SEED_DIR / "tdms_valid").read_bytes()[1:]


def one_input(data: bytes) -> None:
    if not data:
        return
    target, rest = data[0] % 4, data[1:]
    try:
        if target == 3:
            _write(FILES[0], VALID_TDMS)
            _write(WORK / MAP_FILE, rest)
            path = FILES[0]
        else:
            _write(WORK / MAP_FILE, MAP)
            path = FILES[target]
            _write(path, rest)
        for t in read_lab_file(path):
            check_test(t, "fuzz")
    except DataError as e:
        msg = str(e)
        assert "\n" not in msg, f"multi-line error: {msg[:300]!r}"
        assert len(msg) < 2000, f"a {len(msg)}-character error: {msg[:300]!r}"
        assert "np.float64(" not in msg and "np.int64(" not in msg, f"numpy repr in: {msg[:300]!r}"


VALID_TDMS = _valid_tdms()


def main() -> None:
    _instrument_dampnet()
    atheris.Setup(sys.argv, one_input)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
