"""The generated header's format, the exporter's checks, and model.json round trips."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from dampnet.export import check_prefix, header_text, write_header
from dampnet.model import MlpModel, ModelError
from kernel_cases import random_model


def _array_values(text: str, name: str) -> np.ndarray:
    m = re.search(rf"static const double {name}\[[^\]]*\] = \{{(.*?)\}};", text, re.S)
    assert m, f"{name} not in header"
    return np.array([float(v) for v in m.group(1).replace("\n", " ").split(",") if v.strip()])


def test_header_has_banner_guard_sizes_layout_and_features():
    model = random_model(3, (30,), "sigmoid", seed=1)
    model.meta = {"algorithm": "lm", "data": "rig quick plan"}
    text = header_text(model, "my_damper")
    assert "DO NOT EDIT" in text.splitlines()[1]
    assert f"model id: {model.model_id()}" in text
    assert "algorithm: lm" in text
    assert "#ifndef MY_DAMPER_H_" in text and "#endif /* MY_DAMPER_H_ */" in text
    assert "#define MY_DAMPER_N_INPUTS 3" in text and "#define MY_DAMPER_N_HIDDEN1 30" in text
    assert "#define MY_DAMPER_ACTIVATION 1 /* DN_ACT_SIGMOID */" in text
    assert "row-major" in text
    assert 'my_damper_feature_names[3] = {"x0", "x1", "x2"}' in text
    assert "MY_DAMPER_DESC_INIT" in text


def test_header_values_round_trip_exactly():
    """17 significant digits (at least the 9 a float needs): every weight parses back exactly."""
    model = random_model(4, (9, 5), "tanh", seed=2)
    text = header_text(model, "m")
    np.testing.assert_array_equal(_array_values(text, "m_w1"), model.w1.ravel())
    np.testing.assert_array_equal(_array_values(text, "m_w2"), model.w2.ravel())
    np.testing.assert_array_equal(_array_values(text, "m_w_out"), model.w_out)
    np.testing.assert_array_equal(_array_values(text, "m_sat_hi"), model.sat_hi)



@pytest.mark.parametrize("bad", ["", "1abc", "my-model", "int", "class", "dn", "a b"])
def test_invalid_prefix_is_refused(bad):
    with pytest.raises(ValueError, match="prefix"):
        check_prefix(bad)


def test_write_header_refuses_to_overwrite_and_writes_atomically(tmp_path):
    model = random_model(2, (3,), "tanh", seed=3)
    path = tmp_path / "model.h"
    path.write_text("user's own file\n")
    with pytest.raises(FileExistsError):
        write_header(model, path, "m")
    assert path.read_text() == "user's own file\n"
    write_header(model, path, "m", overwrite=True)
    assert "DO NOT EDIT" in path.read_text()
    assert [p.name for p in tmp_path.iterdir()] == ["model.h"]  # no temporary left behind


def test_terms_and_feature_params_are_exported():
    model = random_model(4, (5,), "tanh", seed=4)
    model.terms = [{"kind": "position_poly", "params": [250.0, 3000.0, 0.0, 1e5]}]
    model.feature_params = {"control_lag_tau_s": 0.04}
    text = header_text(model, "h")
    assert "#define H_N_TERMS 1" in text
    assert 'h_term_kinds[1] = {"position_poly"}' in text
    np.testing.assert_array_equal(_array_values(text, "h_term_params"), [250.0, 3000.0, 0.0, 1e5])
    assert "#define H_CONTROL_LAG_TAU_S (0.040000000000000001)" in text


def test_model_json_round_trip(tmp_path):
    model = random_model(5, (8, 4), "sigmoid", seed=5)
    model.meta = {"algorithm": "br", "gamma": 42.5}
    model.save(tmp_path / "model.json")
    back = MlpModel.load(tmp_path)
    assert back.model_id() == model.model_id()
    assert back.meta == model.meta and back.features == model.features
    x = np.random.default_rng(0).uniform(-1, 1, (50, 5))
    np.testing.assert_array_equal(back.predict(x), model.predict(x))
    with pytest.raises(FileExistsError):
        model.save(tmp_path / "model.json")


def test_bad_model_files_name_the_problem(tmp_path):
    p = tmp_path / "model.json"
    p.write_text("{not json")
    with pytest.raises(ModelError, match=r"model.json: line 1"):
        MlpModel.load(p)
    d = random_model(2, (3,), "tanh", seed=6).to_dict()
    del d["w_out"]
    p.write_text(json.dumps(d))
    with pytest.raises(ModelError, match="missing field 'w_out'"):
        MlpModel.load(p)
    d = random_model(2, (3,), "tanh", seed=6).to_dict()
    d["b1"] = [1.0]
    p.write_text(json.dumps(d))
    with pytest.raises(ModelError, match="b1: expected 3 values"):
        MlpModel.load(p)
    d["b1"] = [float("nan")] * 3
    p.write_text(json.dumps(d))
    with pytest.raises(ModelError, match="finite"):
        MlpModel.load(p)


def test_model_refuses_inputs_of_the_wrong_width():
    model = random_model(3, (4,), "tanh", seed=7)
    with pytest.raises(ModelError, match="expected 3 columns"):
        model.predict(np.zeros((4, 2)))


def test_status_codes_reach_python():
    model = random_model(2, (3,), "tanh", seed=8)
    core = model.core()
    y, st, mask = core.forward(np.array([np.nan, model.sat_hi[1] + 10]))
    from dampnet import _core

    assert st == (_core.DN_W_SATURATED | _core.DN_W_NONFINITE_INPUT) and mask == 3
    assert np.isfinite(y)
    assert "NaN" in _core.status_str(_core.DN_W_NONFINITE_INPUT)


def test_cdefs_match_the_header(repo_root):
    """The tests' cffi declaration of dn_mlp_desc has the header's fields in the header's order."""
    from cdefs import MLP_CDEF

    header = (repo_root / "cpp" / "include" / "dampnet" / "dn_types.h").read_text()  # dampnet.h's types
    body = re.search(r"typedef struct dn_mlp_desc \{(.*?)\} dn_mlp_desc;", header, re.S).group(1)
    fields = re.findall(r"(\w+);", re.sub(r"/\*.*?\*/", "", body, flags=re.S))
    cdef_body = re.search(r"typedef struct dn_mlp_desc \{(.*?)\} dn_mlp_desc;", MLP_CDEF, re.S).group(1)
    assert re.findall(r"(\w+);", cdef_body.replace(",", ";")) == fields


def test_the_default_header_is_its_json_exported_by_this_version(repo_root):
    # export/dn_model_default.h said "dampnet 0.2.0" in a 0.3.0 tree: it was not regenerated
    # after the version bump. It must be exactly what this package exports from its json twin.
    import dampnet

    header = (repo_root / "export" / "dn_model_default.h").read_text()
    assert f"(dampnet {dampnet.__version__})" in header.splitlines()[1]
    model = MlpModel.load(repo_root / "export" / "dn_model_default.json")
    assert header == header_text(model, "dn_model_default"), \
        "stale: python export/make_default_model.py --rewrite"


def test_the_exported_activation_is_the_runtime_registry():
    from dampnet import _core

    for name, (value, _) in _core.ACTIVATIONS.items():
        text = header_text(random_model(2, (3,), name, seed=0), "m")
        assert f"#define M_ACTIVATION {value} /* DN_ACT_{name.upper()} */" in text


def test_the_header_states_the_control_input_and_the_inverses_range():
    """Issue 55: P_CONTROL_INPUT / _MIN / _MAX are the input reading dn_damper_input.u and the range
    the runtime's inverse searches (Damper.control_range, double and float); -1 and 0 where the
    runtime has no control (no input reads u, or a lag only). Cost: 0.05 s."""

    from dampnet.modeldir import default_model
    from dampnet.sim.quarter_car.loop import damper_from_model
    from loop_helpers import random_model

    cases = [(default_model(), 2), (random_model(["velocity", "current"], hidden=4, seed=1), 1),
             (random_model(["velocity", "voltage_lag"], hidden=4, seed=1,
                           feature_params={"control_lag_tau_s": 0.01}), -1)]
    for model, k in cases:
        text = header_text(model, "ctl")
        macros = dict(re.findall(r"#define CTL_(CONTROL_\w+) \(?([-0-9.e]+)\)?", text))
        assert int(macros["CONTROL_INPUT"]) == k
        lo, hi = float(macros["CONTROL_MIN"]), float(macros["CONTROL_MAX"])
        if k < 0:
            assert (lo, hi) == (0.0, 0.0)
            with pytest.raises(ValueError):
                damper_from_model(model).control_range()
            continue
        assert (lo, hi) == damper_from_model(model).control_range()
        assert (lo, hi) == pytest.approx(damper_from_model(model, single=True).control_range(), rel=1e-7)
        assert f"/* [{model.units[k]}] */" in text
