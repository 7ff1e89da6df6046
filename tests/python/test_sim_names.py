"""One spelling per control law, and the runtime's validation, on the Python side (issue 15).

The names, defaults and checks of the vehicle and controller are the runtime's
(dampnet._core's registries and check_vehicle / check_controller). A name of the wrong kind
(controller "per_step" or "linear", integrator "skyhook_onoff") or the old Python spelling
("skyhook", "groundhook") is an error naming the field and listing the valid names, through
QuarterCar, the Controller / Vehicle of dampnet.sim, a study's controllers and
`dampnet simulate --control`. The Python reference loop is the tests' oracle only.
"""

from __future__ import annotations

import ast
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest

import dampnet
from dampnet import _core
from dampnet.cli import main
from dampnet.sim.calibration import semi_active
from dampnet.sim.dampers import linear_spec
from dampnet.sim.quarter_car.loop import QuarterCar
from dampnet.sim.roads import impulse
from dampnet.sim.quarter_car.runs import simulate
from dampnet.sim.vehicle import VEHICLE_FIELDS_NOT_HERE, Controller, LoopError, Vehicle

LAWS = list(_core.CONTROLLER_KINDS)
PACKAGE = Path(dampnet.__file__).parent
WRONG_KINDS = ["per_step", "linear", "skyhook", "groundhook", "rk4", "Skyhook_onoff"]


def _names_all(msg: str, names) -> bool:
    return all(f"'{n}'" in msg for n in names)


@pytest.mark.parametrize("kind", WRONG_KINDS)
def test_quarter_car_refuses_a_wrong_law_name_naming_the_field_and_the_laws(kind):
    with pytest.raises(ValueError, match=f"'kind': unknown name '{kind}'") as e:
        QuarterCar(_core.Damper.linear(1500.0), controller={"kind": kind})
    assert _names_all(str(e.value), LAWS)


def test_quarter_car_refuses_a_law_name_as_the_integrator():
    with pytest.raises(ValueError, match="'integrator': unknown name 'skyhook_onoff'") as e:
        QuarterCar(_core.Damper.linear(1500.0), vehicle={"integrator": "skyhook_onoff"})
    assert _names_all(str(e.value), _core.INTEGRATORS)


@pytest.mark.parametrize("kind", WRONG_KINDS)
def test_a_run_with_a_wrong_law_name_is_refused_before_it_runs(kind):
    """The old Python spelling "skyhook" ran on-off skyhook through a mapping; now every
    spelling but the runtime's is an error from Controller, semi_active and a run."""
    with pytest.raises(LoopError, match=f"controller 'kind': unknown name '{kind}'") as e:
        Controller(kind=kind).validate()
    assert _names_all(str(e.value), LAWS)
    with pytest.raises(LoopError, match=f"'kind': unknown name '{kind}'"):
        semi_active(kind, {"low": 5.0, "high": 0.0})
    with pytest.raises(LoopError, match=f"'kind': unknown name '{kind}'"):
        simulate(linear_spec(1500.0), impulse(start_s=0.05, total_s=0.5), controller=Controller(kind=kind))


@pytest.mark.parametrize("law", [k for k in LAWS if k != "external"])
def test_every_runtime_law_runs_under_its_runtime_name(law):
    from dampnet.sim.dampers import load_spec

    # the embedded default model: a damper whose control sets its force (the force-tracking laws invert it)
    r = simulate(load_spec("default"), impulse(start_s=0.05, total_s=0.5),
                 controller=semi_active(law, {"low": 5.0, "high": 0.0}))
    assert r["controller"]["kind"] == law and np.isfinite(r["metrics"]["acc_rms_m_s2"])


@pytest.mark.parametrize("law", ["skyhook_force", "clipped_optimal"])
def test_a_force_tracking_law_refuses_a_damper_without_a_control(law):
    with pytest.raises(LoopError, match=f"'kind' = {_core.CONTROLLER_KINDS[law][0]} \\({law}\\) tracks a force through the "
                                        "damper's inverse.*no control"):
        simulate(linear_spec(1500.0), impulse(start_s=0.05, total_s=0.5), controller=semi_active(law, {"low": 5.0, "high": 0.0}))


def test_vehicle_accel_feature_takes_the_runtime_names_only():
    for name in _core.ACCEL_FEATURES:
        Vehicle(accel_feature=name).validate()
    with pytest.raises(LoopError, match="'accel_feature': unknown name 'skyhook_onoff'") as e:
        Vehicle(accel_feature="skyhook_onoff").validate()
    assert _names_all(str(e.value), _core.ACCEL_FEATURES)


@pytest.mark.parametrize("vehicle, controller, fragment", [
    # ranges the old Python re-implementation did not have (it accepted these)
    (dict(dt=1e-10), {}, "vehicle 'dt' = 1e-10 (step [s], 1e-9 <= dt <= 0.1; stable:"),
    ({}, dict(kind="skyhook_onoff", c_sky=-1.0), "controller 'c_sky' = -1.0 (skyhook damping [N s/m], >= 0)"),
    ({}, dict(c_gnd=-1.0), "controller 'c_gnd' = -1.0"),
    # and the ones it had, now in the runtime's words
    (dict(m_s=0.0), {}, "vehicle 'm_s' = 0.0 (sprung mass [kg], > 0)"),
    ({}, dict(u_min=3.0, u_max=1.0), "controller 'u_min' = 3.0 (lower control limit [V], <= u_max)"),
    ({}, dict(kind="skyhook_continuous", c_min=5000.0), "controller 'c_min' = 5000.0"),
])
def test_vehicle_and_controller_are_checked_by_the_runtime(vehicle, controller, fragment):
    with pytest.raises(LoopError) as e:
        Vehicle(**vehicle).validate()
        Controller(**controller).validate()
    assert fragment in str(e.value)


def test_vehicle_and_controller_fields_and_defaults_are_the_runtimes():
    ctrl = {f.name: f.default for f in fields(Controller)}
    assert list(ctrl) == list(_core.CONTROLLER_FIELDS)
    for name, (default, _) in _core.CONTROLLER_FIELDS.items():
        want = next(n for n, (v, _) in _core.CONTROLLER_KINDS.items() if v == default) if name == "kind" else default
        assert ctrl[name] == want, name
    veh = {f.name: f.default for f in fields(Vehicle)}
    assert set(veh) == set(_core.VEHICLE_FIELDS) - set(VEHICLE_FIELDS_NOT_HERE)
    for name in veh:
        default = _core.VEHICLE_FIELDS[name][0]
        if name == "f_static":
            assert veh[name] is None          # Python's extra: the damper's force at rest
        elif name == "accel_feature":
            assert _core.ACCEL_FEATURES[veh[name]][0] == default
        else:
            assert veh[name] == default, name


def _err_line(capsys, argv) -> str:
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("dampnet: error: ") and err.count("\n") == 1, err
    return err


@pytest.mark.parametrize("law", ["skyhook", "groundhook", "per_step", "linear", "external"])
def test_simulate_command_refuses_a_wrong_law_in_one_line_listing_the_laws(law, capsys, tmp_path):
    out = tmp_path / "run"
    err = _err_line(capsys, ["simulate", "linear:1500", "--road", "bump", "--control", law, "--out", str(out)])
    assert f"--control: '{law}'" in err
    assert _names_all(err, [k for k in LAWS if k != "external"])
    assert not out.exists()


def test_simulate_command_help_lists_the_runtime_laws(capsys):
    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert all(k in text for k in LAWS if k != "external")
    assert "groundhook," not in text and "skyhook," not in text


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            out.add(node.module)
            out.update(f"{node.module}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
    return out


def test_the_reference_loop_is_used_by_tests_only():
    users = [p.relative_to(PACKAGE) for p in PACKAGE.rglob("*.py")
             if p.name != "reference_loop.py" and any(m.startswith("dampnet.sim.quarter_car.reference_loop")
                                                       for m in _imports(p))]
    assert users == []


def test_only_sim_loop_drives_the_runtime_loop_and_commands_do_not_import_each_other():
    for p in [*(PACKAGE / "sim").rglob("*.py"), PACKAGE / "commands" / "simulate.py",
              PACKAGE / "commands" / "study.py"]:
        if p.name in ("loop.py", "reference_loop.py"):
            continue
        text = p.read_text()
        assert "_core.Loop(" not in text and "_core.LoopModel(" not in text, p
        assert not any(m.startswith("dampnet.commands") for m in _imports(p)), p


def test_the_reference_loop_refuses_what_it_does_not_mirror():
    from dampnet.sim.quarter_car.reference_loop import LinearDamper, run

    z = np.zeros(3)
    with pytest.raises(LoopError, match="accel_feature 'implicit' and 'explicit', not 'linear'"):
        run(LinearDamper(1500.0), z, z, Vehicle(accel_feature="linear"))
    with pytest.raises(LoopError, match="does not mirror the control law 'external'"):
        run(LinearDamper(1500.0), z, z, controller=Controller(kind="external"))
