"""Issue 14, items 7, 8 and 9 (negative time constant): malformed or hostile files give the
project's own one-line error naming file and field, never a traceback, a read outside the
dataset, an echo of another file's contents, a 100 kB cell or a numpy repr."""

from __future__ import annotations

import copy
import csv
import json
import os
from pathlib import Path

import numpy as np
import pytest

from dampnet.cli import main
from dampnet.data import DataError, load_dataset
from dampnet.model import MlpModel, ModelError

REPO = Path(__file__).resolve().parents[2]
HEADER = "time_s,displacement_m,velocity_m_s,force_n,voltage_v\n"
GOOD = HEADER + "".join(f"{k * 0.01:.2f},{0.001 * k},{0.1},{10.0 * k},2.0\n" for k in range(20))
MANIFEST = "test_id,file,frequency_hz,amplitude_m,voltage_v\n"
SECRET = "TOP-SECRET-LINE-do-not-echo"


def _dataset(root: Path, body: str = GOOD, file_cell: str = "a.csv", name: str = "ds") -> Path:
    d = root / name
    d.mkdir()
    (d / "a.csv").write_text(body)
    (d / "manifest.csv").write_text(MANIFEST + f"A,{file_cell},1,0.0254,2\n")
    return d


def _one_line_cli_error(capsys, argv) -> str:
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 2, err
    assert err.startswith("dampnet: error: ") and err.count("\n") == 1, err
    return err


# -- item 7: the manifest's file column stays inside the dataset ------------------------

def _outside_csv(tmp_path: Path) -> Path:
    """A valid test CSV outside the dataset whose first line carries a secret."""
    p = tmp_path / "elsewhere" / "outside.csv"
    p.parent.mkdir()
    p.write_text(GOOD.replace("time_s,", f"time_s,{SECRET}_", 1))
    return p


@pytest.mark.parametrize("case", ["dotdot_etc_passwd", "absolute", "symlink_out", "valid_csv_outside"])
def test_manifest_file_outside_the_dataset_is_refused_without_echo(tmp_path, capsys, case):
    outside = _outside_csv(tmp_path)
    cell = {"dotdot_etc_passwd": "../../../../../../../../etc/passwd",
            "absolute": str(outside),
            "symlink_out": "link.csv",
            "valid_csv_outside": "../elsewhere/outside.csv"}[case]
    d = _dataset(tmp_path, file_cell=cell)
    if case == "symlink_out":
        os.symlink(outside, d / "link.csv")
    with pytest.raises(DataError) as e:
        load_dataset(d)
    msg = str(e.value)
    assert "manifest.csv: line 2, column 'file'" in msg
    assert ("absolute path" in msg) if case == "absolute" else ("resolves outside the dataset directory" in msg)
    assert SECRET not in msg and "root:" not in msg  # nothing of the target file
    err = _one_line_cli_error(capsys, ["evaluate", str(REPO / "export" / "dn_model_default.json"), str(d)])
    assert SECRET not in err and "root:" not in err


def test_symlink_inside_the_dataset_is_followed(tmp_path):
    d = _dataset(tmp_path, file_cell="sub/link.csv")
    (d / "sub").mkdir()
    os.symlink(d / "a.csv", d / "sub" / "link.csv")
    assert len(load_dataset(d).tests[0]) == 20


# -- item 8: malformed model.json ------------------------------------------------------

def _default_model_dict() -> dict:
    return json.loads((REPO / "export" / "dn_model_default.json").read_text())


def _set(path: str, value):
    def edit(d):
        *parents, last = path.split(".")
        for p in parents:
            d = d[p]
        d[last] = value
        return d
    return edit


MODEL_CASES = {
    "top_list": (lambda d: [d], "expected a JSON object, got a list"),
    "top_number": (lambda d: 5, "expected a JSON object, got a number"),
    "top_null": (lambda d: None, "expected a JSON object, got null"),
    "b_out_null": (_set("b_out", None), "field 'b_out': expected a number, got null"),
    "b_out_list": (_set("b_out", [1.0]), "field 'b_out': expected a number, got a list"),
    "features_number": (_set("features", 5), "field 'features': expected a list of strings"),
    "features_of_numbers": (_set("features", [1, 2, 3]), r"field 'features'\[0\]: expected a string"),
    "out_gain_string": (_set("out_gain", "0.01"), "field 'out_gain': expected a number, got a string"),
    "in_gain_strings": (_set("in_gain", ["1", "2", "3"]), r"field 'in_gain'\[0\]: expected a number"),
    "w1_ragged": (_set("w1", [[1.0, 2.0], [3.0]]), "field 'w1': expected a list of equal-length lists"),
    "w1_flat": (_set("w1", [1.0, 2.0]), r"field 'w1'\[0\]: expected a list of numbers"),
    "terms_string": (_set("terms", "position_poly"), "field 'terms': expected a list of objects"),
    "terms_params_string": (_set("terms", [{"kind": "position_poly", "params": "1,2,3,4"}]),
                            r"field 'terms'\[0\].params: expected a list of numbers"),
    "terms_kind_huge": (_set("terms", [{"kind": "x" * 5000, "params": []}]),
                        r"field 'terms'\[0\].kind: expected a term kind name \(1-100 characters"),
    "terms_kind_number": (_set("terms", [{"kind": 5, "params": []}]),
                          r"field 'terms'\[0\].kind: expected a string, got a number"),
    "feature_params_list": (_set("feature_params", [0.1]), "field 'feature_params': expected a JSON object"),
    "feature_params_string": (_set("feature_params", {"control_lag_tau_s": "0.1"}),
                              "feature_params.*expected a number"),
    "meta_list": (_set("meta", [1, 2]), "field 'meta': expected a JSON object"),
    "meta_data_number": (_set("meta", {"data": 5}), "field 'meta'.data: expected a JSON object"),
    "meta_holdout_number": (_set("meta", {"data": {"holdout_tests": 3}}), "holdout_tests: expected a list of strings"),
    "activation_number": (_set("activation", 1), "field 'activation': expected a string"),
    "activation_long": (_set("activation", "relu" * 2000), r"activation: expected one of tanh, sigmoid, got 'relurelu"),
    "feature_long": (_set("features", ["velocity", "acceleration", "v" * 5000]), None),
    "output_string": (_set("output", "force"), "field 'output': expected a JSON object"),
    "huge_int": (_set("b_out", 10 ** 400), "field 'b_out': expected a finite number"),
    "missing_w1": (lambda d: {k: v for k, v in d.items() if k != "w1"}, "missing field 'w1'"),
}


@pytest.mark.parametrize("case", sorted(MODEL_CASES))
def test_malformed_model_json_is_a_model_error_naming_file_and_field(tmp_path, capsys, case):
    edit, pattern = MODEL_CASES[case]
    p = tmp_path / "model.json"
    p.write_text(json.dumps(edit(copy.deepcopy(_default_model_dict()))))
    if pattern is None:  # loads: the shape is right; the commands refuse the unknown name in one line
        MlpModel.load(p)
        err = _one_line_cli_error(capsys, ["evaluate", str(p), str(_dataset(tmp_path))])
        assert len(err) < 600, err
        return
    with pytest.raises(ModelError, match=pattern) as e:
        MlpModel.load(p)
    msg = str(e.value)
    assert msg.startswith(str(p)) and "\n" not in msg and len(msg) < 600, msg
    _one_line_cli_error(capsys, ["simulate", str(p), "--road", "impulse", "--out", str(tmp_path / "sim")])


@pytest.mark.parametrize("text, pattern", [
    ("[" * 100000 + "]" * 100000, "nested deeper than"),
    ('{"a":' * 50 + "1" + "}" * 50, "nested deeper than"),
    ("", "line 1: not valid JSON"),
    ("\n\n{oops", "line 3: not valid JSON"),
    ("9" * 5000, "not valid JSON"),
])
def test_unreadable_model_json_is_one_line(tmp_path, text, pattern):
    p = tmp_path / "model.json"
    p.write_text(text)
    with pytest.raises(ModelError, match=pattern):
        MlpModel.load(p)


def test_undecodable_model_json_names_the_file(tmp_path):
    p = tmp_path / "model.json"
    p.write_bytes(b'{"format": "\xff\xfe"}')
    with pytest.raises(ModelError, match=r"model\.json: byte 12: not UTF-8 JSON"):
        MlpModel.load(p)


def test_model_json_with_a_bom_loads(tmp_path):
    p = tmp_path / "model.json"
    p.write_bytes(b"\xef\xbb\xbf" + (REPO / "export" / "dn_model_default.json").read_bytes())
    assert MlpModel.load(p).n_inputs == 3


# -- item 9: a negative time constant is refused by every command, in one place -----------

def _lag_model(tau: float) -> dict:
    d = _default_model_dict()
    d["features"] = ["velocity", "acceleration", "voltage_lag"]
    d["feature_params"] = {"control_lag_tau_s": tau}
    return d


@pytest.mark.parametrize("command", ["evaluate", "simulate"])
def test_negative_feature_time_constant_is_refused_by_every_command(tmp_path, capsys, command):
    p = tmp_path / "model.json"
    p.write_text(json.dumps(_lag_model(-0.02)))
    with pytest.raises(ModelError, match=r"feature_params\['control_lag_tau_s'\]: expected a positive value"):
        MlpModel.load(p)
    d = _dataset(tmp_path)
    argv = ({"evaluate": ["evaluate", str(p), str(d)],
             "simulate": ["simulate", str(p), "--road", "impulse", "--out", str(tmp_path / "o")]})[command]
    err = _one_line_cli_error(capsys, argv)
    assert "control_lag_tau_s" in err


def test_positive_feature_time_constant_loads():
    assert MlpModel.from_dict(_lag_model(0.02)).feature_params == {"control_lag_tau_s": 0.02}


# -- item 8: meta.json -----------------------------------------------------------------

@pytest.mark.parametrize("content, pattern", [
    (b"[1, 2]", r"meta\.json: expected a JSON object, got a list"),
    (b"5", r"meta\.json: expected a JSON object, got a number"),
    (b"null", r"meta\.json: expected a JSON object, got null"),
    (b"[" * 5000 + b"]" * 5000, r"meta\.json: nested deeper than"),
    (b'{"generator": "dampnet.data.rig", "noise": 5}', r"meta\.json: field 'noise': expected a JSON object"),
    (b'{"noise": {"force_n": "2"}}', r"meta\.json: field 'noise'\['force_n'\]: expected a number"),
    (b'{"generator": "dampnet.data.rig", "noise": {}}', r"meta\.json: field 'noise': expected the rig's force_n"),
    (b'{"generator": "dampnet.data.rig"}', r"meta\.json: field 'noise': expected the rig's force_n"),
    (b'{"effects": 3}', r"meta\.json: field 'effects': expected an object or a list"),
    (b'{"plan": []}', r"meta\.json: field 'plan': expected a JSON object"),
    (b'{"a": "\xff"}', r"meta\.json: byte 7: not UTF-8 JSON"),
])
def test_malformed_meta_json_is_a_data_error(tmp_path, content, pattern):
    d = _dataset(tmp_path)
    (d / "meta.json").write_bytes(content)
    with pytest.raises(DataError, match=pattern):
        load_dataset(d)


def test_rig_meta_with_bom_loads(tmp_path):
    d = _dataset(tmp_path)
    (d / "meta.json").write_bytes(b"\xef\xbb\xbf" + json.dumps(
        {"generator": "dampnet.data.rig", "noise": {"force_n": 2.0}, "effects": {}}).encode())
    assert load_dataset(d).meta["noise"]["force_n"] == 2.0


# -- item 8: manifest and test CSVs ----------------------------------------------------------

def test_manifest_field_beyond_the_csv_limit_is_one_line(tmp_path, capsys):
    d = _dataset(tmp_path)
    big = "x" * (csv.field_size_limit() + 10)
    (d / "manifest.csv").write_text(MANIFEST.strip() + ",note\n" + f'A,a.csv,1,0.0254,2,"{big}"\n')
    with pytest.raises(DataError, match=r"manifest\.csv: line 2: not readable as CSV") as e:
        load_dataset(d)
    assert len(str(e.value)) < 600
    _one_line_cli_error(capsys, ["evaluate", str(REPO / "export" / "dn_model_default.json"), str(d)])


def test_long_cells_are_echoed_at_most_200_characters(tmp_path):
    d = _dataset(tmp_path, GOOD.replace("0.05,0.005,0.1,50.0,2.0", "0.05,0.005,0.1," + "7a" * 50000 + ",2.0"))
    with pytest.raises(DataError, match=r"a\.csv: line 7, column 'force_n': expected a number") as e:
        load_dataset(d)
    assert len(str(e.value)) < 500 and "(100000 characters)" in str(e.value)
    d2 = _dataset(tmp_path, name="ds2")
    (d2 / "manifest.csv").write_text(MANIFEST + "A," + "b" * 100000 + ".csv,1,0.0254,2\n")
    with pytest.raises(DataError) as e:
        load_dataset(d2)
    assert len(str(e.value)) < 500


def test_manifest_and_test_csv_with_a_bom_load(tmp_path):
    d = _dataset(tmp_path)
    for f in ("a.csv", "manifest.csv"):
        (d / f).write_bytes(b"\xef\xbb\xbf" + (d / f).read_bytes())
    t = load_dataset(d).tests[0]
    assert len(t) == 20 and t.channels["force"][3] == 30.0


def test_line_numbers_count_blank_lines(tmp_path):
    lines = GOOD.splitlines()
    lines[6] = lines[6].replace(",0.1,", ",nan,")  # file line 7 before the blank lines go in
    body = "\n".join(lines[:3] + ["", ""] + lines[3:]) + "\n"  # two blank lines after data line 3
    with pytest.raises(DataError, match=r"a\.csv: line 9, column 'velocity_m_s': expected a finite number, got nan"):
        load_dataset(_dataset(tmp_path, body))


def test_time_errors_show_plain_numbers_not_numpy_reprs(tmp_path):
    body = GOOD.replace("0.05,0.005", "0.03,0.005", 1)
    with pytest.raises(DataError, match=r"line 7, column 'time_s': decreasing time 0\.03 after 0\.04: expected strictly") as e:
        load_dataset(_dataset(tmp_path, body))
    assert "np." not in str(e.value)


def test_a_second_unit_column_name_of_any_length_is_one_line(tmp_path):
    p = tmp_path / "x.csv"
    p.write_text("time_s," + "_".join(["force"] * 20000) + "\n" + "".join(f"{k},{k}\n" for k in range(20)))
    with pytest.raises(DataError, match=r"expected a column name of at most 100 characters") as e:
        load_dataset(p, voltage=1.0)
    assert len(str(e.value)) < 600


def test_mat_with_a_byte_order_scipy_cannot_read_is_refused(tmp_path):
    import io

    import scipy.io

    buf = io.BytesIO()
    scipy.io.savemat(buf, {"x": np.ones((12, 3)), "u": np.ones(12)}, format="4")
    raw = bytearray(buf.getvalue())
    raw[0:4] = (3000).to_bytes(4, "little")  # MOPT: byte order 'Cray' ("returned data may be corrupt")
    p = tmp_path / "r.mat"
    p.write_bytes(bytes(raw))
    with pytest.raises(DataError, match=r"r\.mat: not a readable MATLAB"):
        load_dataset(p, mapping={"force_n": "x:2", "displacement_m": "x:0", "velocity_m_s": "x:1"},
                     voltage=1.0, dt=1e-3)


@pytest.mark.parametrize("metrics", [b"5", b"[1]", b'{"lookup_table": 3}', b'{"lookup_table": {"a": 1}}', b"\xff"])
def test_a_damaged_metrics_json_falls_back_to_fitting_the_lookup_table(tmp_path, metrics):
    from dampnet.evaluation.report import lookup_for

    m = tmp_path / "m"
    m.mkdir()
    (m / "model.json").write_text((REPO / "export" / "dn_model_default.json").read_text())
    (m / "metrics.json").write_bytes(metrics)
    ds = load_dataset(_dataset(tmp_path))
    table, source = lookup_for(m, ds, [])
    assert source == "fitted on the evaluated data's non-hold-out tests" and table is not None


def test_a_mat_file_that_crashes_scipy_is_a_data_error_not_a_crash(tmp_path):
    """A 531-byte mutated v5 file makes scipy 1.17's loadmat segfault (found by the property
    tests); read_mat runs scipy in a child process, so dampnet survives and says so."""
    import subprocess
    import sys

    p = tmp_path / "bad.mat"
    p.write_bytes((REPO / "fuzz" / "python" / "corpus" / "mat_scipy_segfault").read_bytes()[1:])
    code = ("import sys; from dampnet.data import DataError, read_mat\n"
            "try:\n    read_mat(sys.argv[1], mapping={'force_n': 'x:2'}, voltage=1.0, dt=1e-3)\n"
            "except DataError as e:\n    print(e)\n")
    proc = subprocess.run([sys.executable, "-c", code, str(p)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "bad.mat: not a readable MATLAB v4-v7.2 .mat file" in proc.stdout, proc.stdout


def test_mat_variables_come_back_from_the_child_intact(tmp_path):
    import scipy.io

    k = np.arange(15)
    x = np.column_stack([np.sin(k / 3), np.cos(k / 3), 20 * np.cos(k / 3)])
    p = tmp_path / "ok.mat"
    scipy.io.savemat(p, {"x": x, "label": "run 3", "dt": 1e-3})
    t = load_dataset(p, mapping={"displacement_m": "x:0", "velocity_m_s": "x:1", "force_n": "x:2"},
                     voltage=1.5, dt="dt")
    np.testing.assert_array_equal(t.tests[0].channels["force"], x[:, 2])
    assert t.tests[0].dt == pytest.approx(1e-3)
    with pytest.raises(DataError, match=r"variable 'label': expected real numbers, got <U5"):
        load_dataset(p, mapping={"force_n": "label", "displacement_m": "x:0", "velocity_m_s": "x:1"},
                     voltage=1.5, dt=1e-3)
