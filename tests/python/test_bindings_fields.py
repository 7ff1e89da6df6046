"""dict -> vehicle/controller in dampnet._core (issue 14, item 4).

Every enum field is parsed by its own name table: a name of another enum (controller kind
"per_step", integrator "skyhook_onoff") was accepted as that enum's value and ran the wrong
law or integrator. Wrong names, wrong types and unknown keys are errors naming the field.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dampnet import _core

ENUMS = {  # field -> (dict, {name: value}), from dampnet.h
    "kind": ("controller", {"passive": 0, "skyhook_onoff": 1, "skyhook_continuous": 2,
                            "groundhook_onoff": 3, "groundhook_continuous": 4, "external": 5,
                            "skyhook_force": 6, "groundhook_force": 7, "hybrid_force": 8, "clipped_optimal": 9}),
    "integrator": ("vehicle", {"rk4": 0, "semi_euler": 1}),
    "damper_eval": ("vehicle", {"per_stage": 0, "per_step": 1}),
    "accel_feature": ("vehicle", {"implicit": 0, "explicit": 1, "linear": 2}),
}
ALL_NAMES = sorted({n for _, names in ENUMS.values() for n in names})


def model(vehicle=None, controller=None):
    # a damper with a control: the force-tracking laws refuse one without (its inverse)
    return _core.LoopModel(_core.Damper.parametric(400.0, 3500.0, 1800.0, 40.0, 5.0), vehicle or {}, controller or {})


def given(field, value):
    where, _ = ENUMS[field]
    return model(**{where: {field: value}})


def read(m, field):
    return (m.controller if ENUMS[field][0] == "controller" else m.vehicle)[field]


@pytest.mark.parametrize("field", ENUMS)
def test_each_enum_field_takes_its_own_names_and_values(field):
    for name, value in ENUMS[field][1].items():
        assert read(given(field, name), field) == value
        assert read(given(field, value), field) == value
        assert read(given(field, np.int64(value)), field) == value


@pytest.mark.parametrize("field, name", [(f, n) for f in ENUMS for n in ALL_NAMES
                                         if n not in ENUMS[f][1]])
def test_a_name_of_another_enum_is_refused_naming_the_field_and_the_valid_names(field, name):
    with pytest.raises(ValueError) as e:
        given(field, name)
    msg = str(e.value)
    assert f"'{field}'" in msg and f"unknown name '{name}'" in msg
    for valid in ENUMS[field][1]:
        assert f"'{valid}'" in msg


@pytest.mark.parametrize("field", ENUMS)
@pytest.mark.parametrize("name", ["RK4", "skyhook", "per-step", "", "linear ", "\x00"])
def test_a_misspelled_name_is_refused(field, name):
    with pytest.raises(ValueError, match=f"'{field}': unknown name"):
        given(field, name)


@pytest.mark.parametrize("field", ENUMS)
@pytest.mark.parametrize("value", [1.0, None, True, [1], {"a": 1}, b"rk4", 2**70, -1, 99])
def test_a_value_of_the_wrong_type_or_range_is_refused(field, value):
    exc = ValueError if isinstance(value, int) and not isinstance(value, bool) else TypeError
    with pytest.raises(exc, match=f"'{field}'"):
        given(field, value)


def test_the_issue_examples_no_longer_run_another_law():
    # {"kind": "per_step"} ran on-off skyhook (value 1), integrator "skyhook_onoff" ran
    # semi-implicit Euler (value 1)
    with pytest.raises(ValueError, match="'kind': unknown name 'per_step'.*'passive'"):
        model(controller={"kind": "per_step"})
    with pytest.raises(ValueError, match="'integrator': unknown name 'skyhook_onoff'.*'rk4'"):
        model(vehicle={"integrator": "skyhook_onoff"})
    # {"kind": "linear"} (an accel_feature name, value 2) ran continuous skyhook
    with pytest.raises(ValueError, match="'kind': unknown name 'linear'.*'skyhook_continuous'"):
        model(controller={"kind": "linear"})


def test_the_name_tables_are_the_runtime_registries():
    # fields.hpp's tables and _core's registries both come from dampnet.h's lists
    for field, (_, names) in ENUMS.items():
        registry = {"kind": _core.CONTROLLER_KINDS, "integrator": _core.INTEGRATORS,
                    "damper_eval": _core.DAMPER_EVALS, "accel_feature": _core.ACCEL_FEATURES}[field]
        assert {n: v for n, (v, _) in registry.items()} == names


class BadFloat:
    def __float__(self):
        raise ArithmeticError("no float here")


NUMBER_FIELDS = [("vehicle", f) for f in _core.VEHICLE_FIELDS if f not in ENUMS] + \
                [("controller", f) for f in _core.CONTROLLER_FIELDS if f not in ENUMS]


@pytest.mark.parametrize("where, field", NUMBER_FIELDS)
@pytest.mark.parametrize("value", ["700", None, [1.0], {"v": 1.0}, True, b"1", BadFloat(), 1j])
def test_a_number_field_refuses_a_value_of_the_wrong_type(where, field, value):
    with pytest.raises(TypeError, match=f"{where} '{field}'.*expected a number"):
        model(**{where: {field: value}})


@pytest.mark.parametrize("where, field", NUMBER_FIELDS[:3] + NUMBER_FIELDS[-3:])
def test_a_number_field_takes_ints_floats_and_numpy_scalars(where, field):
    default = (model().vehicle if where == "vehicle" else model().controller)[field]
    for v in (default, float(default), np.float32(default), np.float64(default)):
        m = model(**{where: {field: v}})
        assert (m.vehicle if where == "vehicle" else m.controller)[field] == pytest.approx(default)


def test_a_number_too_large_for_a_double_is_refused_naming_the_field():
    with pytest.raises(ValueError, match="vehicle 'm_s'.*out of the range of a double"):
        model(vehicle={"m_s": 10**400})


def test_nonfinite_numbers_reach_the_runtime_check():
    with pytest.raises(ValueError, match="DN_E_NONFINITE_PARAM"):
        model(vehicle={"k_s": math.inf})


@pytest.mark.parametrize("where", ["vehicle", "controller"])
def test_unknown_and_non_string_keys_are_refused(where):
    with pytest.raises(ValueError, match=f"{where}: unknown parameter 'mass'; known: .*dt|c_sky"):
        model(**{where: {"mass": 1.0}})
    with pytest.raises(ValueError, match="unknown parameter 'Kind'"):
        model(**{where: {"Kind": "passive"}})
    with pytest.raises(TypeError, match=f"{where}: parameter names are strings, got int"):
        model(**{where: {3: 1.0}})


@pytest.mark.parametrize("vehicle, controller, named", [
    ({"dt": 1.0}, {}, "vehicle 'dt' = 1.0 (step [s], 1e-9 <= dt <= 0.1; stable:"),
    ({"m_s": -700.0, "dt": 1e-3}, {}, "vehicle 'm_s' = -700.0 (sprung mass [kg], > 0): DN_E_PARAM"),
    ({"k_t": math.nan}, {}, "vehicle 'k_t' = nan (tyre stiffness [N/m], > 0): DN_E_NONFINITE_PARAM"),
    ({}, {"kind": "skyhook_onoff", "c_sky": -1.0}, "controller 'c_sky' = -1.0 (skyhook damping"),
    ({}, {"u_min": 5.0, "u_max": 0.0}, "controller 'u_min' = 5.0 (lower control limit [V], <= u_max)"),
])
def test_an_out_of_range_value_names_its_field(vehicle, controller, named):
    # the runtime's status alone ("a parameter is out of its valid range") named no field
    with pytest.raises(ValueError) as e:
        model(vehicle, controller)
    assert named in str(e.value)


def test_messages_echo_at_most_a_short_part_of_a_long_or_invalid_name():
    for where, field in [("controller", "kind"), ("vehicle", "integrator")]:
        with pytest.raises(ValueError) as e:
            model(**{where: {field: "x" * 100_000}})
        assert len(str(e.value)) < 400 and "xxx..." in str(e.value)
        with pytest.raises(ValueError, match="not valid text"):
            model(**{where: {field: "rk4\ud800"}})
    with pytest.raises(ValueError) as e:
        model(vehicle={"y" * 100_000: 1.0})
    assert len(str(e.value)) < 400
