"""`dampnet export --onnx`: the network with its input handling as one ONNX graph, checked by
onnx.checker and run by onnxruntime against the runtime's float kernel (dampnet._core) on
inputs inside, outside and at the edges of the training range, NaN and +-Inf included."""

import json

import numpy as np
import onnx
import onnxruntime as ort
import pytest

from dampnet.cli import main
from dampnet.export import ONNX_OPSET, onnx_graph
from dampnet.modeldir import default_model, save_model_dir


def _session(model):
    return ort.InferenceSession(onnx_graph(model).SerializeToString(), providers=["CPUExecutionProvider"])


def _inputs(model, n=10_000, seed=0):
    rng = np.random.default_rng(seed)
    lo, hi = model.sat_lo, model.sat_hi
    x = lo + (hi - lo) * rng.uniform(-0.5, 1.5, (n, model.n_inputs))  # half outside the range
    for value, share in ((np.nan, 0.01), (np.inf, 0.01), (-np.inf, 0.01)):
        x[rng.uniform(size=x.shape) < share] = value
    return x


@pytest.mark.parametrize("which", ["default", "two_layers_sigmoid"])
def test_onnx_graph_equals_the_runtime_float_kernel(which):
    """onnxruntime's output equals the runtime's float forward (Mlp.predict(single=True)) to
    1e-5 of the force range on 10,000 inputs, a quarter of them beyond each saturation limit
    and some NaN / +-Inf (the graph must clamp and replace them as the runtime does)."""
    from loop_helpers import random_model

    model = default_model() if which == "default" else random_model(
        ["velocity", "acceleration", "voltage", "displacement"], hidden=12, seed=3)
    if which != "default":
        model.activation = "sigmoid"
        rng = np.random.default_rng(1)
        model.w2, model.b2 = rng.normal(size=(7, 12)) / 3, rng.normal(size=7) / 3
        model.w_out = rng.normal(size=7)
    x = _inputs(model)
    feeds = {f: x[:, i:i + 1].astype(np.float32) for i, f in enumerate(model.features)}
    y = _session(model).run(None, feeds)[0][:, 0]
    ref = model.core().predict(x.astype(np.float32).astype(np.float64), single=True)[0]
    force_range = (1.0 - model.out_ymin) / model.out_gain
    assert np.all(np.isfinite(y))
    np.testing.assert_allclose(y, ref, rtol=0, atol=1e-5 * force_range)
    # the clamping matters: without it the outside inputs would differ by far more
    assert np.ptp(ref) > 0.1 * force_range


def test_onnx_graph_is_valid_and_describes_itself():
    model = default_model()
    g = onnx_graph(model)
    onnx.checker.check_model(g, full_check=True)
    assert g.opset_import[0].version == ONNX_OPSET
    assert [i.name for i in g.graph.input] == model.features
    assert [o.name for o in g.graph.output] == ["force"]
    meta = {p.key: p.value for p in g.metadata_props}
    assert meta["model_id"] == model.model_id() and json.loads(meta["features"]) == model.features


def test_export_command_writes_onnx_and_header(tmp_path, capsys):
    save_model_dir(default_model(), None, tmp_path / "model")
    out = tmp_path / "m.onnx"
    assert main(["export", str(tmp_path / "model"), "--onnx", str(out), "--header", str(tmp_path / "m.h"),
                 "--prefix", "my_damper"]) == 0
    text = capsys.readouterr().out
    assert "ONNX opset 17" in text and "velocity, acceleration, voltage" in text
    assert onnx.load(str(out)).graph.output[0].name == "force"
    assert "MY_DAMPER_N_INPUTS" in (tmp_path / "m.h").read_text()
    # no overwrite without --force; nothing to export; a bad prefix; a missing model
    assert main(["export", str(tmp_path / "model"), "--onnx", str(out)]) == 2
    assert "exists; refusing to overwrite" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "model"), "--onnx", str(out), "--force"]) == 0
    assert main(["export", str(tmp_path / "model")]) == 2
    assert "nothing to export" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "model"), "--header", str(tmp_path / "x.h"), "--prefix", "int"]) == 2
    assert "header prefix 'int'" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "nope"), "--onnx", str(tmp_path / "y.onnx")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("dampnet: error: ") and "nope" in err
    assert not (tmp_path / "y.onnx").exists()
