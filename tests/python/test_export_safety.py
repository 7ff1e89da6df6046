"""`dampnet export` never loses a user's file and never exports a model the runtime refuses
(issue 29): every output is checked before anything is written (none is the model, its envelope
or a file of its directory; no two outputs are one file; each is new or --force), and a model
file whose folded parameters the runtime's loader (dn_mlp_create) refuses is refused on load,
by every command, naming the file and the field. The default model, an envelope from synthetic
samples in its ranges: no training, no FMU compiled (every refusal comes first)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from dampnet.cli import main
from dampnet.envelope import build_envelope
from dampnet.export import write_header, write_onnx
from dampnet.model import runtime_refusal
from dampnet.model import MlpModel, ModelError
from dampnet.modeldir import default_model, save_model_dir


@pytest.fixture
def model_dir(tmp_path):
    """tmp/M: the default model with model.json, metrics.json, model.h, envelope.npz/.json."""
    model = default_model()
    X = np.random.default_rng(0).uniform(model.sat_lo, model.sat_hi, size=(300, model.n_inputs))
    save_model_dir(model, {"note": "keep me"}, tmp_path / "M", envelope=build_envelope(model, X))
    return tmp_path / "M"


def _snapshot(d):
    return {p.name: p.read_bytes() for p in sorted(d.iterdir())}


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.startswith("dampnet: error: ") and err.count("\n") == 1 and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("options", [
    ["--header", "{M}/model.json"], ["--onnx", "{M}/model.json"], ["--onnx", "{M}/envelope.npz"],
    ["--fmu", "{M}/model.json"], ["--header", "{M}/envelope.json"], ["--onnx", "{M}/metrics.json"],
    ["--header", "{M}"],
])
@pytest.mark.parametrize("model_arg", ["{M}", "{M}/model.json"])
def test_an_output_that_is_a_file_of_the_input_model_is_refused(model_dir, capsys, options, model_arg):
    before = _snapshot(model_dir)
    opts = [o.format(M=model_dir) for o in options]
    assert main(["export", model_arg.format(M=model_dir), *opts, "--force"]) == 2
    err = _one_error_line(capsys)
    assert f"{opts[0]} {opts[1]}: is an input of this command" in err
    assert _snapshot(model_dir) == before  # nothing written, nothing replaced


def test_a_link_to_the_models_file_is_refused(model_dir, tmp_path, capsys):
    before = _snapshot(model_dir)
    (tmp_path / "link.onnx").symlink_to(model_dir / "model.json")
    assert main(["export", str(model_dir), "--onnx", str(tmp_path / "link.onnx"), "--force"]) == 2
    assert "is an input of this command" in _one_error_line(capsys)
    assert _snapshot(model_dir) == before and (tmp_path / "link.onnx").is_symlink()


@pytest.mark.parametrize("first,second", [("--header", "--onnx"), ("--fmu", "--onnx"), ("--fmu", "--header")])
@pytest.mark.parametrize("exists", [False, True])
def test_two_outputs_naming_one_file_are_refused_before_writing(model_dir, tmp_path, capsys, first, second, exists):
    out = tmp_path / "out.bin"
    if exists:
        out.write_bytes(b"the user's file")
    # the same file spelled two ways
    assert main(["export", str(model_dir), first, str(out), second, str(tmp_path / "." / "out.bin"), "--force"]) == 2
    err = _one_error_line(capsys)
    assert "name the same file" in err and first in err and second in err
    assert (out.read_bytes() == b"the user's file") if exists else not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["M"] + (["out.bin"] if exists else []))


def test_every_output_is_checked_before_the_first_is_written(model_dir, tmp_path, capsys):
    (tmp_path / "old.h").write_text("keep")
    # --fmu and --onnx come first in the export order; --header's refusal must stop them
    assert main(["export", str(model_dir), "--fmu", str(tmp_path / "a.fmu"), "--onnx", str(tmp_path / "a.onnx"),
                 "--header", str(tmp_path / "old.h")]) == 2
    err = _one_error_line(capsys)
    assert "--header" in err and "exists; refusing to overwrite (use --force)" in err
    assert not (tmp_path / "a.fmu").exists() and not (tmp_path / "a.onnx").exists()
    assert (tmp_path / "old.h").read_text() == "keep"


def test_plan_tests_uses_the_same_check(model_dir, tmp_path, capsys):
    assert main(["plan-tests", str(model_dir), "impulse:low", "--budget", "1", "--out", str(tmp_path / "p.json"),
                 "--table", str(tmp_path / "p.json")]) == 2
    assert "--out and --table name the same file" in _one_error_line(capsys)


def test_a_missing_parent_directory_is_created_for_the_header_and_the_onnx_graph(model_dir, tmp_path, capsys):
    assert main(["export", str(model_dir), "--header", str(tmp_path / "new" / "m.h"),
                 "--onnx", str(tmp_path / "new2" / "deeper" / "m.onnx")]) == 0
    assert (tmp_path / "new" / "m.h").is_file() and (tmp_path / "new2" / "deeper" / "m.onnx").is_file()


# -- a model the runtime refuses -----------------------------------------------------------------

def _model_json(tmp_path, **changes) -> str:
    d = default_model().to_dict()
    for key, value in changes.items():
        if isinstance(value, tuple):  # (index, value) into an array field
            d[key][value[0]] = value[1]
        else:
            d[key] = value
    (tmp_path / "G").mkdir(exist_ok=True)
    (tmp_path / "G" / "model.json").write_text(json.dumps(d))
    return str(tmp_path / "G")


@pytest.mark.parametrize("changes,field,where", [
    ({"in_gain": (0, 1e300)}, "'in_gain'", "velocity"),       # ONNX gave NaN, the FMU failed at instantiation
    ({"in_gain": (2, 1e39)}, "'in_gain'", "voltage"),
    ({"out_gain": 1e-300}, "'out_gain'", "w_out / out_gain"),
    ({"out_offset": 1e39}, "'out_offset'", "out_offset"),
    ({"sat_lo": (1, -1e39)}, "'sat_lo'", "acceleration"),
])
@pytest.mark.parametrize("option,name", [("--onnx", "g.onnx"), ("--header", "g.h"), ("--fmu", "g.fmu")])
def test_a_model_the_runtime_refuses_is_not_exported(tmp_path, capsys, changes, field, where, option, name):
    g = _model_json(tmp_path, **changes)
    assert main(["export", g, option, str(tmp_path / name)]) == 2
    err = _one_error_line(capsys)
    assert f"{g}/model.json: field {field}" in err and where in err and "refuses the model" in err, err
    assert not (tmp_path / name).exists()


def test_other_commands_name_the_file_and_field_too(tmp_path, capsys):
    """`Mlp: DN_E_PARAM` with no file was all `dampnet vehicle` said."""
    g = _model_json(tmp_path, in_gain=(1, 1e300))
    assert main(["vehicle", g, "--out", str(tmp_path / "v")]) == 2
    err = _one_error_line(capsys)
    assert f"{g}/model.json: field 'in_gain' (input acceleration)" in err and "DN_E_PARAM" in err
    assert not (tmp_path / "v").exists()


def test_the_export_target_folder_and_the_python_writers_refuse_it_too(tmp_path, capsys):
    g = _model_json(tmp_path, in_gain=(0, 1e300))
    assert main(["export", g, "--target", "cortex-m4", "--out", str(tmp_path / "fw")]) == 2
    assert f"{g}/model.json: field 'in_gain' (input velocity)" in _one_error_line(capsys)
    assert not (tmp_path / "fw").exists()
    m = dataclasses.replace(default_model(), in_gain=default_model().in_gain * [1e300, 1, 1])  # not from a file
    for write in (write_header, write_onnx):
        with pytest.raises(ModelError, match=r"^model: field 'in_gain' \(input velocity\)"):
            write(m, tmp_path / "x.out")
        assert not (tmp_path / "x.out").exists()


@pytest.mark.parametrize("field,index", [("in_gain", 0), ("in_gain", 1), ("w1", None), ("out_gain", None),
                                         ("in_offset", 2), ("b_out", None)])
def test_load_refuses_exactly_what_the_runtime_refuses(field, index):
    """Against the runtime itself: over scales from harmless to far beyond float, a model file
    loads if and only if dampnet._core.Mlp (dn_mlp_create) accepts the model."""
    base = default_model().to_dict()
    for scale in (1.0, 1e20, 1e30, 1e36, 1e37, 1e38, 3e38, 1e39, 1e100, 1e300, 1e-30, 1e-38, 1e-300):
        d = json.loads(json.dumps(base))
        if field == "w1":
            d["w1"] = (np.array(d["w1"]) * scale).tolist()
        elif index is None:
            d[field] = d[field] * scale if field != "out_gain" else d[field] / scale
        else:
            d[field][index] = d[field][index] * scale
        m = dataclasses.replace(default_model(), w1=np.array(d["w1"]), in_gain=np.array(d["in_gain"]),
                                in_offset=np.array(d["in_offset"]), out_gain=d["out_gain"], b_out=d["b_out"])
        try:
            m.core()
            accepted = True
        except ValueError as e:
            assert "DN_E_PARAM" in str(e)
            accepted = False
        assert (runtime_refusal(m) is None) == accepted, (field, scale)
        if accepted:
            MlpModel.from_dict(d, "x.json")
        else:
            with pytest.raises(ModelError, match=r"^x\.json: "):
                MlpModel.from_dict(d, "x.json")


def test_an_accepted_model_still_exports_and_round_trips(model_dir, tmp_path, capsys):
    assert main(["export", str(model_dir), "--header", str(tmp_path / "m.h")]) == 0
    assert "with the training envelope" in capsys.readouterr().out
    assert runtime_refusal(default_model()) is None
