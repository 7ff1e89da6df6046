"""The model as an ONNX graph (`dampnet export MODEL --onnx OUT.onnx`): the MLP with its input
handling and scalings, for the tools that run ONNX (onnxruntime, ...). Needs the `onnx` package."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from dampnet.export.header import _package_version
from dampnet.model import MlpModel, check_runtime_accepts
from dampnet.outputs import atomic_write_bytes

#: the ONNX opset of the exported graphs (Clip with tensor bounds, IsNaN/Where, Gemm)
ONNX_OPSET = 17


def onnx_graph(model: MlpModel):
    """The MLP with its input handling and scalings as one ONNX model (onnx.ModelProto, float32).

    Inputs: one tensor [batch, 1] per feature, named by the feature, in the model's order
    (units in their doc strings). Each input: NaN -> the centre of its saturation range, then
    clipped to [sat_lo, sat_hi] (the runtime's policy, dn_mlp_forward), scaled by mapminmax;
    dense layers with the model's activation; output `force` [batch, 1] [N] unscaled. A hybrid
    model's physics terms are not in the graph (listed in its metadata, "terms"): the graph is
    the network, as `dampnet.reference.mlp_forward`. Needs the `onnx` package."""
    import json

    import onnx
    from onnx import TensorProto, helper, numpy_helper

    f32 = np.float32
    n_in = model.n_inputs
    act = "Tanh" if model.activation == "tanh" else "Sigmoid"
    init, nodes = [], []

    def const(name, arr):
        init.append(numpy_helper.from_array(np.asarray(arr, dtype=f32), name))
        return name

    lo, hi = model.sat_lo.astype(np.float64), model.sat_hi.astype(np.float64)
    nodes.append(helper.make_node("Concat", list(model.features), ["x_raw"], axis=1))
    nodes.append(helper.make_node("IsNaN", ["x_raw"], ["x_isnan"]))
    nodes.append(helper.make_node("Where", ["x_isnan", const("sat_mid", [(0.5 * (lo + hi))]), "x_raw"], ["x_nonan"]))
    # Max then Min with tensor bounds (Clip takes scalars only): +-Inf clamp to the limits
    nodes.append(helper.make_node("Max", ["x_nonan", const("sat_lo", [lo])], ["x_lo"]))
    nodes.append(helper.make_node("Min", ["x_lo", const("sat_hi", [hi])], ["x_sat"]))
    # mapminmax: (x - offset) gain + ymin, as one affine map per input
    gain = model.in_gain.astype(np.float64)
    nodes.append(helper.make_node("Mul", ["x_sat", const("in_gain", [gain])], ["x_g"]))
    nodes.append(helper.make_node("Add", ["x_g", const("in_shift", [model.in_ymin - model.in_offset * gain])], ["x_s"]))
    nodes.append(helper.make_node("Gemm", ["x_s", const("w1", model.w1), const("b1", model.b1)], ["z1"], transB=1))
    nodes.append(helper.make_node(act, ["z1"], ["a1"]))
    last = "a1"
    if model.w2 is not None:
        nodes.append(helper.make_node("Gemm", ["a1", const("w2", model.w2), const("b2", model.b2)], ["z2"], transB=1))
        nodes.append(helper.make_node(act, ["z2"], ["a2"]))
        last = "a2"
    # output: (w_out a + b_out - out_ymin) / out_gain + out_offset, folded into one Gemm
    w = model.w_out.reshape(1, -1) / model.out_gain
    b = [(model.b_out - model.out_ymin) / model.out_gain + model.out_offset]
    nodes.append(helper.make_node("Gemm", [last, const("w_out", w), const("b_out", b)], ["force"], transB=1))
    inputs = [helper.make_tensor_value_info(name, TensorProto.FLOAT, ["batch", 1], doc_string=f"[{unit}]")
              for name, unit in zip(model.features, model.units)]
    output = helper.make_tensor_value_info("force", TensorProto.FLOAT, ["batch", 1],
                                           doc_string=f"{model.output} [{model.output_unit}]")
    graph = helper.make_graph(nodes, "dampnet_mlp", inputs, [output], init)
    onnx_model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", ONNX_OPSET)],
                                   producer_name="dampnet", producer_version=_package_version())
    onnx_model.ir_version = 8  # onnxruntime >= 1.14 reads IR 8 with opset 17
    meta = {"model_id": model.model_id(), "features": json.dumps(model.features), "units": json.dumps(model.units),
            "terms": json.dumps(model.terms), "feature_params": json.dumps(model.feature_params),
            "saturation": "NaN -> centre of [sat_lo, sat_hi], then clipped to it (the dampnet runtime's policy)"}
    for k, v in meta.items():
        onnx_model.metadata_props.add(key=k, value=str(v))
    assert n_in == len(inputs)
    onnx.checker.check_model(onnx_model, full_check=True)
    return onnx_model


def write_onnx(model: MlpModel, path: str | os.PathLike, overwrite: bool = False) -> Path:
    """onnx_graph(model) written atomically to path (an existing file only with overwrite); a
    model the runtime would refuse is refused (check_runtime_accepts: its graph would give NaN)."""
    check_runtime_accepts(model)
    path = Path(path)
    if path.exists() and not overwrite:
        raise FileExistsError(f"{path}: exists; refusing to overwrite")
    atomic_write_bytes(path, onnx_graph(model).SerializeToString(), overwrite=True)
    return path
