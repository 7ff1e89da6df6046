"""Single-file readers: unit-bearing CSV and whitespace text, MATLAB .mat with a mapping, sign conventions."""

from __future__ import annotations

import numpy as np
import pytest

from dampnet.data import DataError, load_dataset
from dampnet.data.units import parse_column

LBF = 4.4482216152605   # N, by definition of the pound-force (0.45359237 kg x 9.80665 m/s^2)
INCH = 0.0254


def _signals(n=200, dt=0.002):
    t = np.arange(n) * dt
    x = 0.02 * np.sin(2 * np.pi * 1.5 * t)
    v = 0.02 * 2 * np.pi * 1.5 * np.cos(2 * np.pi * 1.5 * t)
    f = 800.0 * np.tanh(v / 0.05)
    return t, x, v, f


def test_imperial_csv_is_converted_to_si(tmp_path):
    t, x, v, f = _signals()
    p = tmp_path / "dyno_export.csv"
    rows = ["time_ms,displacement_in,velocity_in_s,force_lbf,current_ma,temperature_f"]
    rows += [f"{1e3 * a!r},{b / INCH!r},{c / INCH!r},{d / LBF!r},500,100" for a, b, c, d in zip(t.tolist(), x.tolist(), v.tolist(), f.tolist())]
    p.write_text("\n".join(rows) + "\n")
    test = load_dataset(p).tests[0]
    np.testing.assert_allclose(test.time, t, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(test.channels["displacement"], x, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(test.channels["velocity"], v, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(test.channels["force"], f, rtol=1e-12, atol=1e-12)
    assert test.control_name == "current"
    np.testing.assert_allclose(test.channels["current"], 0.5)
    np.testing.assert_allclose(test.channels["temperature"], (100 - 32) * 5 / 9)   # 100 degF = 37.78 degC


def test_whitespace_text_with_bare_units_and_metric_prefixes(tmp_path):
    t, x, v, f = _signals()
    p = tmp_path / "run.txt"
    lines = ["s   mm   mm/s   kN   V"] + [f"{a:.6f}  {1e3 * b:.9f}  {1e3 * c:.9f}  {f_ / 1e3:.12f}  3.0"
                                        for a, b, c, f_ in zip(t, x, v, f)]
    p.write_text("\n".join(lines) + "\n")
    test = load_dataset(p, frequency_hz=1.5).tests[0]
    np.testing.assert_allclose(test.channels["displacement"], x, atol=1e-12)
    np.testing.assert_allclose(test.channels["velocity"], v, atol=1e-12)
    np.testing.assert_allclose(test.channels["force"], f, atol=1e-8)
    assert test.control_nominal == 3.0 and test.frequency_hz == 1.5


def test_headerless_text_with_named_columns_and_dt(tmp_path):
    t, x, v, f = _signals()
    p = tmp_path / "raw.dat"
    np.savetxt(p, np.column_stack([x * 1e3, f]))
    ds = load_dataset(p, columns=["x_mm", "F_N"], dt=0.002, voltage=0.0, derive_velocity=True)
    test = ds.tests[0]
    # the velocity derived as for lab files (derivative.velocity_from_displacement): 50 ms cut at each end (25
    # samples at 500 Hz), within 0.1 % of the peak of the 1.5 Hz sine's analytic derivative
    np.testing.assert_allclose(test.time, t[25:-25], atol=1e-12)
    np.testing.assert_allclose(test.channels["velocity"], v[25:-25], atol=1e-3 * np.abs(v).max())
    np.testing.assert_allclose(test.channels["force"], f[25:-25], atol=1e-8)
    assert test.meta["velocity"]["from"] == "x_mm" and test.meta["velocity"]["edge_cut_s"] == 0.05
    assert ds.meta["velocity_derived"]["tests"] == [test.test_id]


def test_sign_convention_of_a_compression_positive_rig(tmp_path):
    t, x, v, f = _signals()
    p = tmp_path / "comp.csv"
    rows = ["time_s,displacement_m,velocity_m_s,force_n,voltage_v"]
    rows += [f"{a!r},{-b!r},{-c!r},{-d!r},1" for a, b, c, d in zip(t.tolist(), x.tolist(), v.tolist(), f.tolist())]
    p.write_text("\n".join(rows) + "\n")
    test = load_dataset(p, motion_positive="compression", force_positive="compression").tests[0]
    np.testing.assert_array_equal(test.channels["displacement"], x)
    np.testing.assert_array_equal(test.channels["force"], f)
    raw = load_dataset(p).tests[0]
    np.testing.assert_array_equal(raw.channels["force"], -f)
    with pytest.raises(DataError, match="motion_positive='up'"):
        load_dataset(p, motion_positive="up")


def test_mat_file_with_a_variable_mapping(tmp_path):
    from scipy.io import savemat

    t, x, v, f = _signals()
    p = tmp_path / "test.mat"
    savemat(p, {"x_F": np.column_stack([x * 1e3, v * 1e3, f]), "Ts": np.array([[0.002]]),
                "volts": np.full((len(t), 1), 2.5)})
    mapping = {"displacement_mm": "x_F:0", "velocity_mm_s": "x_F:1", "force_n": "x_F:2", "voltage_v": "volts"}
    test = load_dataset(p, mapping=mapping, dt="Ts").tests[0]
    np.testing.assert_allclose(test.channels["displacement"], x, rtol=1e-12)
    np.testing.assert_allclose(test.channels["velocity"], v, rtol=1e-12)
    np.testing.assert_allclose(test.time, t, atol=1e-12)
    assert test.control_nominal == 2.5
    with pytest.raises(DataError, match=r"test\.mat: variable 'nope' not found"):
        load_dataset(p, mapping={**mapping, "force_n": "nope"}, dt="Ts")
    with pytest.raises(DataError, match=r"test\.mat: 'x_F:7': expected a column index below 3"):
        load_dataset(p, mapping={**mapping, "force_n": "x_F:7"}, dt="Ts")
    with pytest.raises(DataError, match=r"test\.mat: expected mapping="):
        load_dataset(p)


@pytest.mark.parametrize("name,channel,si_of_one", [
    ("force_lbf", "force", LBF), ("F (kN)", "force", 1e3), ("displacement_in", "displacement", INCH),
    ("mm", "displacement", 1e-3), ("mm/s", "velocity", 1e-3), ("velocity_in_s", "velocity", INCH),
    ("time_ms", "time", 1e-3), ("current_ma", "current", 1e-3), ("accel_g", "acceleration", 9.80665),
    ("disp [cm]", "displacement", 1e-2),
])
def test_unit_table(name, channel, si_of_one):
    ch, scale, offset = parse_column(name)
    assert ch == channel and scale == pytest.approx(si_of_one, rel=1e-12) and offset == 0.0
