"""Capacity as a build-time parameter (issue 33): an averaged network wider than the default
64 neurons (`dampnet train --average`: k networks side by side) saved, run and exported.

* The Python module's runtime is built with DN_MAX_HIDDEN 384 (pyproject.toml): its kernel, in
  double and float, gives numpy's forward for layers of 64 up to its limit. (Before, a layer
  wider than 69 neurons lost its last neurons: the output weights were sized by layer 2's
  capacity, which equalled layer 1's only while both were 64.)
* `dampnet train --restarts 3 --average 3` of 30-neuron networks makes one 90-neuron model that
  saves and loads; its header states the build it needs; a C++ program compiled with the
  header's DN_MAX_HIDDEN gives the Python force, one compiled with the default refuses the
  model (DN_E_SIZE) instead of truncating it.
* The FMU sizes its own build from the model (fmu_config.h defines DN_MAX_HIDDEN) and FMPy's
  co-simulation gives the runtime's forces. The firmware folder: tests/python/test_embedded.py.
"""

from __future__ import annotations

import copy
import subprocess
import zipfile

import numpy as np
import pytest
from fmpy import simulate_fmu

from cbuild import compile_program
from dampnet import _core, paths
from dampnet.export.fmu import build_fmu
from dampnet.export.header import build_defines, write_header
from dampnet.model import MlpModel, ModelError
from dampnet.rig import generate
from dampnet.sim.quarter_car.loop import damper_from_model
from loop_helpers import numpy_forward


@pytest.fixture(scope="module")
def wide(tmp_path_factory) -> MlpModel:
    """Three 30-neuron restarts of a short training on the quick plan, averaged: 90 neurons."""
    import dampnet

    trained = dampnet.train(generate("quick", seed=0), seed=0, restarts=3, average=3, workers=1, max_epochs=30)
    path = tmp_path_factory.mktemp("wide") / "model.json"
    trained.model.save(path)
    return MlpModel.load(path)


def _inputs(model: MlpModel, n: int = 400) -> np.ndarray:
    """Points over the model's input ranges, a tenth beyond them (the saturation) included."""
    lo, hi = np.asarray(model.sat_lo), np.asarray(model.sat_hi)
    span = hi - lo
    return np.random.default_rng(3).uniform(lo - 0.1 * span, hi + 0.1 * span, (n, lo.size))


@pytest.mark.parametrize("width", [64, 65, 70, 128, 200, "max"])
def test_the_runtime_s_kernel_is_numpy_s_forward_up_to_its_width_limit(wide, width):
    width = _core.MAX_HIDDEN if width == "max" else width
    assert _core.MAX_HIDDEN == 384 and _core.MAX_HIDDEN_DEFAULT == 64
    rng = np.random.default_rng(width)
    m = copy.deepcopy(wide)
    m.w1, m.b1 = rng.normal(size=(width, m.n_inputs)), rng.normal(size=width)
    m.w_out = rng.normal(size=width) / np.sqrt(width)
    m.validate()
    x = _inputs(m)
    ref = numpy_forward(m, x)
    scale = 1.0 / m.out_gain  # the output's unit span
    for single, tol in ((False, 1e-12), (True, 2e-6)):
        y, status, _ = m.core().predict(x, single=single)
        assert np.all(status >= 0)
        assert np.max(np.abs(y - ref)) <= tol * scale * np.sqrt(width), (single, np.max(np.abs(y - ref)))


@pytest.mark.parametrize("hidden", [(30, 20), (64, 64)])
def test_two_layer_networks_keep_to_layer_2_s_limit_in_the_wide_build(wide, hidden):
    """Two hidden layers: both within DN_MAX_HIDDEN2 (64), so the [H2][H1] weights stay small in
    a build that raises DN_MAX_HIDDEN; numpy's forward up to it, refused beyond it (DN_E_SIZE)."""
    rng = np.random.default_rng(sum(hidden))
    m = copy.deepcopy(wide)
    h1, h2 = hidden
    m.w1, m.b1 = rng.normal(size=(h1, m.n_inputs)), rng.normal(size=h1)
    m.w2, m.b2, m.w_out = rng.normal(size=(h2, h1)) / np.sqrt(h1), rng.normal(size=h2), rng.normal(size=h2) / np.sqrt(h2)
    m.validate()
    x = _inputs(m)
    y, status, _ = m.core().predict(x, single=False)
    assert np.all(status >= 0)
    np.testing.assert_allclose(y, numpy_forward(m, x), rtol=0, atol=1e-12 * np.sqrt(h1) / m.out_gain)
    m.w1, m.b1 = np.zeros((_core.MAX_HIDDEN2 + 1, m.n_inputs)), np.zeros(_core.MAX_HIDDEN2 + 1)
    m.w2 = np.zeros((h2, _core.MAX_HIDDEN2 + 1))
    with pytest.raises(ModelError, match="two-layer network; the runtime holds 64"):
        m.validate()
    with pytest.raises(ValueError, match=r"layer 1 of a two-layer network, up to DN_MAX_HIDDEN2 = 64"):
        m.core()


def test_a_layer_beyond_the_runtime_s_limit_is_refused_by_name(wide):
    m = copy.deepcopy(wide)
    n = _core.MAX_HIDDEN + 1
    m.w1, m.b1, m.w_out = np.zeros((n, m.n_inputs)), np.zeros(n), np.zeros(n)
    with pytest.raises(ModelError, match=rf"1..{_core.MAX_HIDDEN} neurons in hidden layer 1 .*DN_MAX_HIDDEN"):
        m.validate()


def test_an_average_of_three_is_one_wider_model_that_says_what_build_it_needs(wide, tmp_path):
    assert wide.hidden == (90,)
    assert build_defines(wide) == ["DN_MAX_HIDDEN=90"]
    narrow = copy.deepcopy(wide)
    narrow.w1, narrow.b1, narrow.w_out = wide.w1[:30], wide.b1[:30], wide.w_out[:30]
    assert build_defines(narrow) == []
    x = _inputs(wide)
    np.testing.assert_allclose(wide.predict(x), numpy_forward(wide, x), rtol=0, atol=1e-9)

    header = write_header(wide, tmp_path / "model.h", prefix="dn_model")
    assert "#define DN_MODEL_DN_MAX_HIDDEN 90" in header.read_text()
    prog = tmp_path / "wide.cpp"
    prog.write_text('#include <cstdio>\n#include "dampnet/mlp.hpp"\n#include "model.h"\n'
                    "static dampnet::Mlp<double> m;  // static: its storage is sized by DN_MAX_HIDDEN\n"
                    "int main() {\n  dn_mlp_desc d = DN_MODEL_DESC_INIT;\n  const int st = m.load(&d);\n"
                    "  for (int k = 0; k < 3; ++k) {\n    double x[3], y = 0;\n"
                    "    if (std::scanf(\"%lf %lf %lf\", &x[0], &x[1], &x[2]) != 3) return 2;\n"
                    "    if (st == DN_OK) m.forward(x, &y);\n    std::printf(\"%d %.17g\\n\", st, y);\n  }\n}\n")
    rows = "\n".join(" ".join(repr(float(v)) for v in r) for r in x[:3]) + "\n"
    outs = {}
    for name, extra in (("default", []), ("raised", ["-DDN_MAX_HIDDEN=90"])):
        exe = compile_program([prog], tmp_path / name, cxx=True, include_dirs=[*paths.include_dirs(), tmp_path],
                              extra=extra)
        proc = subprocess.run([str(exe)], input=rows, capture_output=True, text=True, timeout=60, check=True)
        outs[name] = [line.split() for line in proc.stdout.splitlines()]
    assert [int(r[0]) for r in outs["default"]] == [_core.DN_E_SIZE] * 3
    got = np.array([float(r[1]) for r in outs["raised"]])
    assert [int(r[0]) for r in outs["raised"]] == [0] * 3
    np.testing.assert_allclose(got, numpy_forward(wide, x[:3]), rtol=0, atol=1e-9)


@pytest.mark.parametrize("fmi", [2, 3])
def test_the_fmu_sizes_its_build_from_the_model(wide, tmp_path, fmi):
    path = build_fmu(wide, tmp_path / "wide.fmu", fmi=fmi)
    config = zipfile.ZipFile(path).read("sources/fmu_config.h").decode()
    assert "#define DN_MAX_HIDDEN 90" in config
    test = generate("quick", seed=0).tests[4]
    k = slice(0, 1500)
    t, x, v, u = test.time[k] - test.time[0], test.channels["displacement"][k], test.channels["velocity"][k], test.control[k]
    a = np.gradient(v, t)
    sig = np.zeros(t.size, dtype=[("time", float)] + [(n, float) for n in ("x", "v", "a", "u")])
    sig["time"], sig["x"], sig["v"], sig["a"], sig["u"] = t, x, v, a, u
    dt = float(t[1] - t[0])
    res = simulate_fmu(str(path), start_time=0.0, stop_time=float(t[-1]), step_size=dt, output_interval=dt,
                       input=sig, output=["force", "status"])
    f, status, _ = damper_from_model(wide).forces(x, v, a, u, u, 20.0 + 0 * t)
    assert np.all(status >= 0) and np.all(res["status"] >= 0) and np.ptp(f) > 100.0
    # FMPy records the output at t_k with the inputs of t_k-1 (test_export_fmu.py)
    np.testing.assert_allclose(res["force"][1:], f[: len(res) - 1], rtol=0, atol=1e-9)


@pytest.mark.parametrize("single", [False, True])
@pytest.mark.parametrize("damper_eval", ["per_stage", "per_step"])
def test_the_loop_runs_an_average_of_copies_as_the_network_itself(repo_root, single, damper_eval):
    """The default network repeated 6 times with its output weights divided by 6 (180 neurons: the
    average `--average 6` of six identical restarts) is the same function: the quarter-car loop with
    on-off skyhook, whose damper evaluates it through the batched and the single forward, follows
    the one network's trajectory (to float rounding of the wider sums with `single`)."""
    from dampnet.training.ensemble import average_networks

    one = MlpModel.load(repo_root / "export" / "dn_model_default.json")
    six = average_networks([copy.deepcopy(one) for _ in range(6)])
    assert six.hidden == (180,)
    t = np.arange(3000) * 1e-3
    z = 0.03 * np.sin(2 * np.pi * 1.3 * t) + 0.01 * np.sin(2 * np.pi * 11.0 * t)
    v = np.gradient(z, t)
    states = []
    for m in (one, six):
        loop = _core.Loop(_core.LoopModel(damper_from_model(m, single=single), {"damper_eval": damper_eval},
                                          {"kind": "skyhook_onoff"}))
        forces = [loop.step(zk, vk)["force"] for zk, vk in zip(z, v)]
        states.append((np.array(loop.state), np.array(forces)))
    (s1, f1), (s6, f6) = states
    assert np.ptp(f1) > 100.0
    tol = 1e-4 if single else 1e-9  # of each quantity's range over the run
    np.testing.assert_allclose(f6, f1, rtol=0, atol=tol * np.ptp(f1))
    np.testing.assert_allclose(s6, s1, rtol=0, atol=tol * (np.abs(s1).max() + 1e-12))
