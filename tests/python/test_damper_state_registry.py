"""Issue 30: the damper owns its states, and Python reads them from the same registry.

dampnet.h's DN_DAMPER_STATE_LIST (`_core.DAMPER_STATES`: unit, dynamics, source field,
parameter) and DN_STATE_DYNAMICS_LIST (`_core.STATE_DYNAMICS`) define the states; here:
(a) dampnet.features' derived features are those states (each runtime feature reading a
    damper state has the State its dynamics says, following the state's source, with the
    state's parameter; unit and value at rest by the stated rule), and the rule that picks a
    lag's base feature is checked on its own;
(b) the loop's state columns end with the damper's block, by name, in registry order;
(c) the Python reference loop's damper states equal the runtime loop's, state by state, with
    the parameters set (each state moving by its dynamics) and without them (a lag follows its
    source, the Dahl state stays at 0);
(d) the damper FMU's state variables and the demo's C rows come from the registry, and no
    damper state is spelled by hand in python/dampnet's code.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from dampnet import _core, features
from dampnet.features import DYNAMICS, FEATURES, Dahl, Lag

ROOT = Path(__file__).resolve().parents[2]

#: the runtime features whose dn_damper_input field is a damper state
DERIVED = [f for f in _core.FEATURE_NAMES if _core.FEATURE_INPUTS[f] in _core.DAMPER_STATES]


# -- (a) the features' states are the runtime's ------------------------------------------------


def test_every_kind_of_dynamics_has_its_python_twin():
    assert set(DYNAMICS) == set(_core.STATE_DYNAMICS)
    assert [v for v, _doc in _core.STATE_DYNAMICS.values()] == list(range(len(_core.STATE_DYNAMICS)))


def test_the_registry_rows_are_well_formed():
    for name, (unit, dyn, source, param, doc) in _core.DAMPER_STATES.items():
        assert name in _core.DAMPER_INPUT_FIELDS, name  # a state fills the input field of its name
        assert dyn in _core.STATE_DYNAMICS, name
        assert source in ("x", "v", "u"), name  # what every host knows over a step
        assert param in _core.FEATURE_PARAM_NAMES, name
        assert unit and doc, name
    assert {"u_lag", "v_lag", "z_fric"} <= set(_core.DAMPER_STATES)  # this build's three at least


def test_each_derived_feature_has_the_state_its_dynamics_says():
    assert DERIVED, "no runtime feature reads a damper state"
    for name in DERIVED:
        f = FEATURES[name]
        unit, dyn, source, param, _doc = _core.DAMPER_STATES[f.field]
        kind, held = DYNAMICS[dyn]
        assert isinstance(f.state, kind), (name, dyn, f.state)
        assert f.param == param == _core.FEATURE_PARAMS[name], name
        assert f.state.loop_input == source, (name, f.state.loop_input, source)
        if isinstance(f.state, Lag):
            assert f.state.held is held, name
            base = FEATURES[f.state.source]
            assert base.state is None and base.field == source, name  # a lag of the base feature reading its source
            assert f.unit == base.unit and f.at_rest == base.at_rest, name
            assert f.channel == base.channel
        else:
            assert f.unit == unit and f.at_rest is None, name
    # what this build's rows say, spelled out
    assert FEATURES["voltage_lag"].state == Lag("voltage", held=True) and FEATURES["voltage_lag"].unit == "V"
    assert FEATURES["current_lag"].state == Lag("current", held=True) and FEATURES["current_lag"].unit == "A"
    assert FEATURES["velocity_lag"].state == Lag("velocity") and FEATURES["velocity_lag"].at_rest == 0.0
    assert FEATURES["voltage_lag"].at_rest is None
    assert isinstance(FEATURES["friction_state"].state, Dahl) and FEATURES["friction_state"].at_rest is None
    assert FEATURES["friction_state"].unit == _core.DAMPER_STATES["z_fric"][0]


def test_python_lists_the_base_features_only():
    assert set(features._PYTHON_SIDE) == set(_core.FEATURE_NAMES) - set(DERIVED)
    assert list(FEATURES)[:len(_core.FEATURE_NAMES)] == list(_core.FEATURE_NAMES)


def test_damper_states_are_the_registry_block_in_order():
    got = features.damper_states()
    assert list(got) == list(_core.DAMPER_STATES)
    for field, (state, param) in got.items():
        assert param == _core.DAMPER_STATES[field][3]
        assert isinstance(state, DYNAMICS[_core.DAMPER_STATES[field][1]][0])
    assert set(features.steady_inputs(0.0, 0.0, 0.0)) == set(_core.DAMPER_STATES)


@pytest.mark.parametrize("name, source, base", [
    ("voltage_lag", "u", "voltage"),         # u is read by voltage and current: the name's prefix
    ("current_lag", "u", "current"),
    ("current_lag_fast", "u", "current"),
    ("velocity_lag", "v", "velocity"),       # one base feature reads v: that one
    ("damping_state", "v", "velocity"),      # whatever the derived feature's name
    ("displacement_lag", "x", "displacement"),
])
def test_a_lags_base_feature_reads_its_source_and_starts_its_name(name, source, base):
    assert features.base_feature(name, source) == base


@pytest.mark.parametrize("name, source, why", [
    ("valve_state", "u", "none of them starts its name"),  # voltage or current? the name must say
    ("control_lag", "u", "none of them starts its name"),
    ("time_lag", "t", "read by the base feature.s. none"),  # no base feature reads t
])
def test_a_lag_without_one_base_feature_is_refused_naming_the_rule(name, source, why):
    with pytest.raises(ValueError, match=why):
        features.base_feature(name, source)


# -- (b) the loop's state columns ------------------------------------------------------------------


def test_the_loop_state_ends_with_the_damper_block():
    from dampnet.sim.quarter_car.loop import S, STATE_NAMES

    k = len(_core.DAMPER_STATES)
    assert STATE_NAMES[-k:] == tuple(_core.DAMPER_STATES)
    assert list(_core.STATE_DOCS) == list(STATE_NAMES)
    assert all(S[name] == STATE_NAMES.index(name) for name in STATE_NAMES)
    for corner in _core.FULLCAR_CORNERS:
        per = [n for n in _core.FULLCAR_STATE_NAMES if n.endswith(f"_{corner}")]
        assert per[-k:] == [f"{name}_{corner}" for name in _core.DAMPER_STATES], corner


# -- (c) the reference loop's update is the runtime's --------------------------------------------

ALL = {"control_lag_tau_s": 0.02, "velocity_lag_tau_s": 0.004, "friction_presliding_m": 5e-4}


@pytest.mark.parametrize("names, params", [
    (["velocity", "voltage_lag", "velocity_lag", "friction_state"], ALL),  # every state moving
    (["velocity", "voltage"], {}),  # none set: the lags follow their sources, the Dahl state stays
], ids=["parameters", "defaults"])
def test_the_reference_loops_damper_states_are_the_runtimes(names, params):
    from loop_helpers import random_model

    from dampnet.sim.dampers import neural_spec
    from dampnet.sim.quarter_car.reference_loop import NeuralLoopDamper, run
    from dampnet.sim.roads import thesis_rough_road
    from dampnet.sim.quarter_car.runs import simulate
    from dampnet.sim.vehicle import Controller, Vehicle

    model = random_model(names, seed=6, force_range=800.0, feature_params=params)
    road, veh = thesis_rough_road(), Vehicle(accel_feature="explicit")
    ctrl = Controller(kind="skyhook_onoff")  # the control switches: its lag moves
    speed, duration = 20.0, 4.0
    s = road.sample(veh.dt, speed)
    n = min(s.z.size, int(round(duration / veh.dt)) + 1)
    py = run(NeuralLoopDamper(model), s.z[:n], s.zdot[:n], veh, ctrl)
    rt = simulate(neural_spec(model), road, speed, ctrl, vehicle=veh)["arrays"]
    m = py["t"].size
    for name in _core.DAMPER_STATES:
        a, b = rt[name][:m], py[name]
        # the runtime's Dahl update takes the travel from x with x_static: ~1 ulp apart
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-9 * max(1.0, float(np.max(np.abs(a)))), err_msg=name)
    for k in ("z_s", "z_us", "force", "u"):
        np.testing.assert_allclose(py[k], rt[k][:m], rtol=0, atol=1e-9 * max(1.0, float(np.max(np.abs(rt[k])))))
    if params:
        assert np.ptp(py["u_lag"]) > 0.1 and np.ptp(py["v_lag"]) > 0.01 and np.ptp(py["z_fric"]) > 1.0
        assert not np.allclose(py["u_lag"], py["u"])  # lagged
    else:
        # the control's "lag" is the control held over the last step (at rest at the first)
        np.testing.assert_array_equal(py["u_lag"], np.concatenate([py["u"][:1], py["u"][:-1]]))
        np.testing.assert_array_equal(py["v_lag"], py["v"])
        np.testing.assert_array_equal(py["z_fric"], 0.0)


# -- (d) the hosts' names come from the registry -------------------------------------------------


def test_the_damper_fmus_states_are_the_registry_block():
    from loop_helpers import random_model

    from dampnet.export.fmu.damper import STATES, VR_DERIV, VR_STATE, damper_variables

    assert [(name, k) for name, k, _doc in STATES] == [(name, k) for k, name in enumerate(_core.DAMPER_STATES)]
    # one feature reading each damper state (the control's lag through current_lag: the control is
    # a current here), from the registry: a state added by dn_xmacro.h's recipe is in the model too
    per_state = {}
    for f in DERIVED:
        if f != "voltage_lag":
            per_state.setdefault(_core.FEATURE_INPUTS[f], f)
    assert set(per_state) == set(_core.DAMPER_STATES)
    model = random_model(["velocity", *per_state.values(), "current"], feature_params=ALL)
    vs = {v.name: v for v in damper_variables(model)}
    for k, name in enumerate(_core.DAMPER_STATES):
        assert vs[name].vr == VR_STATE + k and vs[f"der({name})"].vr == VR_DERIV + k
    assert (vs["u_lag"].unit, vs["der(u_lag)"].unit) == ("A", "A/s")  # the model's control unit
    assert (vs["v_lag"].unit, vs["der(v_lag)"].unit) == ("m/s", "m/s2")
    assert (vs["z_fric"].unit, vs["der(z_fric)"].unit) == (None, "1/s")
    # only the states the model reads
    vs = {v.name for v in damper_variables(random_model(["velocity", "velocity_lag"], feature_params=ALL))}
    assert {n for n in vs if n in _core.DAMPER_STATES} == {"v_lag"}


def test_the_c_programs_rows_are_the_damper_forces_quantities():
    """controller.c reads DN_DAMPER_INPUT_FIELDS' quantities (QTY, QTY_OPT); cprogram.ROW_FIELDS are
    the fields the runtime's features read: the same list as Damper.forces's arguments."""
    from dampnet.demo.cprogram import ROW_FIELDS

    sig = (_core.Damper.forces.__doc__ or "").splitlines()[0]
    args = re.findall(r"(\w+): ", sig.split("(", 1)[1])
    assert args[0] == "self"
    assert tuple(args[1:]) == ROW_FIELDS
    assert set(_core.DAMPER_STATES) <= set(ROW_FIELDS)


def _python_strings(path: Path) -> list[str]:
    from test_feature_registry import _python_strings

    return _python_strings(path.read_text())


def test_no_damper_state_is_spelled_in_python_dampnets_code():
    """python/dampnet reads the damper's states from _core.DAMPER_STATES: none of their names is
    a string constant of its code (docstrings aside)."""
    pattern = re.compile(r"(?<![A-Za-z0-9_])(" + "|".join(map(re.escape, _core.DAMPER_STATES)) + r")(?![A-Za-z0-9_])")
    found = {}
    for path in sorted((ROOT / "python" / "dampnet").rglob("*.py")):
        hits = sorted({m.group(1) for s in _python_strings(path) for m in pattern.finditer(s)})
        if hits:
            found[path.relative_to(ROOT).as_posix()] = hits
    assert not found, f"damper state names written by hand: {found}"
