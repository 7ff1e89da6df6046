"""Every bad input gets a DataError naming the file, the line or column, and what was expected."""

from __future__ import annotations

import subprocess
import sys

import pytest

from dampnet.data import DataError, load_dataset

GOOD = "time_s,displacement_m,velocity_m_s,force_n,voltage_v\n" + "".join(
    f"{k * 0.01:.2f},{0.001 * k},{0.1},{10.0 * k},2.0\n" for k in range(20))


def _dataset(tmp_path, body=GOOD, manifest=None):
    d = tmp_path / "ds"
    d.mkdir()
    (d / "a.csv").write_text(body)
    (d / "manifest.csv").write_text(manifest or "test_id,file,frequency_hz,amplitude_m,voltage_v\nA,a.csv,1,0.0254,2\n")
    return d


def _replace_line(body, lineno, new):
    lines = body.splitlines()
    lines[lineno - 1] = new
    return "\n".join(lines) + "\n"


def test_good_dataset_loads(tmp_path):
    ds = load_dataset(_dataset(tmp_path))
    assert len(ds.tests[0]) == 20 and ds.tests[0].control_nominal == 2.0


@pytest.mark.parametrize("lineno,new,pattern", [
    (5, "0.03,0.003,0.1,abc,2.0", r"a\.csv: line 5, column 'force_n': expected a number, got 'abc'"),
    (7, "0.05,0.005,nan,50,2.0", r"a\.csv: line 7, column 'velocity_m_s': expected a finite number"),
    (4, "0.01,0.002,0.1,20,2.0", r"a\.csv: line 4, column 'time_s': duplicated time .*strictly increasing"),
    (6, "0.01,0.004,0.1,40,2.0", r"a\.csv: line 6, column 'time_s': decreasing time"),
    (9, "0.07,0.007,0.1", r"a\.csv: line 9: expected 5 columns, got 3"),
])
def test_bad_cells_name_file_line_and_column(tmp_path, lineno, new, pattern):
    with pytest.raises(DataError, match=pattern):
        load_dataset(_dataset(tmp_path, _replace_line(GOOD, lineno, new)))


def test_missing_column(tmp_path):
    body = "\n".join(",".join(r.split(",")[:3] + r.split(",")[4:]) for r in GOOD.splitlines()) + "\n"
    with pytest.raises(DataError, match=r"a\.csv: line 1: missing column\(s\) force_n"):
        load_dataset(_dataset(tmp_path, body))


def test_unknown_column_in_a_single_file(tmp_path):
    f = tmp_path / "x.csv"
    f.write_text(GOOD.replace("force_n", "force_furlongs"))
    with pytest.raises(DataError, match=r"x\.csv.*column 'force_furlongs': expected a quantity with a known unit"):
        load_dataset(f)


def test_unknown_unit(tmp_path):
    f = tmp_path / "y.csv"
    f.write_text(GOOD.replace("velocity_m_s", "velocity_parsec_s"))
    with pytest.raises(DataError, match=r"y\.csv.*'velocity_parsec_s'"):
        load_dataset(f)


def test_too_few_samples(tmp_path):
    body = "\n".join(GOOD.splitlines()[:6]) + "\n"
    with pytest.raises(DataError, match=r"a\.csv: too few samples: expected at least 10, got 5"):
        load_dataset(_dataset(tmp_path, body))


def test_manifest_row_whose_file_is_missing(tmp_path):
    m = "test_id,file,frequency_hz,amplitude_m,voltage_v\nA,a.csv,1,0.0254,2\nB,b.csv,2,0.0254,2\n"
    with pytest.raises(DataError, match=r"manifest\.csv: line 3, column 'file': file 'b\.csv' not found"):
        load_dataset(_dataset(tmp_path, manifest=m))


def test_manifest_missing_columns_and_bad_cells(tmp_path):
    with pytest.raises(DataError, match=r"manifest\.csv: line 1: missing column\(s\) amplitude_m"):
        load_dataset(_dataset(tmp_path, manifest="test_id,file,frequency_hz,voltage_v\nA,a.csv,1,2\n"))
    d2 = tmp_path / "two"
    d2.mkdir()
    with pytest.raises(DataError, match=r"manifest\.csv: line 2, column 'frequency_hz': expected a number"):
        load_dataset(_dataset(d2, manifest="test_id,file,frequency_hz,amplitude_m,voltage_v\nA,a.csv,fast,0.0254,2\n"))


def test_control_column_missing(tmp_path):
    f = tmp_path / "noctl.csv"
    f.write_text("\n".join(",".join(r.split(",")[:4]) for r in GOOD.splitlines()) + "\n")
    with pytest.raises(DataError, match=r"noctl\.csv: missing control column"):
        load_dataset(f)
    assert load_dataset(f, voltage=1.5).tests[0].channels["voltage"][0] == 1.5


def test_directory_without_manifest_and_missing_path(tmp_path):
    with pytest.raises(DataError, match="without manifest.csv"):
        load_dataset(tmp_path)
    with pytest.raises(DataError, match="not found"):
        load_dataset(tmp_path / "nope.csv")


def test_command_line_prints_one_line_and_exits_2(tmp_path):
    bad_plan = tmp_path / "plan.json"
    bad_plan.write_text('{"frequencies_hz": [1], "amplitudes_m": [0.01], "voltages_v": [0], "colour": "red"}')
    r = subprocess.run([sys.executable, "-m", "dampnet.commands.rig", str(tmp_path / "out"), "--plan",
                        str(bad_plan), "--no-progress"], capture_output=True, text=True)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("dampnet: error: ") and "colour" in lines[0]
    assert not (tmp_path / "out").exists()
