"""A damaged training envelope (envelope.npz / envelope.json beside a model) is validated on load
like a model (issue 29): `read_envelope` refuses it in one line naming the file and the field,
`dampnet export` refuses to export with it, and the commands that report coverage (vehicle,
simulate, study, plan-tests) fall back to the per-input training ranges with a one-line warning
naming the file and the field, as docs/coverage.md ("The envelope") says. Before, these gave BadZipFile /
EOFError / AttributeError tracebacks, an IndexError, or silently wrong coverage (a NaN threshold:
0 % outside; a negative one: 100 %). The default model and an envelope from synthetic samples."""

from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest

from dampnet.cli import main
from dampnet.envelope.coverage import coverage
from dampnet.envelope import (ENVELOPE_JSON, ENVELOPE_NPZ, MAX_NPZ_BYTES, Envelope, EnvelopeError, build_envelope,
                              load_envelope, read_envelope, save_envelope)
from dampnet.envelope.grid import grid_cells
from dampnet.modeldir import default_model, save_model_dir
from dampnet.sim.dampers import load_spec


@pytest.fixture
def model_dir(tmp_path):
    model = default_model()
    X = np.random.default_rng(0).uniform(model.sat_lo, model.sat_hi, size=(300, model.n_inputs))
    save_model_dir(model, {}, tmp_path / "M", envelope=build_envelope(model, X))
    return tmp_path / "M"


def _arrays(d):
    with np.load(d / ENVELOPE_NPZ) as z:
        return {k: z[k] for k in z.files}


def _npz(**changes):
    """A damage: the npz's arrays with `changes` (None removes one)."""
    def damage(d):
        arr = _arrays(d)
        for k, v in changes.items():
            if v is None:
                del arr[k]
            else:
                arr[k] = v(arr[k]) if callable(v) else v
        np.savez(d / ENVELOPE_NPZ, **arr)
    return damage


def _json(change):
    def damage(d):
        meta = json.loads((d / ENVELOPE_JSON).read_text())
        (d / ENVELOPE_JSON).write_text(json.dumps(change(meta)))
    return damage


def _bytes(name, data):
    def damage(d):
        (d / name).write_bytes(data(d / name) if callable(data) else data)
    return damage


def _set(i, j, value):
    def f(a):
        a = a.copy()
        a[(i, j) if j is not None else i] = value
        return a
    return f


def _bomb(d):
    """Small on disk, far beyond MAX_NPZ_BYTES uncompressed."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        with zf.open("points.npy", "w", force_zip64=True) as f:
            chunk = bytes(2**20)
            for _ in range(MAX_NPZ_BYTES // 2**20 + 1):
                f.write(chunk)
    (d / ENVELOPE_NPZ).write_bytes(buf.getvalue())


DAMAGES = {  # name: (damage, the file named, what the message says)
    "empty npz": (_bytes(ENVELOPE_NPZ, b""), ENVELOPE_NPZ, "not a readable envelope file"),
    "truncated npz": (_bytes(ENVELOPE_NPZ, lambda p: p.read_bytes()[:1000]), ENVELOPE_NPZ, "not a readable"),
    "npz not a zip": (_bytes(ENVELOPE_NPZ, b"PK\x03\x04 not really"), ENVELOPE_NPZ, "not a readable"),
    "json []": (_bytes(ENVELOPE_JSON, b"[]"), ENVELOPE_JSON, "expected a JSON object"),
    "json empty": (_bytes(ENVELOPE_JSON, b""), ENVELOPE_JSON, "not valid JSON"),
    "json schema": (_json(lambda m: {**m, "schema": "x/9"}), ENVELOPE_JSON, "schema: expected"),
    "json features": (_json(lambda m: {**m, "features": "velocity"}), ENVELOPE_JSON, "features: expected"),
    "json units short": (_json(lambda m: {**m, "units": ["m/s"]}), ENVELOPE_JSON, "units: expected 3"),
    "json model_id": (_json(lambda m: {**m, "model_id": "0123456789abcdef"}), ENVELOPE_JSON,
                      "built for model 0123456789abcdef"),
    "json missing": (lambda d: (d / ENVELOPE_JSON).unlink(), ENVELOPE_JSON, "missing"),
    "npz missing": (lambda d: (d / ENVELOPE_NPZ).unlink(), ENVELOPE_NPZ, "missing"),
    "threshold NaN": (_npz(threshold=np.array(np.nan)), ENVELOPE_NPZ, "threshold: expected a finite distance > 0"),
    "threshold Inf": (_npz(threshold=np.array(np.inf)), ENVELOPE_NPZ, "threshold: expected a finite distance > 0"),
    "threshold negative": (_npz(threshold=np.array(-0.1)), ENVELOPE_NPZ, "threshold: expected a finite distance"),
    "threshold zero": (_npz(threshold=np.array(0.0)), ENVELOPE_NPZ, "threshold: expected a finite distance"),
    "threshold array": (_npz(threshold=np.ones(2)), ENVELOPE_NPZ, "threshold: expected one number"),
    "in_gain 0": (_npz(in_gain=_set(1, None, 0.0)), ENVELOPE_NPZ, "in_gain: expected a non-zero gain"),
    "in_gain tiny": (_npz(in_gain=_set(1, None, 1e-320)), ENVELOPE_NPZ, "in_gain: expected a non-zero gain"),
    "in_gain not the model's": (_npz(in_gain=lambda a: 2 * a), ENVELOPE_NPZ, "in_gain: differs from the model's"),
    "in_ymin NaN": (_npz(in_ymin=np.array(np.nan)), ENVELOPE_NPZ, "in_ymin: expected a finite number"),
    "lo NaN": (_npz(lo=_set(0, None, np.nan)), ENVELOPE_NPZ, "lo: expected finite numbers"),
    "lo above hi": (_npz(lo=lambda a: a + 100.0), ENVELOPE_NPZ, "lo, hi: expected lo <= hi"),
    "hi short": (_npz(hi=lambda a: a[:2]), ENVELOPE_NPZ, "hi: expected 3 values"),
    "point NaN": (_npz(points=_set(5, 0, np.nan)), ENVELOPE_NPZ, "points: expected finite scaled samples, got [nan, "),
    "point Inf": (_npz(points=_set(0, 2, -np.inf)), ENVELOPE_NPZ, "points: expected finite"),
    "no points": (_npz(points=np.zeros((0, 3))), ENVELOPE_NPZ, "points: expected [m >= 1"),
    "points 2 wide": (_npz(points=lambda a: a[:, :2]), ENVELOPE_NPZ, "points: expected [m >= 1"),
    "points text": (_npz(points=np.array([["a", "b", "c"]])), ENVELOPE_NPZ, "points: expected real numbers"),
    "points complex": (_npz(points=lambda a: a + 0j), ENVELOPE_NPZ, "points: expected real numbers"),
    "points pickled": (_npz(points=np.array([[object()] * 3], dtype=object)), ENVELOPE_NPZ, "points: unreadable"),
    "array missing": (_npz(threshold=None), ENVELOPE_NPZ, "threshold: missing"),
    "zip bomb": (_bomb, ENVELOPE_NPZ, "expands to"),
}


@pytest.mark.parametrize("name", list(DAMAGES))
def test_a_damaged_envelope_is_refused_naming_file_and_field(model_dir, name):
    damage, file, says = DAMAGES[name]
    damage(model_dir)
    with pytest.raises(EnvelopeError) as e:
        read_envelope(model_dir, default_model())
    msg = str(e.value)
    assert msg.startswith(str(model_dir / file)) and says in msg, msg
    assert "\n" not in msg and len(msg) < 400 and "np.float64" not in msg


@pytest.mark.parametrize("name", ["empty npz", "json []", "threshold NaN", "in_gain 0", "no points"])
def test_export_refuses_a_damaged_envelope(model_dir, tmp_path, capsys, name):
    damage, file, says = DAMAGES[name]
    damage(model_dir)
    assert main(["export", str(model_dir), "--header", str(tmp_path / "m.h")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"dampnet: error: {model_dir / file}") and says in err, err
    assert "move envelope.npz and envelope.json away" in err and not (tmp_path / "m.h").exists()


@pytest.mark.parametrize("name", ["empty npz", "truncated npz", "json []", "threshold NaN", "threshold negative",
                                  "in_gain 0", "no points", "json missing", "point NaN"])
def test_coverage_falls_back_to_the_ranges_with_a_warning(model_dir, capsys, name):
    """Before: tracebacks, or (a NaN stored point) "data must be finite, check for nan or inf values"
    from scipy's k-d tree with no file named."""
    damage, file, says = DAMAGES[name]
    damage(model_dir)
    env, note = load_envelope(model_dir, default_model())
    assert env is None and note.startswith(str(model_dir / file)) and "per-input training ranges only" in note
    err = capsys.readouterr().err
    assert err == f"dampnet: warning: {note}\n"
    spec = load_spec(str(model_dir))  # what simulate, vehicle, study and sweep load
    assert spec.meta["envelope"] is None and says in spec.meta["envelope_note"]
    assert capsys.readouterr().err.count("dampnet: warning: ") == 1


def test_vehicle_reports_the_ranges_and_says_why(model_dir, tmp_path, capsys):
    """Before: a NaN threshold gave a joint envelope nothing is ever outside of (d > NaN is false)."""
    DAMAGES["threshold NaN"][0](model_dir)
    assert main(["vehicle", str(model_dir), "--out", str(tmp_path / "v")]) == 0
    cap = capsys.readouterr()
    assert cap.err.count("dampnet: warning: ") == 1 and "threshold" in cap.err
    line = next(x for x in cap.out.splitlines() if x.startswith("coverage of"))
    assert "no joint envelope" in line and "threshold: expected a finite distance > 0" in line
    metrics = json.loads((tmp_path / "v" / "metrics.json").read_text())
    cov = json.dumps(metrics)
    assert '"envelope": "ranges only"' in cov and "threshold" in cov


@pytest.mark.parametrize("name", ["empty npz", "threshold NaN"])
def test_plan_tests_falls_back_with_the_warning(model_dir, tmp_path, capsys, name):
    """Before: EOFError / AttributeError tracebacks, and a NaN threshold reported as "--radius"."""
    damage, file, says = DAMAGES[name]
    damage(model_dir)
    assert main(["plan-tests", str(model_dir), "impulse:low", "--budget", "1"]) == 0
    cap = capsys.readouterr()
    assert cap.err.count("dampnet: warning: ") == 1 and str(model_dir / file) in cap.err and says in cap.err
    assert "Traceback" not in cap.err and "--radius" not in cap.err + cap.out


def test_a_valid_envelope_round_trips_and_works(model_dir, tmp_path):
    model = default_model()
    env = read_envelope(model_dir, model)
    save_envelope(env, tmp_path / "copy")
    again = read_envelope(tmp_path / "copy", model)
    for k in ("lo", "hi", "in_offset", "in_gain", "points"):
        np.testing.assert_array_equal(getattr(again, k), getattr(env, k))
    assert again.threshold == env.threshold > 0 and again.features == model.features
    X = np.random.default_rng(1).uniform(model.sat_lo, model.sat_hi, size=(50, 3))
    assert coverage(model, X, again)["envelope"] == "joint"
    assert grid_cells(again).any()
    assert read_envelope(tmp_path / "nothing-here") is None  # no files: no envelope, no error


@pytest.mark.parametrize("field,value,says", [
    ("threshold", np.nan, "threshold"), ("threshold", -1.0, "threshold"), ("in_gain", np.zeros(3), "in_gain"),
    ("points", np.zeros((0, 3)), "points"), ("features", ["v", "v", "u"], "features"),
    ("lo", np.array([0.0, 0.0, np.inf]), "lo"),
])
def test_an_envelope_object_is_validated_when_made(model_dir, field, value, says):
    """Envelope() runs the same check (validate_envelope) as the files: so does build_envelope."""
    env = read_envelope(model_dir)
    kw = dict(features=env.features, units=env.units, lo=env.lo, hi=env.hi, in_offset=env.in_offset,
              in_gain=env.in_gain, in_ymin=env.in_ymin, points=env.points, threshold=env.threshold)
    kw[field] = value
    with pytest.raises(EnvelopeError, match=rf"^envelope: {says}"):
        Envelope(**kw)
