"""The Python-level benchmark (dampnet.latency.python_bench): its reference implementations compute the
kernel's function, its inputs are the C++ harness's, its percentiles are right, and
`dampnet bench` in a quick configuration completes with every row. No times are asserted:
the machines are shared and noisy."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import needs

from cbuild import ROOT, compile_program, run
from dampnet.latency import python_bench as bp
from dampnet.modeldir import default_model


@pytest.fixture(scope="module")
def model():
    return default_model()


def test_default_model_is_the_harness_header_model(model):
    assert model.model_id() == bp.header_model_id()


def test_inputs_are_the_cpp_harness_inputs(tmp_path, model):
    src = tmp_path / "inputs.cpp"
    lo, hi = model.sat_lo, model.sat_hi
    src.write_text(f"""
#include <cstdio>
#include <random>
int main() {{
  const double lo[3] = {{{', '.join(repr(float(v)) for v in lo)}}};
  const double hi[3] = {{{', '.join(repr(float(v)) for v in hi)}}};
  std::mt19937 rng(1);
  for (int k = 0; k < 1024; ++k)
    for (int i = 0; i < 3; ++i) {{
      std::uniform_real_distribution<double> u(lo[i], hi[i]);
      std::printf("%.17g\\n", u(rng));
    }}
}}
""")
    exe = compile_program([src], tmp_path / "inputs", cxx=True, include_dirs=[])
    cpp = np.array(run([exe]).stdout.split(), dtype=float).reshape(1024, 3)
    assert np.array_equal(bp.harness_inputs(model), cpp)


def test_references_compute_the_kernels_function(model, tmp_path):
    """torch eager, TorchScript, onnxruntime (float32) within 1e-5 of the output range of
    MlpModel.predict (float64 kernel), numpy and the pybind double call within 1e-10; on the
    harness inputs and on inputs beyond the training range (the clamp)."""
    needs.need_module("torch", "train")
    needs.need_module("onnxruntime")
    rng = np.random.default_rng(5)
    span = model.sat_hi - model.sat_lo
    outside = model.sat_lo - 0.5 * span + 2.0 * span * rng.random((200, model.n_inputs))
    X = np.vstack([bp.harness_inputs(model), outside])
    with bp._torch_threads_restored():
        cands = bp.build_candidates(model, X, tmp_path)
    assert {"dampnet_pybind_forward", "dampnet_pybind_forward_float", "numpy_forward", "torch_eager",
            "torch_script", "onnxruntime"} <= set(cands)
    checks = bp.check_references(model, cands, X)  # raises beyond the tolerance
    for name, c in checks.items():
        assert c["ok"] and c["max_err_of_range"] <= c["tolerance_of_range"], (name, c)
    assert bp.TOL_FLOAT32 == 1e-5 and bp.TOL_FLOAT64 == 1e-10
    # the check would catch a different function: a model with one weight changed
    wrong = dict(cands)
    other = default_model()
    other.w1[0, 0] += 0.1
    wrong["numpy_forward"] = dict(cands["numpy_forward"], eval=bp.numpy_forward(other))
    with pytest.raises(RuntimeError, match="numpy_forward"):
        bp.check_references(model, wrong, X)


def test_percentiles_match_numpy_on_a_synthetic_distribution():
    rng = np.random.default_rng(3)
    for n in (100_001, 1001, 7):  # ranks q (n - 1) are whole numbers: no rounding ties
        v = rng.lognormal(4.0, 0.6, n)
        s = bp.summarise(v)
        for key, q in bp.QUANTILES.items():
            if q * (n - 1) == int(q * (n - 1)):
                assert s[key] == np.percentile(v, 100 * q, method="nearest"), (n, key)
            assert s[key] == np.sort(v)[int(q * (n - 1) + 0.5)]
        assert s["max_ns"] == v.max() and s["n"] == n and abs(s["mean_ns"] - v.mean()) < 1e-9 * v.mean()
    # nearest rank rounds half up, as bench/latency.hpp does
    assert bp.percentile(np.array([1.0, 2.0]), 0.5) == 2.0


def test_time_calls_times_each_call():
    calls = []
    r = bp.time_calls(calls.append, 500, 100)
    assert len(calls) == 600 and calls[100:] == list(range(500))
    assert r["n"] == 500 and 0 < r["p50_ns"] <= r["p99_ns"] <= r["p999_ns"] <= r["max_ns"]


def test_dampnet_bench_quick_configuration_has_every_row(tmp_path):
    out = tmp_path / "bench.json"
    proc = subprocess.run([sys.executable, "-m", "dampnet.cli", "bench", "--calls", "20000", "--py-calls",
                           "1000", "--sim-steps", "20000", "--json", str(out)],
                          capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert proc.returncode in (0, 1), proc.stderr  # 1 = HIL budget missed on a noisy machine
    res = json.loads(out.read_text())
    py = res["python"]
    assert py["model_id"] == py["header_model_id"]
    forward = ("python_clock_overhead", "dampnet_pybind_forward", "dampnet_pybind_forward_float",
               "numpy_forward", "torch_eager", "torch_script", "onnxruntime")
    for name in forward:
        r = py["results"][name]
        assert r["n"] == 1000 and 0 < r["p50_ns"] <= r["p99_ns"] <= r["p999_ns"] <= r["max_ns"], name
        assert r["ratio_to_kernel_p50"] > 0
    for d in ("neural_float", "linear"):
        assert py["loop_step"][d]["n"] == 1000 and py["loop_step"][d]["target_ns"] == 1000.0
    for d in ("linear", "neural_float", "neural_double", "neural_float_hil", "neural_float_hil_out"):
        s = py["simulate"][d]
        assert s["n_steps"] == 20000 and s["steps_per_s_median"] > 0
        # the target is for the real-time configurations; the offline ones are reported
        assert s["target_steps_per_s"] == (5e6 if d in ("linear", "neural_float_hil", "neural_float_hil_out")
                                           else None), d
        assert "recording the state" in s["what"]
    assert "fresh arrays" in py["simulate"]["neural_float_hil"]["what"]
    assert "out=" in py["simulate"]["neural_float_hil_out"]["what"]
    names = {r["name"] for r in res["table"]}
    expected = set(forward) | {"dampnet_static_float", "naive_cpp_std_tanh",
                               "loop_step_rk4_neural_float_skyhook", "pybind_loop_step_neural_float",
                               "pybind_loop_step_linear", "pybind_simulate_linear",
                               "pybind_simulate_neural_float", "pybind_simulate_neural_float_hil",
                               "pybind_simulate_neural_float_hil_out"}
    assert expected <= names, expected - names
    for name in expected:
        assert name in proc.stdout
    assert "HIL budget" in proc.stdout and "x kernel p50" in proc.stdout
    assert (proc.returncode == 0) == res["headroom"]["within_budget"]
