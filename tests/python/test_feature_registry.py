"""The feature registry: the runtime's (dampnet.h via _core) plus Python's side (dampnet.features).

(a) Each derived feature and feature parameter is named, in code, only where the recipe
    says a feature lives: dampnet.h (the registry: its feature, parameter and damper-state
    rows). Everything else, features.py included (its derived features come from the damper
    states, _core.DAMPER_STATES), finds them in the registry.
(b) A feature defined only in features.py's registry (a second lag of velocity with its own
    time constant, registered here) reaches training, the C header, the reference loop and
    the diagnosis; the runtime, which reads its feature names from dampnet.h, refuses it
    with an error naming it (a runtime feature needs its dampnet.h line: the C/C++ side
    cannot learn a name at run time). Its reference-loop trajectory is the runtime's for
    the same model on the runtime's own velocity_lag (same time constant).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import numpy as np
import pytest

from dampnet import _core, features
from dampnet.features import FEATURES, Dahl, Lag, feature_matrix, first_order_lag
from dampnet.reference import mlp_forward

ROOT = Path(__file__).resolve().parents[2]

# -- the registry is the runtime's ---------------------------------------------------------


def test_python_registry_is_the_runtimes():
    assert list(FEATURES) == list(_core.FEATURE_NAMES)
    # Python's side lists the base features (channels) only, no stale line; the derived ones are
    # the features reading a damper state (tests/python/test_damper_state_registry.py)
    base = {f for f in _core.FEATURE_NAMES if _core.FEATURE_INPUTS[f] not in _core.DAMPER_STATES}
    assert set(features._PYTHON_SIDE) == base
    for name, f in FEATURES.items():
        assert (f.state is None) == (f.param is None), name  # a state needs its parameter
    assert features.feature_param_names() == dict(_core.FEATURE_PARAM_NAMES)


def test_every_runtime_feature_can_be_built_from_a_test():
    """A column for each runtime feature, on a test with every channel (units from the registry)."""
    from dampnet.data import DynoTest

    n, dt = 400, 1e-3
    t = np.arange(n) * dt
    ch = {"velocity": np.sin(20 * t), "displacement": -np.cos(20 * t) / 20, "voltage": np.where(t < 0.2, 1.0, 4.0),
          "current": np.full(n, 0.5), "temperature": np.full(n, 30.0), "force": np.zeros(n)}
    test = DynoTest(test_id="t", time=t, channels=ch)
    params = {p: 0.01 for p in _core.FEATURE_PARAM_NAMES}
    X = feature_matrix([test], list(_core.FEATURE_NAMES), params)
    assert X.shape == (n, len(_core.FEATURE_NAMES)) and np.all(np.isfinite(X))
    j = list(_core.FEATURE_NAMES).index("velocity_lag")
    np.testing.assert_array_equal(X[:, j], first_order_lag(ch["velocity"], dt, 0.01))
    with pytest.raises(Exception, match=r"needs feature_params\['velocity_lag_tau_s'\]"):
        feature_matrix([test], ["velocity_lag"], {})


def test_steady_inputs_are_the_derived_fields_the_runtime_damper_takes():
    """Every derived dn_damper_input field in steady state (a lag equals its input, the Dahl
    state sgn(v)), usable as Damper.forces's keyword arguments."""
    from loop_helpers import random_model

    from dampnet.sim.quarter_car.loop import damper_from_model

    x, v, u = np.array([0.01, -0.02, 0.0]), np.array([0.3, -0.5, 0.0]), np.array([1.0, 2.0, 3.0])
    got = features.steady_inputs(x, v, u)
    derived = {_core.FEATURE_INPUTS[f] for f in _core.FEATURE_NAMES if _core.FEATURE_PARAMS[f] is not None}
    assert set(got) == derived
    np.testing.assert_array_equal(got["u_lag"], u)
    np.testing.assert_array_equal(got["v_lag"], v)
    np.testing.assert_array_equal(got["z_fric"], np.sign(v))
    names = ["velocity", "voltage_lag", "velocity_lag", "friction_state"]
    model = random_model(names, feature_params={p: 0.01 for p in _core.FEATURE_PARAM_NAMES})
    f, status, _ = damper_from_model(model).forces(x=x, v=v, a=0 * x, u=u, temperature=20 + 0 * x, **got)
    np.testing.assert_allclose(f, mlp_forward(model, np.column_stack([v, u, v, np.sign(v)])), rtol=1e-12, atol=1e-9)


# -- (a) where the names are written ------------------------------------------------------------

#: where a derived feature's or a feature parameter's name may be written in code
ALLOWED = {
    "cpp/include/dampnet/dn_xmacro.h",  # the registry (dampnet.h's lists): DN_FEATURE_LIST, DN_FEATURE_PARAM_LIST, DN_DAMPER_STATE_LIST
    # before/after checks run against an older tree too: they name the features both trees know
    "bench/compare_loop_states.py",
    "bench/fullcar_bits.c",
}
#: not scanned: tests, the fuzzers' corpora (model files), the default model's files, data
SKIP_DIRS = {".git", ".venv", "build", "tests", "corpus", ".pytest_cache", ".benchmarks", "__pycache__"}
SUFFIXES = {".py", ".pyi", ".h", ".hpp", ".c", ".cc", ".cpp"}


def _python_strings(text: str) -> list[str]:
    """The str constants of a module (f-string parts included) except docstrings."""
    tree = ast.parse(text)
    docs = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                docs.add(id(first.value))
    return [n.value for n in ast.walk(tree)
            if isinstance(n, ast.Constant) and isinstance(n.value, str) and id(n) not in docs]


def _c_strings(text: str) -> list[str]:
    """The string literals of a C/C++ source outside comments."""
    lit = r'"(?:[^"\\\n]|\\.)*"'
    out = []
    for m in re.finditer(rf"{lit}|//[^\n]*|/\*.*?\*/|'(?:[^'\\\n]|\\.)*'", text, re.S):
        if m.group(0).startswith('"'):
            out.append(m.group(0))
    return out


def _code_strings(path: Path) -> list[str]:
    text = path.read_text(errors="replace")
    return _python_strings(text) if path.suffix in (".py", ".pyi") else _c_strings(text)


def _source_files():
    for p in sorted(ROOT.rglob("*")):
        rel = p.relative_to(ROOT)
        if p.suffix in SUFFIXES and p.is_file() and not SKIP_DIRS.intersection(rel.parts) \
                and rel.parts[0] != "export":
            yield rel.as_posix(), p


def test_the_scanner_sees_literals_not_comments_or_docstrings():
    assert _c_strings('/* "a" */ x = "b"; // "c"\n char q = \'"\'; y = "d\\"e";') == ['"b"', '"d\\"e"']
    assert _python_strings('"""doc"""\ndef f():\n    "doc2"\n    return "x" + f"{1}y"\n') == ["x", "y"]


def test_derived_features_and_their_parameters_are_named_only_in_the_registry():
    derived = [f for f in _core.FEATURE_NAMES if _core.FEATURE_PARAMS[f] is not None]
    names = derived + list(_core.FEATURE_PARAM_NAMES)
    assert "velocity_lag" in names and "friction_presliding_m" in names
    pattern = re.compile(r"(?<![A-Za-z0-9_])(" + "|".join(map(re.escape, names)) + r")(?![A-Za-z0-9_])")
    found = {}
    for rel, path in _source_files():
        hits = sorted({m.group(1) for s in _code_strings(path) for m in pattern.finditer(s)})
        if hits:
            found[rel] = hits
    assert "cpp/include/dampnet/dn_xmacro.h" in found  # the scan works
    outside = {rel: hits for rel, hits in found.items() if rel not in ALLOWED}
    assert not outside, f"derived-feature names written outside the registry: {outside}"


# -- (b) a feature defined only in features.py ----------------------------------------------------

NEW = "velocity_lag_slow"
NEW_PARAM = "velocity_lag_slow_tau_s"
TAU_S = 0.003


@pytest.fixture(scope="module")
def new_feature():
    f = features.register_feature(NEW, "m/s", Lag("velocity"), 0.0, param=NEW_PARAM,
                                  param_doc="time constant of velocity_lag_slow [s], > 0")
    yield f
    features.unregister_feature(NEW)
    assert NEW not in FEATURES and NEW_PARAM not in features.feature_param_names()


@pytest.fixture(scope="module")
def trained(new_feature):
    from dampnet import rig
    from dampnet.training.pipeline import train_dataset

    ds = rig.generate("quick", seed=1)
    model, _, _ = train_dataset(ds, ["velocity", NEW, "voltage"], hidden=(6,), holdout_voltage=None,
                                feature_params={NEW_PARAM: TAU_S}, max_epochs=40, seed=0)
    return model, ds


def test_registering_checks_its_input(new_feature):
    with pytest.raises(ValueError, match="runtime's"):
        features.register_feature("velocity_lag", "m/s", Lag("velocity"), 0.0, param="x_tau_s")
    with pytest.raises(ValueError, match="needs one"):
        features.register_feature("other_lag", "m/s", Lag("velocity"), 0.0)
    assert features.lags_of("velocity") == ["velocity_lag", NEW]
    assert features.with_state(Dahl) == ["friction_state"]


def test_training_builds_and_learns_the_new_feature(trained):
    from dampnet.predict import predict_force

    model, ds = trained
    assert model.features == ["velocity", NEW, "voltage"] and model.units[1] == "m/s"
    assert model.feature_params == {NEW_PARAM: TAU_S}
    test = ds.tests[4]
    lag = first_order_lag(test.channels["velocity"], test.dt, TAU_S)
    X = np.column_stack([test.channels["velocity"], lag, test.channels["voltage"]])
    np.testing.assert_array_equal(predict_force(model, test), model.predict(X))
    # it learned the damper: far better than the mean force
    f = np.concatenate([t.channels["force"] for t in ds.tests])
    pred = np.concatenate([predict_force(model, t) for t in ds.tests])
    assert np.sqrt(np.mean((pred - f) ** 2)) < 0.2 * np.std(f)


def test_the_header_carries_the_new_feature(trained):
    from dampnet.export import header_text

    text = header_text(trained[0])
    assert f'"{NEW}"' in text and f'"{NEW_PARAM}"' in text


def test_the_runtime_refuses_the_new_feature_naming_it(trained):
    """The runtime reads feature names from dampnet.h only: a name it lacks is DN_E_UNKNOWN_NAME,
    reported with the name and the runtime's features."""
    from dampnet.sim.quarter_car.loop import damper_from_model

    with pytest.raises(ValueError, match=rf"{NEW}.*velocity_lag"):
        damper_from_model(trained[0])
    with pytest.raises(ValueError, match=rf"feature '{NEW}' is registered only in Python.*velocity_lag"):
        features.check_runtime(trained[0].features)
    with pytest.raises(ValueError, match=rf"feature_params\['{NEW_PARAM}'\]: not a runtime"):
        features.check_runtime(["velocity"], trained[0].feature_params)
    features.check_runtime(list(_core.FEATURE_NAMES), {p: 1.0 for p in _core.FEATURE_PARAM_NAMES})


def test_the_reference_loop_feeds_it_as_the_runtime_feeds_velocity_lag(new_feature):
    """The same network on the new feature (Python loop) and on the runtime's velocity_lag with
    the same time constant (runtime loop): the same trajectory, so the new state is advanced
    with the runtime's exact update."""
    from loop_helpers import random_model

    from dampnet.sim.dampers import neural_spec
    from dampnet.sim.quarter_car.reference_loop import NeuralLoopDamper, run
    from dampnet.sim.roads import thesis_rough_road
    from dampnet.sim.quarter_car.runs import simulate
    from dampnet.sim.vehicle import Controller, Vehicle

    # seed 6: a random network that keeps the car on the road (seed 5's feeds energy in and leaves
    # the physical bounds at 8.4 s: DN_E_DIVERGED, as it should)
    twin = random_model(["velocity", "velocity_lag", "voltage"], seed=6, force_range=800.0,
                        feature_params={"velocity_lag_tau_s": TAU_S})
    model = random_model(["velocity", "velocity_lag", "voltage"], seed=6, force_range=800.0,
                         feature_params={NEW_PARAM: TAU_S})
    model.features[1] = NEW
    road, ctrl, veh = thesis_rough_road(), Controller(kind="skyhook_onoff"), Vehicle(accel_feature="explicit")
    a = simulate(neural_spec(twin), road, 20.0, ctrl, vehicle=veh)["arrays"]  # the runtime's loop
    s = road.sample(veh.dt, 20.0)
    b = run(NeuralLoopDamper(model), s.z, s.zdot, veh, ctrl)
    assert np.ptp(b["v"]) > 0.1  # the velocity moves, so its lag matters
    for k in ("z_s", "z_us", "acc_s", "force", "u"):
        np.testing.assert_allclose(b[k], a[k], rtol=0, atol=1e-9 * max(1.0, np.max(np.abs(a[k]))))


def test_the_diagnosis_runs_on_a_model_with_the_new_feature(trained):
    import dampnet
    from dampnet.diagnosis.context import build_context

    model, ds = trained
    ctx = build_context(model, ds, rows_per_test=100)
    td = ctx.tests[2]
    np.testing.assert_array_equal(td.X[:, 1], first_order_lag(td.test.channels["velocity"], td.test.dt, TAU_S))
    found = dampnet.diagnose(model, ds, n_surrogates=5, rows_per_test=100, ctx=ctx)
    assert isinstance(found, dict) and found
