"""Round trip rig -> files -> reader, and the dataset writer's refusal to overwrite."""

from __future__ import annotations

import numpy as np
import pytest

from dampnet.data import DataError, load_dataset, write_dataset
from dampnet.rig import generate


@pytest.fixture(scope="module")
def quick_thermal():
    return generate("quick", effects=["thermal", "valve_lag"], seed=11)


def test_round_trip_gives_the_same_arrays(tmp_path, quick_thermal):
    ds = quick_thermal
    out = write_dataset(ds, tmp_path / "ds")
    back = load_dataset(out)
    assert back.test_ids == ds.test_ids
    for a, b in zip(ds.tests, back.tests):
        assert np.array_equal(a.time, b.time)
        assert set(a.channels) == set(b.channels) == {"displacement", "velocity", "force", "voltage",
                                                      "temperature"}
        for k in a.channels:
            assert np.array_equal(a.channels[k], b.channels[k]), (a.test_id, k)
        assert (b.frequency_hz, b.amplitude_m, b.control_nominal, b.control_name) == \
            (a.frequency_hz, a.amplitude_m, a.control_nominal, "voltage")
    assert back.meta["seed"] == 11 and back.meta["plan"]["name"] == "quick"
    assert set(back.meta["effects"]) == {"thermal", "valve_lag"}


def test_manifest_and_columns_are_exactly_the_format(tmp_path, quick_thermal):
    out = write_dataset(quick_thermal, tmp_path / "ds")
    lines = (out / "manifest.csv").read_text().splitlines()
    # issue 50: the rig states the order it ran its tests in (docs/data-formats.md, "The run order")
    assert lines[0] == "test_id,file,frequency_hz,amplitude_m,voltage_v,run_order"
    assert len(lines) == 1 + len(quick_thermal.tests)
    tid, fname, f, a, v, order = lines[1].split(",")
    assert order == "1"
    assert (out / fname).is_file()
    header = (out / fname).read_text().splitlines()[0]
    assert header == "time_s,displacement_m,velocity_m_s,force_n,voltage_v,temperature_c"


def test_refuses_to_overwrite_and_leaves_no_temporaries(tmp_path, quick_thermal):
    out = write_dataset(quick_thermal, tmp_path / "ds")
    before = (out / "manifest.csv").read_text()
    with pytest.raises(FileExistsError):
        write_dataset(quick_thermal, out)
    assert (out / "manifest.csv").read_text() == before
    small = quick_thermal.subset(quick_thermal.tests[:2])
    write_dataset(small, out, overwrite=True)
    assert len(load_dataset(out).tests) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ds"]


def test_a_failed_write_leaves_nothing(tmp_path, quick_thermal):
    bad = quick_thermal.subset([t.copy() for t in quick_thermal.tests[:2]])
    bad.tests[1].channels["force"][5] = np.nan
    with pytest.raises(DataError, match="force"):
        write_dataset(bad, tmp_path / "ds")
    assert list(tmp_path.iterdir()) == []


def test_current_controlled_and_non_sine_tests_round_trip(tmp_path):
    from dampnet.data import DynoTest, Dataset

    t = np.arange(50) * 0.01
    test = DynoTest("road1", t, {"displacement": 0.01 * np.sin(t), "velocity": 0.01 * np.cos(t),
                                 "force": 100 * np.cos(t), "current": np.full(50, 0.5),
                                 "strain_gauge": np.linspace(0, 1, 50)},
                    frequency_hz=None, amplitude_m=None, control_nominal=0.5, control_name="current")
    out = write_dataset(Dataset([test], "hand-made"), tmp_path / "c")
    assert (out / "manifest.csv").read_text().splitlines()[0].endswith("current_a")
    back = load_dataset(out).tests[0]
    assert back.control_name == "current" and back.frequency_hz is None
    np.testing.assert_allclose(back.channels["strain_gauge"], test.channels["strain_gauge"], rtol=1e-9)
    np.testing.assert_allclose(back.channels["force"], test.channels["force"], atol=5e-4)


@pytest.mark.parametrize("sep", [",", ";", "\t", " "])
def test_plain_and_general_table_paths_read_the_same(tmp_path, sep):
    """read_table reads a plain file (no comment, no blank line) in one pass and anything else line
    by line; both give the same names, values and file line numbers, and a bad cell is still named
    by its line (the one-pass path hands it to the general one). Milliseconds."""
    from dampnet.data.table import _plain_table, read_table

    rows = [[0.0, 1.5, -2.25e-3], [0.001, 1.25, 7.0], [0.002, -3.0, 1e5]]
    body = "\n".join(sep.join(repr(v) for v in r) for r in rows)
    plain = tmp_path / "plain.csv"
    plain.write_text(sep.join(["time_s", "force_n", "velocity_m_s"]) + "\n" + body + "\n")
    general = tmp_path / "general.csv"
    general.write_text("# a comment\n" + sep.join(["time_s", "force_n", "velocity_m_s"]) + "\n\n" + body + "\n")
    assert _plain_table(plain.read_text(), 0, True) is not None
    assert _plain_table(general.read_text(), 0, True) is None
    n1, d1, l1 = read_table(plain)
    n2, d2, l2 = read_table(general)
    assert n1 == n2 == ["time_s", "force_n", "velocity_m_s"]
    np.testing.assert_array_equal(d1, np.array(rows))
    np.testing.assert_array_equal(d2, np.array(rows))
    assert list(l1) == [2, 3, 4] and list(l2) == [4, 5, 6]
    bad = tmp_path / "bad.csv"
    bad.write_text(plain.read_text().replace("1.25", "x1.25"))
    with pytest.raises(DataError, match=r"bad.csv: line 3, column 'force_n': expected a number"):
        read_table(bad)
