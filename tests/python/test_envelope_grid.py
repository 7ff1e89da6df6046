"""The training envelope's bounded-time check (dampnet.h "Training envelope", dampnet::Envelope,
dampnet.envelope.grid): the C++ check against a numpy reference written here from the header's
definition, the grid of a quick-plan model against the k-d tree measure (training data inside,
the held-out control level and the quarter-car impulse outside), refusals, a C program built from
the exported header, and the FMUs' envelope_flags output against the runtime's flags."""

from __future__ import annotations

import dataclasses
import subprocess

import numpy as np
import pytest

import fmi2_callbacks
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave

from cbuild import compile_program
from dampnet import _core, paths
from dampnet.cli import main
from dampnet.envelope import Envelope, build_envelope
from dampnet.envelope.grid import grid_cells, pairs, runtime_flags
from dampnet.export import write_header
from dampnet.features import feature_matrix
from dampnet.modeldir import save_model_dir
from dampnet.sim.calibration import damping_levels
from dampnet.sim.dampers import neural_spec
from dampnet.sim.quarter_car.loop import QuarterCar, damper_from_model
from dampnet.sim.roads import impulse
from dampnet.sim.quarter_car.runs import simulate
from dampnet.sim.vehicle import Controller
from loop_helpers import random_model

CELLS = 32  # dampnet.h's DN_ENVELOPE_CELLS, as the header documents it
FEATURES3 = ["velocity", "acceleration", "voltage"]


def reference_flags(lo, hi, cells, X):
    """dampnet.h's definition, point by point: outside a range (or NaN) -> bit 0; else a pair's
    cell (floor((x - lo) * s), s = 32 / (hi - lo) computed first, the last cell at x = hi)
    unmarked -> bit 1."""
    n = len(lo)
    out = []
    for x in X:
        flags, c = 0, []
        for i in range(n):
            if not (lo[i] <= x[i] <= hi[i]):
                flags |= 1
                c.append(None)
            else:
                c.append(min(int(np.floor((x[i] - lo[i]) * (CELLS / (hi[i] - lo[i])))), CELLS - 1))
        p = 0
        for i in range(n):
            for j in range(i + 1, n):
                if c[i] is not None and c[j] is not None:
                    bit = c[i] * CELLS + c[j]
                    if not (int(cells[p, bit // 32]) >> (bit % 32)) & 1:
                        flags |= 2
                p += 1
        out.append(flags)
    return np.array(out, dtype=np.uint32)


def test_check_against_the_header_definition():
    assert _core.ENVELOPE_CELLS == CELLS and _core.ENVELOPE_PAIR_WORDS == CELLS * CELLS // 32
    rng = np.random.default_rng(3)
    for n in (1, 2, 4, 8):
        lo = rng.uniform(-2, 0, n)
        hi = lo + rng.uniform(0.1, 3, n)
        n_pairs = n * (n - 1) // 2
        # each cell unmarked with probability 0.7 / n_pairs: inside and outside points both common
        marked = rng.random((n_pairs, CELLS * CELLS)) > 0.7 / max(n_pairs, 1)
        weights = (2 ** np.arange(32, dtype=np.uint64))
        cells = (marked.reshape(n_pairs, 32, 32).astype(np.uint64) * weights).sum(-1).astype(np.uint32)
        X = rng.uniform(lo - 0.2 * (hi - lo), hi + 0.2 * (hi - lo), size=(400, n))
        X[:5] = lo  # the edges: lo in the first cell, hi in the last
        X[5:10] = hi
        X[10, 0], X[11, -1], X[12, 0] = np.nan, np.inf, -np.inf
        env = _core.Envelope(lo, hi, cells)
        assert env.n_inputs == n
        got = env.check(X)
        np.testing.assert_array_equal(got, reference_flags(lo, hi, cells, X))
        assert got[10] & 1 and got[11] & 1 and got[12] & 1
        if n > 1:
            assert np.any(got == 2) and np.any(got == 0)  # both outcomes inside the ranges occur


def test_grid_cells_against_loops_over_the_samples():
    """grid_cells' bitmaps: each stored sample's cell and the 8 around it (inside the grid) marked,
    bit ci * 32 + cj of the pair's words, written here with plain loops."""
    lo, hi = np.array([0.0, -2.0, 1.0]), np.array([1.0, 2.0, 6.0])
    rng = np.random.default_rng(5)
    x = rng.uniform(lo, hi, size=(40, 3))
    x[0] = lo  # the corners: the dilation must not wrap around
    x[1] = hi
    gain = 2.0 / (hi - lo)
    env = Envelope(FEATURES3, ["m/s", "m/s^2", "V"], lo, hi, lo, gain, -1.0, (x - lo) * gain - 1.0, 0.1)
    expected = np.zeros((3, 32), dtype=np.uint32)
    for p, (i, j) in enumerate([(0, 1), (0, 2), (1, 2)]):
        marked = set()
        for row in x:
            ci = min(int(np.floor((row[i] - lo[i]) * (32 / (hi[i] - lo[i])))), 31)
            cj = min(int(np.floor((row[j] - lo[j]) * (32 / (hi[j] - lo[j])))), 31)
            marked |= {(a, b) for a in range(ci - 1, ci + 2) for b in range(cj - 1, cj + 2)
                       if 0 <= a < 32 and 0 <= b < 32}
        for a, b in marked:
            bit = a * 32 + b
            expected[p, bit // 32] |= np.uint32(1 << (bit % 32))
    np.testing.assert_array_equal(grid_cells(env), expected)


def test_bad_descriptions_are_refused():
    ok = np.zeros((1, 32), np.uint32)
    with pytest.raises(ValueError, match="DN_E_PARAM"):
        _core.Envelope([0.0, 1.5], [1.0, 1.0], ok)  # hi < lo
    with pytest.raises(ValueError, match="DN_E_PARAM"):
        _core.Envelope([-1e308, 0.0], [1e308, 1.0], ok)  # a width beyond double
    with pytest.raises(ValueError, match="DN_E_NONFINITE_PARAM"):
        _core.Envelope([np.nan, 0.0], [1.0, 1.0], ok)
    with pytest.raises(ValueError, match=r"cells must be \[1, 32\]"):
        _core.Envelope([0.0, 0.0], [1.0, 1.0], np.zeros((2, 32), np.uint32))
    with pytest.raises(ValueError, match="1..8 values"):
        _core.Envelope(np.zeros(9), np.ones(9), np.zeros((36, 32), np.uint32))
    env = _core.Envelope([0.0, 0.0], [1.0, 1.0], ok)
    with pytest.raises(ValueError, match=r"x must be 2-D \[n_points, 2\]"):
        env.check(np.zeros((3, 3)))
    with pytest.raises(TypeError, match="never initialised"):
        _core.Envelope.__new__(_core.Envelope).check(np.zeros((1, 2)))


@pytest.fixture(scope="module")
def trained(quick_envelope_model):
    return quick_envelope_model


def test_grid_of_a_model_follows_its_training_data(trained):
    model, env, split = trained["model"], trained["env"], trained["split"]
    cells = grid_cells(env)
    assert cells.shape == (len(pairs(3)), 32) and cells.dtype == np.uint32
    # every stored training sample's own cell is marked: the stored samples are all inside (mapped
    # back from the scaled space and held to the box: the sample at a box edge comes back an ulp
    # outside it, 9.074996130000001 for a hi of 9.07499613, which the box check rightly flags)
    back = (env.points - env.in_ymin) / env.in_gain + env.in_offset
    assert np.all(np.abs(np.clip(back, env.lo, env.hi) - back) <= 1e-12 * (env.hi - env.lo))
    assert not np.any(runtime_flags(env, np.clip(back, env.lo, env.hi)))
    # the training tests at the full 5 kHz rate (between the stored samples): inside
    X = np.concatenate([feature_matrix([t], model.features, model.feature_params) for t in split.train.tests])
    assert np.mean(runtime_flags(env, X) != 0) < 0.005
    # the held-out control level lies between two training levels: outside, as the k-d measure says
    Xh = np.concatenate([feature_matrix([t], model.features, model.feature_params) for t in split.holdout.tests])
    flags = runtime_flags(env, Xh)
    assert np.mean(flags == _core.ENV_OUTSIDE_JOINT) > 0.95
    assert np.mean(env.distance(Xh) > env.threshold) > 0.95


def test_impulse_flags_agree_with_the_offline_measure(trained):
    model, env = trained["model"], trained["env"]
    spec = neural_spec(model, envelope=env)
    run = simulate(spec, impulse(), None, Controller(kind="passive", u_passive=damping_levels(spec)["low"]))
    rt, cov = run["coverage"]["runtime_flag"], run["coverage"]
    flags = runtime_flags(env, run["arrays"]["features"])
    assert rt["share_steps_outside"] == pytest.approx(np.mean(flags != 0))
    # measured 0.279 flagged against 0.278 outside, agreeing on 99.2 % of steps (quick plan, 30 epochs)
    assert rt["share_steps_outside"] == pytest.approx(cov["outside"]["share_steps"], abs=0.05)
    assert rt["agreement_steps"] > 0.95


def test_c_program_from_the_exported_header(trained, tmp_path):
    """The header's P_ENVELOPE_DESC_INIT through the C ABI gives Python's flags."""
    model, env = trained["model"], trained["env"]
    write_header(model, tmp_path / "model.h", "dn_model", envelope=env)
    rng = np.random.default_rng(0)
    X = rng.uniform(model.sat_lo - 0.1 * (model.sat_hi - model.sat_lo),
                    model.sat_hi + 0.1 * (model.sat_hi - model.sat_lo), size=(2000, 3))
    np.savetxt(tmp_path / "points.txt", X, fmt="%.17g")
    (tmp_path / "main.c").write_text("""
#include <stdio.h>
#include "dampnet/dampnet.h"
#include "model.h"
int main(void) {
  dn_envelope_desc d = DN_MODEL_ENVELOPE_DESC_INIT;
  dn_envelope* e = NULL;
  int st = dn_envelope_create(&d, &e);
  if (st != DN_OK) { printf("create %d\\n", st); return 1; }
  double x[3];
  while (scanf("%lf %lf %lf", &x[0], &x[1], &x[2]) == 3) {
    uint32_t flags = 99;
    if (dn_envelope_check(e, x, &flags) != DN_OK) return 2;
    printf("%u\\n", (unsigned)flags);
  }
  dn_envelope_destroy(e);
  return 0;
}
""")
    exe = compile_program([tmp_path / "main.c"], tmp_path / "env_c", cxx=False,
                          include_dirs=paths.include_dirs() + [tmp_path], libs=[paths.shared_library()])
    out = subprocess.run([str(exe)], stdin=open(tmp_path / "points.txt"), capture_output=True, text=True,
                         check=True).stdout.split()
    got = np.array([int(v) for v in out], dtype=np.uint32)
    np.testing.assert_array_equal(got, runtime_flags(env, X))
    assert {0, 1, 2} <= set(got)


def test_a_constant_input_is_one_cell(tmp_path):
    """A model trained at one voltage (sat_lo = sat_hi = 5 V): its envelope, its grid, the runtime
    check and the FMU (with and without the envelope) all work; off 5 V is outside the range."""
    base = random_model(FEATURES3, hidden=6, seed=2)
    lo, hi = base.sat_lo.copy(), base.sat_hi.copy()
    lo[2] = hi[2] = 5.0
    model = dataclasses.replace(base, sat_lo=lo, sat_hi=hi)
    rng = np.random.default_rng(1)
    t = np.linspace(0, 2, 4000)
    X = np.stack([0.3 * np.sin(2 * np.pi * t), 0.3 * 2 * np.pi * np.cos(2 * np.pi * t), np.full(t.size, 5.0)], 1)
    env = build_envelope(model, X)
    assert not np.any(runtime_flags(env, X))
    probe = np.concatenate([X[::50], X[::50] * [1, 1, 0.98], rng.uniform(lo, hi, (50, 3))])
    flags = runtime_flags(env, probe)
    assert np.all(flags[80:160] == _core.ENV_OUTSIDE_RANGE) and np.any(flags[160:] == _core.ENV_OUTSIDE_JOINT)
    save_model_dir(model, {}, tmp_path / "m", envelope=env)
    for name, args in (("grid", []), ("ranges", ["--force"])):
        if name == "ranges":
            save_model_dir(model, {}, tmp_path / "m", force=True)  # no envelope this time
        assert main(["export", str(tmp_path / "m"), "--fmu", str(tmp_path / f"{name}.fmu")]) == 0
        got, _ = _drive_flags(tmp_path / f"{name}.fmu", np.zeros(len(probe)), probe[:, 0], probe[:, 1], probe[:, 2])
        expect = runtime_flags(env, probe)
        np.testing.assert_array_equal(got, expect if name == "grid" else expect & _core.ENV_OUTSIDE_RANGE)


def _drive_flags(path, x, v, a, u):
    """The FMU's envelope_flags at each point, read after setting that point's inputs."""
    md = read_model_description(str(path))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(path)),
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="damper")
    vr = {sv.name: sv.valueReference for sv in md.modelVariables}
    cb = fmi2_callbacks.callbacks()  # not FMPy's defaults (fmi2_callbacks); alive until freed
    fmu.instantiate(callbacks=cb)
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    flags = np.empty(len(x), dtype=np.uint32)
    for k in range(len(x)):
        fmu.setReal([vr["x"], vr["v"], vr["a"], vr["u"]], [x[k], v[k], a[k], u[k]])
        flags[k] = fmu.getInteger([vr["envelope_flags"]])[0]
        fmu.doStep(k * 1e-3, 1e-3)
    fmu.terminate()
    fmu.freeInstance()
    return flags, md


def test_damper_fmu_reports_the_runtime_flags(trained, tmp_path, capsys):
    model, env, root = trained["model"], trained["env"], trained["root"]
    assert main(["export", str(root / "model"), "--fmu", str(tmp_path / "d.fmu")]) == 0
    assert "envelope_flags from the training envelope's grid" in capsys.readouterr().out
    # inputs inside the training data, between control levels, and far beyond the ranges
    test = trained["split"].train.tests[1]
    X = feature_matrix([test], model.features, model.feature_params)[::40]
    Xh = feature_matrix([trained["split"].holdout.tests[0]], model.features, model.feature_params)[::40]
    X = np.concatenate([X, Xh, X[:20] * 5.0])
    fmu_flags, md = _drive_flags(tmp_path / "d.fmu", np.zeros(len(X)), X[:, 0], X[:, 1], X[:, 2])
    np.testing.assert_array_equal(fmu_flags, runtime_flags(env, X))
    assert {0, 1, 2} <= set(fmu_flags)
    doc = next(sv for sv in md.modelVariables if sv.name == "envelope_flags").description
    assert "not computed" not in doc
    # exported without the envelope: the training ranges only (bit 1 never set)
    save_model_dir(model, {}, tmp_path / "bare")
    assert main(["export", str(tmp_path / "bare"), "--fmu", str(tmp_path / "b.fmu")]) == 0
    assert "training ranges only" in capsys.readouterr().out
    bare, md = _drive_flags(tmp_path / "b.fmu", np.zeros(len(X)), X[:, 0], X[:, 1], X[:, 2])
    np.testing.assert_array_equal(bare, runtime_flags(env, X) & _core.ENV_OUTSIDE_RANGE)
    assert "not computed" in next(sv for sv in md.modelVariables if sv.name == "envelope_flags").description


def test_quarter_car_fmu_reports_the_flags_of_its_damper_inputs(trained, tmp_path):
    """The quarter car's envelope_flags at each communication point: the runtime's flags of the
    loop's damper inputs there (QuarterCar.simulate's features on the same road: a 4 cm bump)."""
    from test_export_fmu_quarter_car import DT, road_signal

    model, env, root = trained["model"], trained["env"], trained["root"]
    assert main(["export", str(root / "model"), "--fmu", str(tmp_path / "q.fmu"), "--what", "quarter-car"]) == 0
    t = np.arange(1500) * DT
    bump = (t > 0.2) & (t < 0.3)
    z = np.where(bump, 0.02 * (1 - np.cos(2 * np.pi * (t - 0.2) / 0.1)), 0.0)
    zd = np.where(bump, 0.02 * 2 * np.pi / 0.1 * np.sin(2 * np.pi * (t - 0.2) / 0.1), 0.0)
    ref = QuarterCar(damper_from_model(model)).simulate(z, zd)
    res = simulate_fmu(str(tmp_path / "q.fmu"), start_time=0.0, stop_time=(z.size - 1) * DT, step_size=DT,
                       output_interval=DT, input=road_signal(z, zd), output=["envelope_flags", "force"],
                       fmi_type="CoSimulation")
    np.testing.assert_allclose(res["force"], ref["force"], rtol=0, atol=1e-9)
    expect = runtime_flags(env, ref["features"])
    np.testing.assert_array_equal(np.asarray(res["envelope_flags"], dtype=np.uint32), expect)
    assert np.any(expect != 0) and np.any(expect == 0)
