"""The control study (issue 55 item 3, dampnet.recipes.control_study): its ideal references
against independent results. The ideal active car (lsim over the road) against the analytic RMS
from the ISO 8608 PSD and the car's frequency response; the ideal semi-active damper (a lookup
table F = u) giving exactly the law's clipped demand; one road and speed's table on a short road;
`dampnet study --control`. Cost: about 15 s."""

from __future__ import annotations

import numpy as np
import pytest

from dampnet.recipes import control_laws
from dampnet.recipes import roads as road_recipes
from dampnet.sim.dampers import load_spec
from dampnet.recipes import control_study as cs
from dampnet.sim.quarter_car.runs import simulate
from dampnet.sim.roads.profiles import ISO_BAND, ISO_CLASSES
from dampnet.sim.vehicle import Vehicle


@pytest.fixture(scope="module")
def spec():
    return load_spec("default")


@pytest.mark.parametrize("law", ["hybrid_force", "clipped_optimal"])
def test_ideal_active_equals_the_analytic_rms_from_the_road_psd(spec, law):
    """A 2 km ISO C road at 80 km/h: the Wk-weighted body acceleration RMS of the exact linear
    solution is within 3 % of sqrt(integral |W_k H_a|^2 G df) (measured -0.25 % and -0.44 %, printed: the road
    realisation's own spread). (skyhook_force and groundhook_force alone leave a mode
    undamped - no passive damper beside the actuator - so the integral has no finite value.)"""
    veh = Vehicle()
    ctrl = control_laws.make(law, spec, veh)
    v = 80.0 / 3.6
    road = road_recipes.build("iso:class=C,length_m=2000", seed=1, speed_m_s=v)
    s = road.sample(veh.dt, speed=v)
    t = np.arange(len(s.z)) * veh.dt
    sim = cs.ideal_active(veh, ctrl, t, np.asarray(s.z), np.asarray(s.zdot))["metrics"]["acc_wk_rms_m_s2"]
    ana = cs.ideal_active_analytic(veh, ctrl, ISO_CLASSES["C"], v, ISO_BAND)
    print(f"{law}: ideal active Wk RMS {sim:.4f} m/s^2 (lsim) against {ana:.4f} (PSD), {100 * (sim / ana - 1):+.2f} %")
    assert sim == pytest.approx(ana, rel=0.03), (sim, ana)


@pytest.mark.parametrize("law", cs.FORCE_LAWS)
def test_the_ideal_semi_active_damper_gives_the_clipped_demand(spec, law):
    """On the ideal table damper (F = u) each step's force is the law's demand at the step start
    (the runtime's force_demand, clipped to F v > 0), to 1e-6 N; and the ideal active car's
    feedback row K x is that demand wherever the clip passes it (hybrid_force: both parts
    dissipating), to 1e-9 of it."""
    veh = Vehicle()
    ctrl = cs.ideal_controller(control_laws.make(law, spec, veh))
    road = road_recipes.build("iso:class=C,length_m=60", seed=0, speed_m_s=20.0)
    res = simulate(cs.ideal_spec(), road, 20.0, ctrl, veh, law=law)
    a = res["arrays"]
    fd = cs.demand(ctrl, a)
    assert res["f_static_n"] == 0.0
    assert (fd != 0).mean() > 0.2 and (fd == 0).mean() > (0.0 if law == "hybrid_force" else 0.05)
    np.testing.assert_allclose(a["force"], fd, rtol=0, atol=1e-6)
    vs, vus = a["v_s"], a["v_us"]
    v = vs - vus
    kx = np.column_stack([a["z_s"] - a["z_us"], vs, a["z_us"] - a["z_r"], vus]) @ cs.feedback_row(ctrl)
    passes = kx * v > 0
    if law == "hybrid_force":
        passes &= (vs * v > 0) & (-vus * v > 0)
    assert passes.mean() > 0.05
    np.testing.assert_allclose(kx[passes], fd[passes], rtol=1e-9)


def test_one_case_of_the_table(spec):
    """ISO C at 80 km/h on a 100 m road, skyhook_force: every metric finite, the hard passive
    setting rougher than the soft one (Wk), the ideal semi-active skyhook smoother than passive
    low, the tracking shares within [0, 1]."""
    r = cs.quarter_car_case(spec, "C", 80.0, laws=("skyhook_force",), length_m=100.0)
    assert r["passive_high"]["wk_rms_m_s2"] > r["passive_low"]["wk_rms_m_s2"]
    row = r["skyhook_force"]
    assert row["ideal_semi_active"]["wk_rms_m_s2"] < r["passive_low"]["wk_rms_m_s2"]
    for k in ("model", "ideal_semi_active", "ideal_active"):
        assert all(np.isfinite(v) for v in row[k].values() if v is not None), row[k]
    m = row["model"]
    assert 0 < m["demand_share"] < 1 and 0 <= m["saturated_share"] <= 1 and m["tracking_rel"] > 0
    assert row["gain_share"] is not None
    # today's linear map (skyhook_continuous), measured against skyhook's ideal semi-active damper
    low, ideal = r["passive_low"]["wk_rms_m_s2"], row["ideal_semi_active"]["wk_rms_m_s2"]
    assert r["skyhook_continuous"]["gain_share"] == pytest.approx(
        (low - r["skyhook_continuous"]["wk_rms_m_s2"]) / (low - ideal), rel=1e-12)


def test_the_study_command_runs_it_prints_the_tables_and_draws_the_figure(tmp_path, capsys):
    """`dampnet study default --control --quick`: class C at 80 km/h, quarter car and full car;
    the tables (the gain column, the tracking table, the full car's rows) printed and in
    study.txt, every law's rows in study.json, the headline against the target, the figure; a
    study replaced without --control drops its figure; the options' errors name the option.
    Cost: about 10 s (the thesis study's quick runs twice)."""
    import json

    from dampnet.cli import main

    out = tmp_path / "s"
    assert main(["study", "default", "--control", "--quick", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "| C, 80 |" in text and "(gain " in text and "out of reach" in text and "heave Wk RMS" in text
    assert "as a share of the ideal semi-active damper's (target >= 0.9" in text
    assert "| C, 80 |" in (out / "study.txt").read_text()
    study = json.loads((out / "study.json").read_text())["control"]
    assert study["model"] == "default" and list(study["quarter_car"]) == ["C_80"]
    assert set(study["quarter_car"]["C_80"]) >= {"passive_low", "passive_high", "skyhook_continuous", *cs.FORCE_LAWS}
    assert set(study["full_car"]["C_80"]) >= {"low", "high", "skyhook", *cs.FORCE_LAWS}
    # the full car's force tracking over its four corners (the linearised coupling's, 0.9-2.8 % measured)
    assert "Full car, force tracking over the four corners" in text
    for law in cs.FORCE_LAWS:
        row = study["full_car"]["C_80"][law]
        assert 0 < row["tracking_rel"] < 0.05 and 0 < row["saturated_share"] < 1, (law, row)
    assert (out / "control_vs_ideal.png").stat().st_size > 10_000
    assert main(["study", "default", "--quick", "--no-plots", "--out", str(out), "--force"]) == 0
    capsys.readouterr()
    assert "control" not in json.loads((out / "study.json").read_text())
    assert not (out / "control_vs_ideal.png").exists()
    for argv, expect in ((["default", "--control", "--control-classes", "Z"], "--control-classes: ISO 8608 class must be one of A-H, got 'Z'"),
                         (["default", "--control-speeds", "80"], "--control-speeds sets the control study's roads: give --control"),
                         (["default", "--control", "--control-speeds", "-5"], "--control-speeds"),
                         (["linear:1800", "--control"], "linear:1800: the control study tracks forces through the damper's inverse")):
        assert main(["study", *argv, "--out", str(tmp_path / "bad")]) == 2
        err = capsys.readouterr().err
        assert err.startswith("dampnet: error: ") and expect in err and err.count("\n") == 1, err
    assert not (tmp_path / "bad").exists()
