"""atheris harness over the damper spec strings (MODEL of `dampnet simulate` / `vehicle`:
'linear:C', 'truth', 'truth:EFFECT,...', a model directory or model.json, a lookup-table JSON):
any text gives a damper that evaluates to a finite force, or the project's own error (LoopError,
ModelError) in one line, never another exception.

The input is the MODEL string (UTF-8, undecodable bytes kept as surrogates, as Python passes a
command line's). It runs in a folder holding a valid model directory `m` (export's default
model), a lookup table `t.json` and a broken `bad.json`, so that mutations reach the files too.

Run (from the repository root, in the project's venv with the `fuzz` extra):
  cp -r fuzz/python/corpus_damper_specs /tmp/specs
  python fuzz/python/fuzz_damper_specs.py /tmp/specs -runs=1000000 -max_len=256
"""

from __future__ import annotations

import json
import math
import os
import shutil
import sys
import tempfile
from pathlib import Path

import atheris

from dampnet.model import ModelError
from dampnet.sim.dampers import load_spec, runtime_damper, steady_forces
from dampnet.sim.vehicle import LoopError

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from fuzz_readers import _instrument_dampnet  # noqa: E402  (the same instrumentation as the readers')

REPO = Path(__file__).resolve().parents[2]
EXPECTED = (LoopError, ModelError)
TABLE = {"velocities": [-1.0, 0.0, 1.0], "voltages": [0.0, 5.0],
         "forces": [[-1000.0, 0.0, 1000.0], [-2000.0, 0.0, 2000.0]]}


def make_workdir() -> Path:
    """The folder the specs are read in: a model directory, a lookup table, a broken JSON. In
    $DAMPNET_FUZZ_WORK when set (the test's temporary folder), else a new one on tmpfs."""
    base = "/dev/shm" if os.path.isdir("/dev/shm") and os.access("/dev/shm", os.W_OK) else None
    given = os.environ.get("DAMPNET_FUZZ_WORK")
    work = Path(given) if given else Path(tempfile.mkdtemp(prefix="dampnet-fuzz-specs-", dir=base))
    (work / "m").mkdir(exist_ok=True)
    shutil.copy(REPO / "export" / "dn_model_default.json", work / "m" / "model.json")
    (work / "t.json").write_text(json.dumps(TABLE))
    (work / "bad.json").write_text('{"velocities": [1, 0], "forces": "x"}')
    return work


def check_one(text: str) -> None:
    """load_spec(text) and the runtime's damper of it: a finite force, or a one-line error."""
    try:
        spec = load_spec(text)
        forces = steady_forces(spec, [-0.5, 0.0, 0.5], 0.5 * (spec.u_range[0] + spec.u_range[1]))
        runtime_damper(spec)
    except EXPECTED as e:
        msg = str(e)
        if "\n" in msg or "\r" in msg or not msg or len(msg) > 2000:
            raise AssertionError(f"not a one-line error for {text!r}: {msg!r}") from None
        return
    if not all(math.isfinite(f) for f in forces):
        raise AssertionError(f"{text!r}: non-finite steady force {forces}")


def test_one_input(data: bytes) -> None:
    check_one(data.decode("utf-8", "surrogateescape"))


def main() -> None:
    # the corpus directories as given, before the harness moves into its folder
    argv = [a if a.startswith("-") or i == 0 else os.path.abspath(a) for i, a in enumerate(sys.argv)]
    os.chdir(make_workdir())
    _instrument_dampnet()
    atheris.Setup(argv, test_one_input)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
