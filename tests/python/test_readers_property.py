"""Property tests of the readers (issue 14): any bytes, or any mutation of a valid file, give
a loaded object that passes the readers' own checks or the project's own one-line error
(DataError, ModelError; exit 2 from the CLI) - never another exception, a hang or a
partial load. Example counts are bounded so the file runs in seconds; the long runs are
the atheris harness in fuzz/python/."""

from __future__ import annotations

import io
import json
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dampnet.cli import main
from dampnet.data import DataError, load_dataset
from dampnet.data.fileformat import read_dataset_dir
from dampnet.data.readers import read_mat
from dampnet.data.types import CHANNEL_UNITS
from dampnet.data.units import parse_column
from dampnet.data.validate import check_test
from dampnet.model import MlpModel, ModelError

REPO = Path(__file__).resolve().parents[2]
DEFAULT_MODEL = REPO / "export" / "dn_model_default.json"
MANIFEST = b"test_id,file,frequency_hz,amplitude_m,voltage_v\nA,a.csv,1,0.0254,2\n"
TEST_CSV = b"time_s,displacement_m,velocity_m_s,force_n,voltage_v\n" + b"".join(
    b"%g,%g,0.1,%g,2.0\n" % (k * 0.01, 0.001 * k, 10.0 * k) for k in range(20))
META = json.dumps({"generator": "dampnet.data.rig", "noise": {"force_n": 2.0}, "effects": {},
                   "plan": {"name": "quick"}}).encode()
SINGLE = b"time_ms;disp (mm);mm/s;force_lbf\n" + b"".join(
    b"%d;%g;%g;%g\n" % (k, np.sin(k / 3), np.cos(k / 3), 20 * np.cos(k / 3)) for k in range(15))
MAPPING = {"displacement_mm": "x:0", "velocity_mm_s": "x:1", "force_n": "x:2"}

# bounded: the whole file runs in seconds; no deadline (timing flakiness on a loaded machine):
# a hang would stall the run, and the atheris CI run (-timeout=10) reports one per input
#: examples per property; DN_HYPOTHESIS_EXAMPLES=5000 for a longer local sweep
EXAMPLES = int(os.environ.get("DN_HYPOTHESIS_EXAMPLES", "150"))
FAST = settings(max_examples=EXAMPLES, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


def _mat_bytes() -> bytes:
    import scipy.io

    buf = io.BytesIO()
    k = np.arange(15)
    scipy.io.savemat(buf, {"x": np.column_stack([np.sin(k / 3), np.cos(k / 3), 20 * np.cos(k / 3)])})
    return buf.getvalue()


def mutated(valid: bytes) -> st.SearchStrategy[bytes]:
    """A valid file with a few bytes replaced, inserted or deleted (and sometimes truncated)."""
    edit = st.tuples(st.sampled_from(["set", "insert", "delete", "truncate"]),
                     st.integers(0, max(len(valid) - 1, 0)), st.binary(min_size=1, max_size=8))

    def apply(edits):
        b = bytearray(valid)
        for kind, pos, data in edits:
            pos = min(pos, len(b))
            if kind == "set":
                b[pos:pos + len(data)] = data
            elif kind == "insert":
                b[pos:pos] = data
            elif kind == "delete":
                del b[pos:pos + len(data)]
            else:
                del b[pos:]
        return bytes(b)

    return st.lists(edit, min_size=1, max_size=4).map(apply)


def any_or_mutated(valid: bytes) -> st.SearchStrategy[bytes]:
    return st.one_of(st.binary(max_size=600), mutated(valid))


def _assert_one_line(e: Exception) -> None:
    msg = str(e)
    assert "\n" not in msg and len(msg) < 2000 and "np.float64(" not in msg, msg[:300]


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    d = tmp_path_factory.mktemp("prop") / "ds"
    d.mkdir()
    return d


def _load_dir(d: Path) -> None:
    try:
        ds = read_dataset_dir(d)
    except DataError as e:
        _assert_one_line(e)
        return
    assert ds.tests and all(check_test(t, "t") is t for t in ds.tests) and isinstance(ds.meta, dict)


@FAST
@given(data=any_or_mutated(TEST_CSV))
def test_any_test_csv(work, data):
    (work / "manifest.csv").write_bytes(MANIFEST)
    (work / "a.csv").write_bytes(data)
    (work / "meta.json").unlink(missing_ok=True)
    _load_dir(work)


@FAST
@given(data=any_or_mutated(MANIFEST))
def test_any_manifest(work, data):
    (work / "manifest.csv").write_bytes(data)
    (work / "a.csv").write_bytes(TEST_CSV)
    (work / "meta.json").unlink(missing_ok=True)
    _load_dir(work)


@FAST
@given(data=any_or_mutated(META))
def test_any_meta_json(work, data):
    (work / "manifest.csv").write_bytes(MANIFEST)
    (work / "a.csv").write_bytes(TEST_CSV)
    (work / "meta.json").write_bytes(data)
    _load_dir(work)


@FAST
@given(data=any_or_mutated(SINGLE))
def test_any_single_text_file(work, data):
    p = work.parent / "single.txt"
    p.write_bytes(data)
    try:
        ds = load_dataset(p, voltage=1.0)
    except DataError as e:
        _assert_one_line(e)
        return
    check_test(ds.tests[0], "t")


@settings(FAST, max_examples=max(EXAMPLES * 2 // 3, 1))
@given(data=any_or_mutated(_mat_bytes()))
def test_any_mat_file(work, data):
    p = work.parent / "x.mat"
    p.write_bytes(data)
    try:
        t = read_mat(p, mapping=MAPPING, voltage=1.0, dt=1e-3)
    except DataError as e:
        _assert_one_line(e)
        return
    check_test(t, "t")


@FAST
@given(data=any_or_mutated(DEFAULT_MODEL.read_bytes()))
def test_any_model_json(work, data):
    p = work.parent / "model.json"
    p.write_bytes(data)
    try:
        m = MlpModel.load(p)
    except ModelError as e:
        _assert_one_line(e)
        return
    m.validate()
    assert np.all(np.isfinite(m.predict(np.zeros((1, m.n_inputs)))))


JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.floats(allow_nan=False) | st.integers() | st.text(max_size=5),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=5), inner, max_size=3),
    max_leaves=8)


@FAST
@given(key=st.sampled_from(["w1", "b1", "w_out", "b_out", "in_offset", "in_gain", "out_offset", "out_gain",
                            "sat_lo", "sat_hi", "features", "units", "activation", "w2", "b2", "terms",
                            "feature_params", "meta", "output", "in_ymin", "format_version"]),
       value=JSON_VALUES)
def test_model_json_with_any_value_in_any_field(key, value):
    d = json.loads(DEFAULT_MODEL.read_text())
    d[key] = value
    try:
        MlpModel.from_dict(d, "model.json").validate()
    except ModelError as e:
        _assert_one_line(e)


@FAST
@given(name=st.text(max_size=40) | st.sampled_from(["force_lbf", "disp (mm)", "mm/s", "time_ms", "x_in_s2"]))
def test_any_unit_column_name(name):
    try:
        ch, scale, offset = parse_column(name)
    except DataError as e:
        _assert_one_line(e)
        return
    assert ch in CHANNEL_UNITS and np.isfinite(scale) and scale != 0 and np.isfinite(offset)


@settings(FAST, max_examples=max(EXAMPLES // 4, 1))
@given(data=any_or_mutated(TEST_CSV))
def test_cli_evaluate_on_any_test_csv_exits_0_or_2_with_one_line(work, data, capsys):
    d = work.parent / "cli"
    d.mkdir(exist_ok=True)
    (d / "manifest.csv").write_bytes(MANIFEST)
    (d / "a.csv").write_bytes(data)
    rc = main(["evaluate", str(DEFAULT_MODEL), str(d), "--no-lookup"])
    err = capsys.readouterr().err
    assert rc in (0, 2)
    if rc == 2:
        assert err.startswith("dampnet: error: ") and err.count("\n") == 1, err[:300]
