"""The runtime's registries as dampnet._core exposes them (issue 15, item 1).

Every name list is an X-macro in dampnet.h; _core expands it into a module attribute. These
tests hold each registry against what the runtime *does* (the loop model, the neural damper,
the step report, the callback's input), so a registry that drifts from the C code fails.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dampnet import _core

ENUM_REGISTRIES = {  # registry -> (dict, field of that dict it names)
    "CONTROLLER_KINDS": ("controller", "kind"),
    "INTEGRATORS": ("vehicle", "integrator"),
    "DAMPER_EVALS": ("vehicle", "damper_eval"),
    "ACCEL_FEATURES": ("vehicle", "accel_feature"),
}


def model(vehicle=None, controller=None):
    # a damper with a control: the force-tracking laws refuse one without (its inverse)
    return _core.LoopModel(_core.Damper.parametric(400.0, 3500.0, 1800.0, 40.0, 5.0), vehicle or {}, controller or {})


@pytest.mark.parametrize("registry", ENUM_REGISTRIES)
def test_enum_registries_are_name_to_value_and_doc_in_value_order_and_the_loop_agrees(registry):
    reg = getattr(_core, registry)
    where, field = ENUM_REGISTRIES[registry]
    values = [v for v, _ in reg.values()]
    assert values == sorted(values) and len(set(values)) == len(values)
    for name, (value, doc) in reg.items():
        assert isinstance(doc, str) and doc
        m = model(**{where: {field: name}})
        assert (m.controller if where == "controller" else m.vehicle)[field] == value
    # one past the last value is no value of the enum: the runtime refuses it
    with pytest.raises(ValueError, match=f"'{field}'"):
        model(**{where: {field: max(values) + 1}})


def test_the_other_enum_registries_match_the_runtime():
    assert {n: v for n, (v, _) in _core.DAMPER_KINDS.items()} == {
        "linear": _core.Damper.linear(1.0).kind,
        "parametric": _core.Damper.parametric(1.0, 2.0, 1.0, 0.0, 5.0).kind,
        "table": _core.Damper.table([0.0, 1.0], [0.0], [[0.0, 1.0]]).kind,
        "neural": _core.Damper.neural(tiny_mlp(1), ["velocity"]).kind,
        "callback": _core.Damper.callback(lambda i: 0.0).kind,
    }
    for name in _core.ACTIVATIONS:  # every listed activation builds an Mlp, nothing else does
        tiny_mlp(1, activation=name)
    with pytest.raises(ValueError, match=r"Mlp 'activation': unknown name .* for a dn_activation; valid: 'tanh' \(0\), 'sigmoid' \(1\)"):
        tiny_mlp(1, activation="relu")
    assert list(_core.PRECISIONS) == ["double", "float"]


def tiny_mlp(n_in, activation="tanh", w=None):
    """An Mlp whose output is y = sum_i w_i x_i exactly (one linear-enough hidden path is
    not needed: the output layer reads a hidden layer, so use w_out on a tiny w1 and undo
    the tanh slope: for |w1 x| << 1, tanh(z) = z to 1e-12)."""
    w = np.ones(n_in) if w is None else np.asarray(w, float)
    eps = 1e-6
    return _core.Mlp(w1=(eps * w)[None, :], b1=[0.0], w2=None, b2=None, w_out=[1 / eps], b_out=[0.0],
                     in_offset=np.zeros(n_in), in_gain=np.ones(n_in), in_ymin=0.0,
                     out_offset=0.0, out_gain=1.0, out_ymin=0.0,
                     sat_lo=-1e3 * np.ones(n_in), sat_hi=1e3 * np.ones(n_in), activation=activation)


def test_feature_registries_cover_every_feature():
    names = tuple(_core.FEATURE_NAMES)
    assert tuple(_core.FEATURE_INPUTS) == names and tuple(_core.FEATURE_PARAMS) == names
    assert set(_core.FEATURE_INPUTS.values()) <= set(_core.DAMPER_INPUT_FIELDS)
    needed = {p for p in _core.FEATURE_PARAMS.values() if p is not None}
    assert needed <= set(_core.FEATURE_PARAM_NAMES)
    for doc in _core.FEATURE_PARAM_NAMES.values():
        assert "[" in doc and "]" in doc  # states its unit
    # the ones the issue names, as the runtime defined them before the column existed
    assert _core.FEATURE_PARAMS["voltage_lag"] == "control_lag_tau_s"
    assert _core.FEATURE_PARAMS["current_lag"] == "control_lag_tau_s"
    assert _core.FEATURE_PARAMS["velocity_lag"] == "velocity_lag_tau_s"
    assert _core.FEATURE_PARAMS["friction_state"] == "friction_presliding_m"


@pytest.mark.parametrize("feature", list(_core.FEATURE_NAMES))
def test_a_neural_damper_needs_exactly_the_listed_parameter(feature):
    mlp = tiny_mlp(1)
    param = _core.FEATURE_PARAMS[feature]
    if param is None:
        _core.Damper.neural(mlp, [feature])
    else:
        with pytest.raises(ValueError, match="DN_E_PARAM"):
            _core.Damper.neural(mlp, [feature])
        _core.Damper.neural(mlp, [feature], {param: 0.01})
    for other in _core.FEATURE_PARAM_NAMES:  # any listed parameter is a known name
        _core.Damper.neural(mlp, [feature], {other: 0.01, **({param: 0.01} if param else {})})


@pytest.mark.parametrize("feature", list(_core.FEATURE_NAMES))
def test_a_neural_damper_reads_the_listed_input_field(feature):
    field = _core.FEATURE_INPUTS[feature]
    param = _core.FEATURE_PARAMS[feature]
    d = _core.Damper.neural(tiny_mlp(1), [feature], {param: 0.01} if param else {})
    # forces takes every quantity field by name (all but the loop's context t, dt, stage);
    # give each a distinct value
    quantities = [f for f in _core.DAMPER_INPUT_FIELDS if f not in ("t", "dt", "stage")]
    values = {q: 0.1 * (k + 1) for k, q in enumerate(quantities)}
    f, st, _ = d.forces(**{q: np.array([v]) for q, v in values.items()})
    assert st[0] == 0
    assert f[0] == pytest.approx(values[field], rel=1e-9)


def test_input_and_output_field_registries_match_the_objects():
    di = _core.DamperInput()
    for name, doc in _core.DAMPER_INPUT_FIELDS.items():
        assert hasattr(di, name) and "[" in doc
    loop = _core.Loop(model())
    report = loop.step(0.0, 0.0)
    assert list(report.keys()) == list(_core.STEP_OUTPUT_FIELDS)
    for name, doc in _core.STEP_OUTPUT_FIELDS.items():
        assert "[" in doc and getattr(report, name) is not None


# ---- check_vehicle / check_controller: the runtime's validation, naming the field ----

def test_check_functions_accept_the_defaults_and_return_none():
    assert _core.check_vehicle({}) is None and _core.check_controller({}) is None
    defaults = model()
    assert _core.check_vehicle(defaults.vehicle) is None
    assert _core.check_controller(defaults.controller) is None
    for kind in _core.CONTROLLER_KINDS:
        assert _core.check_controller({"kind": kind}) is None


@pytest.mark.parametrize("vehicle, named", [
    ({"dt": 1.0}, "vehicle 'dt' = 1.0 (step [s], 1e-9 <= dt <= 0.1; stable:"),
    ({"m_s": -700.0, "dt": 1e-3}, "vehicle 'm_s' = -700.0 (sprung mass [kg], > 0): DN_E_PARAM"),
    ({"k_t": math.nan}, "vehicle 'k_t' = nan (tyre stiffness [N/m], > 0): DN_E_NONFINITE_PARAM"),
    ({"m_s": -1.0, "m_us": -1.0}, "vehicle 'm_s' = -1.0 (sprung mass [kg], > 0)"),  # two bad
    ({"m_s": 1e-320}, "vehicle 'm_s' = 1e-320 (sprung mass [kg], > 0): DN_E_PARAM"),
])
def test_check_vehicle_names_the_field_and_its_range(vehicle, named):
    with pytest.raises(ValueError) as e:
        _core.check_vehicle(vehicle)
    assert named in str(e.value)


@pytest.mark.parametrize("controller, named", [
    ({"kind": "skyhook_onoff", "c_sky": -1.0}, "controller 'c_sky' = -1.0 (skyhook damping"),
    ({"u_min": 5.0, "u_max": 0.0}, "controller 'u_min' = 5.0 (lower control limit [V], <= u_max)"),
    ({"kind": "skyhook_continuous", "c_min": 5000.0}, "controller 'c_min' = 5000.0 (damping at u_soft"),
    ({"u_tau_s": -0.1}, "controller 'u_tau_s' = -0.1 (command filter time constant [s], >= 0"),
])
def test_check_controller_names_the_field_and_its_range(controller, named):
    with pytest.raises(ValueError) as e:
        _core.check_controller(controller)
    assert named in str(e.value)


@pytest.mark.parametrize("check, where, given, match", [
    (_core.check_controller, "controller", {"kind": "per_step"}, "'kind': unknown name 'per_step'"),
    (_core.check_controller, "controller", {"kind": "linear"}, "'kind': unknown name 'linear'"),
    (_core.check_vehicle, "vehicle", {"integrator": "skyhook_onoff"}, "'integrator': unknown name"),
    (_core.check_vehicle, "vehicle", {"mass": 1.0}, "unknown parameter 'mass'"),
])
def test_check_functions_parse_names_per_field(check, where, given, match):
    with pytest.raises(ValueError, match=match) as e:
        check(given)
    assert str(e.value).startswith(where)
    with pytest.raises(TypeError, match="expected a number"):
        check({"dt" if where == "vehicle" else "c_sky": "1"})


def test_check_functions_agree_with_loop_model_creation():
    # the same validation: on random vehicles and controllers, LoopModel is refused exactly
    # when check_vehicle or check_controller refuses, and with the same message when one does
    rng = np.random.default_rng(7)
    vdef, cdef = model().vehicle, model().controller
    kinds = list(_core.CONTROLLER_KINDS)
    outcomes = {"valid": 0, "one invalid": 0, "both invalid": 0}
    for _ in range(400):
        veh = {k: float(v) * rng.choice([1.0, -1.0, 0.0, 200.0]) for k, v in vdef.items()
               if k not in ENUM_FIELDS and rng.random() < 0.3}
        ctl = {k: float(v) * rng.choice([1.0, -1.0, 0.0, 3.0]) for k, v in cdef.items()
               if k not in ENUM_FIELDS and rng.random() < 0.3}
        ctl["kind"] = kinds[rng.integers(len(kinds))]
        errors = []
        for check, d in ((_core.check_vehicle, veh), (_core.check_controller, ctl)):
            try:
                assert check(d) is None
            except ValueError as e:
                errors.append(str(e))
        try:
            model(veh, ctl)
        except ValueError as e:
            assert errors, f"LoopModel refused what check_* accept: {e}"
            if len(errors) == 1:
                assert str(e) == "LoopModel: " + errors[0]
            outcomes["one invalid" if len(errors) == 1 else "both invalid"] += 1
        else:
            assert errors == [], f"check_* refused what LoopModel accepts: {errors}"
            outcomes["valid"] += 1
    assert min(outcomes.values()) >= 20, outcomes  # every outcome was exercised


ENUM_FIELDS = {"kind", "integrator", "damper_eval", "accel_feature"}


def test_check_functions_do_not_crash_on_hostile_input():
    for bad in (None, [], "x", 3, {1: 2}, {"dt": object()}):
        with pytest.raises((TypeError, ValueError)):
            _core.check_vehicle(bad)
        with pytest.raises((TypeError, ValueError)):
            _core.check_controller(bad)
