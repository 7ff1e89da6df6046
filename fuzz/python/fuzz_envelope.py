"""atheris harness over the training-envelope reader (dampnet.envelope.read_envelope): any bytes
give an envelope that every user of one accepts, or the reader's own one-line EnvelopeError,
never another exception or a hang; and load_envelope (the coverage commands' fall-back) never
raises.

The first byte picks what the rest of the input is (one harness, one corpus):

  0  envelope.npz's bytes, beside a valid envelope.json of the default model
  1  envelope.json's bytes, beside a valid envelope.npz of the default model
  2  the npz's arrays themselves (atheris.FuzzedDataProvider: the number of inputs and of stored
     points, every value a float that may be NaN, Inf, 0, negative or huge, and now and then a
     wrong shape or an array left out), written as a valid .npz beside a matching envelope.json

An envelope that loads must work: its k-d tree distance, its runtime grid (envelope.grid: the C++
check), and, for the default model's (targets 0 and 1), coverage and the exported header.

Run (from the repository root, in the project's venv with the `fuzz` extra):
  python fuzz/python/fuzz_envelope.py fuzz/python/corpus_envelope -runs=100000 -max_len=8192
The seed corpus: `python fuzz/python/fuzz_envelope.py --write-corpus DIR`.
"""

from __future__ import annotations

import io
import json
import os
import sys
import tempfile
from pathlib import Path

import atheris

import numpy as np

from dampnet import schema  # noqa: F401  (loaded, so _instrument_dampnet covers it)
from dampnet.envelope.coverage import coverage
from dampnet.envelope import (ENVELOPE_JSON, ENVELOPE_NPZ, EnvelopeError, build_envelope, load_envelope,
                              read_envelope, save_envelope)
from dampnet.envelope.grid import grid_cells, runtime_flags
from dampnet.export import header_text
from dampnet.modeldir import default_model

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fuzz_readers import _instrument_dampnet  # noqa: E402  (the same instrumentation as the readers')

_BASE = "/dev/shm" if os.path.isdir("/dev/shm") and os.access("/dev/shm", os.W_OK) else None
WORK = Path(tempfile.mkdtemp(prefix="dampnet-fuzz-envelope-", dir=_BASE))
MODEL = default_model()
FEATURES = ["velocity", "acceleration", "voltage", "current", "position", "temperature", "u_lag", "v_lag"]


def seed_envelope():
    """A small valid envelope of the default model: 40 samples in its ranges."""
    X = np.random.default_rng(0).uniform(MODEL.sat_lo, MODEL.sat_hi, size=(40, MODEL.n_inputs))
    return build_envelope(MODEL, X)


def _valid_files() -> tuple[bytes, bytes]:
    d = WORK / "seed"
    save_envelope(seed_envelope(), d)
    return (d / ENVELOPE_NPZ).read_bytes(), (d / ENVELOPE_JSON).read_bytes()


VALID_NPZ, VALID_JSON = _valid_files()
PROBE = np.concatenate([np.random.default_rng(1).uniform(MODEL.sat_lo - 1, MODEL.sat_hi + 1, size=(16, 3)),
                        [[np.nan, 0.0, 0.0], [np.inf, -np.inf, 1e308]]])


def _write(path: Path, data: bytes) -> None:
    with open(path, "wb") as f:
        f.write(data)


def _arrays_from(fdp: atheris.FuzzedDataProvider) -> tuple[dict, int]:
    """The npz's arrays from the fuzzer's bytes (target 2): plausible values (ranges with lo <= hi,
    positive gains and threshold, points in [-1, 1]), one element of an array in four replaced by
    any float (NaN, Inf, 0, negative, huge), so that both sides of every check are reached."""
    n = fdp.ConsumeIntInRange(1, 8)
    m = fdp.ConsumeIntInRange(0, 24)

    def floats(k: int, lo: float, hi: float) -> np.ndarray:
        a = np.array([fdp.ConsumeFloatInRange(lo, hi) for _ in range(k)], dtype=np.float64)
        if k and fdp.ConsumeIntInRange(0, 3) == 0:
            a[fdp.ConsumeIntInRange(0, k - 1)] = fdp.ConsumeFloat()
        return a

    def one(lo: float, hi: float) -> float:
        return float(floats(1, lo, hi)[0])

    lo = floats(n, -1e3, 1e3)
    with np.errstate(over="ignore", invalid="ignore"):
        hi = lo + floats(n, 0.0, 1e3)
    arr = {"lo": lo, "hi": hi, "in_offset": lo, "in_gain": floats(n, 1e-6, 1e3),
           "in_ymin": np.array(one(-1.0, -1.0)), "threshold": np.array(one(1e-9, 2.0)),
           "points": floats(m * n, -1.0, 1.0).reshape(m, n)}
    if fdp.ConsumeIntInRange(0, 7) == 0:  # now and then a wrong shape or a missing array
        key = fdp.PickValueInList(sorted(arr))
        arr[key] = arr[key].reshape(-1)[: fdp.ConsumeIntInRange(0, 3)] if fdp.ConsumeBool() else None
    return {k: v for k, v in arr.items() if v is not None}, n


def _exercise(env, model) -> None:
    """What the commands do with a loaded envelope: none of it may fail."""
    # what coverage relies on: a finite positive threshold (NaN: never outside; negative: always),
    # stored samples to measure from (none: IndexError), a scaling that can be undone (gain 0)
    assert np.isfinite(env.threshold) and env.threshold > 0
    assert env.points.shape[0] >= 1 and np.all(np.isfinite(env.points))
    assert np.all(env.in_gain != 0) and np.all(env.lo <= env.hi)
    X = PROBE if model is not None else np.zeros((3, len(env.features)))
    d = env.distance(X)
    assert d.shape == (X.shape[0],) and not np.any(np.isnan(d))
    if len(env.features) > 1:  # one input has no pairs: its check is the range alone
        assert grid_cells(env).any(), "a grid that flags every point"
    runtime_flags(env, X)
    if model is not None:
        coverage(model, X, env)
        header_text(model, envelope=env)


def one_input(data: bytes) -> None:
    if not data:
        return
    target, rest = data[0] % 3, data[1:]
    d = WORK / "m"
    d.mkdir(exist_ok=True)
    model = MODEL
    if target == 0:
        _write(d / ENVELOPE_NPZ, rest)
        _write(d / ENVELOPE_JSON, VALID_JSON)
    elif target == 1:
        _write(d / ENVELOPE_NPZ, VALID_NPZ)
        _write(d / ENVELOPE_JSON, rest)
    else:
        arr, n = _arrays_from(atheris.FuzzedDataProvider(rest))
        buf = io.BytesIO()
        np.savez(buf, **arr)
        _write(d / ENVELOPE_NPZ, buf.getvalue())
        _write(d / ENVELOPE_JSON, json.dumps({"schema": "dampnet.envelope/1", "features": FEATURES[:n],
                                              "units": ["-"] * n}).encode())
        model = None
    try:
        env = read_envelope(d, model)
    except EnvelopeError as e:
        msg = str(e)
        assert "\n" not in msg, f"multi-line error: {msg[:300]!r}"
        assert len(msg) < 2000, f"a {len(msg)}-character error: {msg[:300]!r}"
        assert "np.float64(" not in msg and "np.int64(" not in msg, f"numpy repr in: {msg[:300]!r}"
        env = None
    if env is not None:
        _exercise(env, model)
    # the coverage commands' fall-back never raises (its warning goes to stderr: silenced here)
    saved, sys.stderr = sys.stderr, io.StringIO()
    try:
        loaded, note = load_envelope(d, model)
    finally:
        sys.stderr = saved
    assert (loaded is None) == (env is None) and isinstance(note, str)


def write_corpus(out: Path) -> None:
    """The seed corpus: a valid npz (target 0), a valid json (1), and structured inputs (2)."""
    out.mkdir(parents=True, exist_ok=True)
    seeds = {"npz_valid": b"\x00" + VALID_NPZ, "json_valid": b"\x01" + VALID_JSON,
             "npz_truncated": b"\x00" + VALID_NPZ[: len(VALID_NPZ) // 2], "json_list": b"\x01[]",
             "arrays_random": b"\x02" + np.random.default_rng(2).bytes(600),
             "arrays_zeros": b"\x02" + bytes(300)}
    for name, data in seeds.items():
        (out / name).write_bytes(data)


def main() -> None:
    if len(sys.argv) == 3 and sys.argv[1] == "--write-corpus":
        write_corpus(Path(sys.argv[2]))
        return
    _instrument_dampnet()
    atheris.Setup(sys.argv, one_input)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
