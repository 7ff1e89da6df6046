"""The quarter-car FMU (`build_fmu(..., what="quarter-car")`, co-simulation, FMI 2 and 3) checked
by an independent importer (FMPy): no validation problems, a binary needing only libc and libm,
and FMPy's co-simulation on the thesis rough road equal to QuarterCar.simulate (states, damper
force, accelerations) to 1e-9 for the passive and the on-off skyhook law; parameters set by the
importer or compiled in as start values give the run of QuarterCar with the same parameters;
a communication step of n dt is n loop steps on the road's Hermite interpolant (FMPy's default
run takes 16 dt); a step that is not a whole multiple of dt and an invalid parameter are errors
naming them."""

import subprocess
import zipfile

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

from dampnet import _core
from dampnet.export.fmu import FmuError, build_fmu
from dampnet.modeldir import default_model
from dampnet.sim.quarter_car.loop import QuarterCar, damper_from_model
from dampnet.sim.roads import thesis_rough_road
from loop_helpers import random_model

DT = 1e-3
N = 2001  # 2 s of the thesis rough road at 20 m/s
STATES = {"z_s": 1, "v_s": 2, "z_us": 3, "v_us": 4}  # STATE_NAMES columns
OUTPUTS = [*STATES, "force", "control", "acc_s", "acc_us", "travel", "tyre_force", "status"]
BINARY = {2: "binaries/linux64/dampnet_quarter_car.so", 3: "binaries/x86_64-linux/dampnet_quarter_car.so"}


@pytest.fixture(scope="module")
def road():
    s = thesis_rough_road().sample(DT, speed=20.0)
    return s.z[:N], s.zdot[:N]


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    """The default model's quarter-car FMU (default parameters: thesis Table 5, passive), FMI 2 and 3."""
    d = tmp_path_factory.mktemp("qc")
    return {fmi: build_fmu(default_model(), d / f"qc{fmi}.fmu", fmi=fmi, what="quarter-car")
            for fmi in (2, 3)}


def road_signal(z, zd, u=None, dt=DT):
    """FMPy's input table for a road sampled at DT. FMPy applies the input of t_k before the step
    from t_k, and the FMU takes it as the road at the step's END (t_k+1, as dn_loop_input): so
    the table holds the road one sample ahead. The first row (t = -dt) and the event at t = 0 (two
    rows) give road[0] at initialisation (FMPy applies the left value there) and road[1] from the
    first step on. u (the external law's control over the step from t_k) is not shifted."""
    n = z.size
    sig = np.zeros(n + 1, dtype=[("time", float), ("z_r", float), ("v_r", float), ("u", float)])
    sig["time"] = np.concatenate([[-dt, 0.0], np.arange(n - 1) * dt])
    sig["z_r"] = np.concatenate([[z[0]], z])
    sig["v_r"] = np.concatenate([[zd[0]], zd])
    if u is not None:
        sig["u"] = np.concatenate([[u[0], u[0]], u[:-1]])
    return sig


def simulate(path, z, zd, u=None, **kw):
    return simulate_fmu(str(path), start_time=0.0, stop_time=(z.size - 1) * DT, step_size=DT, output_interval=DT,
                        input=road_signal(z, zd, u), output=OUTPUTS, fmi_type="CoSimulation", **kw)


def assert_same_run(res, ref, vehicle=None, report=True):
    """The FMU's recorded outputs at t_k equal QuarterCar.simulate's row k (the state at t_k and
    what the step from t_k reports at its start) to 1e-9."""
    st = ref["state"]
    assert len(res) == st.shape[0]
    for name, col in STATES.items():
        np.testing.assert_allclose(res[name], st[:, col], rtol=0, atol=1e-9, err_msg=name)
    np.testing.assert_allclose(res["travel"], st[:, 1] - st[:, 3], rtol=0, atol=1e-12)
    k_t, c_t = (vehicle or {}).get("k_t", 200000.0), (vehicle or {}).get("c_t", 0.0)
    np.testing.assert_allclose(res["tyre_force"], k_t * (st[:, 3] - st[:, 5]) + c_t * (st[:, 4] - st[:, 6]),
                               rtol=0, atol=1e-6)
    if report:
        for name, key in (("force", "force"), ("control", "control"), ("acc_s", "acc_s"), ("acc_us", "acc_us")):
            np.testing.assert_allclose(res[name], ref[key], rtol=0, atol=1e-9, err_msg=name)
    assert np.all(res["status"] >= 0)


@pytest.mark.parametrize("fmi", [2, 3])
def test_fmpy_validates_and_runs_the_quarter_car_on_the_rough_road(fmus, road, fmi):
    """validate_fmu: no problem. FMPy's co-simulation of 2 s of the thesis rough road (20 m/s,
    dt 1 ms) equals QuarterCar.simulate: z_s, v_s, z_us, v_us, the damper force, the control and
    both accelerations to 1e-9 (measured: 0.0, bit for bit), passive and on-off skyhook (the law
    chosen by the importer, an Integer parameter); the skyhook run differs from the passive one."""
    path = fmus[fmi]
    assert validate_fmu(str(path)) == []
    md = read_model_description(str(path))
    assert md.coSimulation is not None and md.modelExchange is None
    assert float(md.defaultExperiment.stepSize) == DT
    z, zd = road
    runs = {}
    for kind, value in (("passive", 0), ("skyhook_onoff", 1)):
        ref = QuarterCar(damper_from_model(default_model()), controller={"kind": kind}).simulate(z, zd)
        res = simulate(path, z, zd, start_values={"kind": value})
        assert_same_run(res, ref)
        assert np.ptp(ref["force"]) > 1000.0 and np.ptp(ref["state"][:, 1]) > 0.03
        runs[kind] = res
    assert np.max(np.abs(runs["passive"]["z_s"] - runs["skyhook_onoff"]["z_s"])) > 0.01


def test_external_control_input(fmus, road):
    """The external law: u set at t_k is the control over the step from t_k (as Loop.simulate's
    u[k]); the states equal QuarterCar.simulate's with the same control to 1e-9."""
    z, zd = road
    t = np.arange(z.size) * DT
    u = 2.5 + 2.5 * np.sign(np.sin(2 * np.pi * 3.0 * t))
    ref = QuarterCar(damper_from_model(default_model()), controller={"kind": "external"}).simulate(z, zd, u=u)
    res = simulate(fmus[3], z, zd, u=u, start_values={"kind": 5})
    # the report at t_k+1 is evaluated with the u set for the step that ended there (FMPy reads
    # before setting the next one): compare the states
    assert_same_run(res, ref, report=False)
    np.testing.assert_allclose(res["control"][1:], u[:-1], rtol=0, atol=0)


@pytest.mark.parametrize("law", ["skyhook_force", "clipped_optimal"])
def test_force_tracking_laws_run_in_the_fmu_as_on_the_host(fmus, road, law):
    """A force-tracking law chosen by the importer (its kind and gains as start values: the damper's
    inverse at every step inside the FMU) gives QuarterCar.simulate's run to 1e-9, and differs from
    on-off skyhook. Cost: two 2 s FMPy runs of the session's FMU, about 1 s."""
    from dampnet.sim.calibration import lqr_gains

    z, zd = road
    controller = {"kind": law, "c_sky": 4000.0, **(lqr_gains() if law == "clipped_optimal" else {})}
    ref = QuarterCar(damper_from_model(default_model()), controller=controller).simulate(z, zd)
    res = simulate(fmus[3], z, zd, start_values={**controller, "kind": _core.CONTROLLER_KINDS[law][0]})
    assert_same_run(res, ref)
    onoff = QuarterCar(damper_from_model(default_model()), controller={"kind": "skyhook_onoff"}).simulate(z, zd)
    assert np.max(np.abs(onoff["control"] - ref["control"])) > 1.0


def test_parameters_set_by_the_importer_or_compiled_in(fmus, road, tmp_path):
    """Start values given by the importer (vehicle, controller: m_s, k_s, the continuous skyhook
    and c_sky) give the run of QuarterCar with those parameters; so do start values compiled into
    another FMU (build_fmu's vehicle/controller, the CLI's --set), which gets its own GUID."""
    z, zd = road
    vehicle = {"m_s": 450.0, "k_s": 20000.0}
    controller = {"kind": "skyhook_continuous", "c_sky": 3000.0}
    ref = QuarterCar(damper_from_model(default_model()), vehicle, controller).simulate(z, zd)
    res = simulate(fmus[2], z, zd, start_values={**vehicle, "kind": 2, "c_sky": 3000.0})
    assert_same_run(res, ref, vehicle)
    base = QuarterCar(damper_from_model(default_model()), controller={"kind": "skyhook_continuous"}).simulate(z, zd)
    assert np.max(np.abs(base["state"][:, 1] - ref["state"][:, 1])) > 1e-3  # the parameters matter

    built = build_fmu(default_model(), tmp_path / "qc-450.fmu", fmi=3, interface="cs", what="quarter-car",
                      vehicle=vehicle, controller=controller)
    assert validate_fmu(str(built)) == []
    md, md0 = read_model_description(str(built)), read_model_description(str(fmus[3]))
    assert md.guid != md0.guid and md.guid.startswith(md0.guid)
    starts = {v.name: v.start for v in md.modelVariables}
    assert float(starts["m_s"]) == 450.0 and int(starts["kind"]) == 2
    assert_same_run(simulate(built, z, zd), ref, vehicle)


def test_hybrid_damper_parameters(road, tmp_path):
    """A hybrid model with a control lag, a velocity lag, the Dahl friction state and two physics
    terms in the quarter car: its feature constants and term parameters are the FMU's parameters
    too, and a changed value gives QuarterCar's run of the model with that value (1e-9)."""
    feats = ["velocity", "acceleration", "voltage_lag", "velocity_lag", "friction_state", "displacement"]
    params = {"control_lag_tau_s": 0.004, "velocity_lag_tau_s": 0.002, "friction_presliding_m": 0.0005}
    terms = [{"kind": "position_poly", "params": [-150.0, 3000.0, 1e4, 0.0]},
             {"kind": "bump_stop", "params": [0.04, 2e5, 1.5]}]
    model = random_model(feats, hidden=9, seed=4, feature_params=params, terms=terms)
    path = build_fmu(model, tmp_path / "h.fmu", fmi=2, interface="cs", what="quarter-car",
                     controller={"kind": "skyhook_onoff", "u_tau_s": 0.005})
    assert validate_fmu(str(path)) == []
    z, zd = road
    changed = random_model(feats, hidden=9, seed=4, feature_params={**params, "control_lag_tau_s": 0.02},
                           terms=[{"kind": "position_poly", "params": [-400.0, 3000.0, 1e4, 0.0]}, terms[1]])
    ref = QuarterCar(damper_from_model(changed), controller={"kind": "skyhook_onoff", "u_tau_s": 0.005}).simulate(z, zd)
    res = simulate(path, z, zd, start_values={"control_lag_tau_s": 0.02, "position_poly_0.p0": -400.0})
    assert_same_run(res, ref)


@pytest.mark.parametrize("fmi", [2, 3])
def test_communication_steps_of_whole_multiples_of_dt(fmus, road, fmi):
    """FMPy's run with all its defaults (the default experiment, 10 s: its interval doubled to
    16 dt) runs. A step of n = 4 dt with the road given at the communication points equals
    QuarterCar.simulate at dt on the road's cubic Hermite interpolant between them (scipy's
    CubicHermiteSpline, an independent one) to 1e-9; holding the road at the step's end instead
    differs by far more, so the interpolant matters."""
    from scipy.interpolate import CubicHermiteSpline

    res = simulate_fmu(str(fmus[fmi]))
    assert res["time"][-1] == pytest.approx(10.0) and np.diff(res["time"])[0] == pytest.approx(16 * DT)
    n = 4
    z, zd = road
    zc, zdc = z[::n], zd[::n]  # the road at the communication points, h = n dt
    tc = np.arange(zc.size) * n * DT
    spline = CubicHermiteSpline(tc, zc, zdc)
    t = np.arange((zc.size - 1) * n + 1) * DT
    zf, zdf = spline(t), spline.derivative()(t)
    zf[::n], zdf[::n] = zc, zdc  # the knots exactly (the FMU uses the given values there)
    ref = QuarterCar(damper_from_model(default_model())).simulate(zf, zdf)
    run = simulate_fmu(str(fmus[fmi]), start_time=0.0, stop_time=float(tc[-1]), output_interval=n * DT,
                       input=road_signal(zc, zdc, dt=n * DT), output=OUTPUTS, fmi_type="CoSimulation")
    assert len(run) == zc.size
    for name, col in STATES.items():
        np.testing.assert_allclose(run[name], ref["state"][::n, col], rtol=0, atol=1e-9, err_msg=name)
    held = QuarterCar(damper_from_model(default_model())).simulate(np.repeat(zc, n)[n - 1:], np.repeat(zdc, n)[n - 1:])
    assert np.max(np.abs(held["state"][::n, 1] - ref["state"][::n, 1])) > 1e-5


def test_errors_name_the_step_and_the_parameter(fmus, tmp_path):
    """A communication step that is not a whole multiple of dt: fmi2Error/fmi3Error from doStep,
    the logged message naming h and dt; m_s = -1: initialisation fails naming m_s and its range;
    two fields refused only together are named together; model exchange is refused by build_fmu
    in one line."""
    messages = []

    def log(*args):
        messages.append(args[-1].decode() if isinstance(args[-1], bytes) else str(args[-1]))

    for fmi, path in fmus.items():
        messages.clear()
        with pytest.raises(Exception, match=f"fmi{fmi}DoStep"):
            simulate_fmu(str(path), stop_time=0.03, output_interval=1.5e-3, logger=log)
        assert any("h = 0.0015 s is not a whole multiple" in m and "fixed step dt = 0.001 s" in m
                   for m in messages), messages
        messages.clear()
        with pytest.raises(Exception, match=f"fmi{fmi}ExitInitializationMode"):
            simulate_fmu(str(path), stop_time=0.01, output_interval=DT, start_values={"m_s": -1.0}, logger=log)
        assert any("parameter m_s = -1: sprung mass [kg], > 0" in m for m in messages), messages
    messages.clear()
    with pytest.raises(Exception, match="fmi2ExitInitializationMode"):
        simulate_fmu(str(fmus[2]), stop_time=0.01, output_interval=DT, start_values={"u_min": 3.0, "u_max": 1.0},
                     logger=log)
    assert any("u_min = 3 and u_max = 1 are refused together" in m for m in messages), messages
    for interface in ("me", "both"):
        with pytest.raises(FmuError, match="co-simulation FMU only") as e:
            build_fmu(default_model(), tmp_path / "me.fmu", interface=interface, what="quarter-car")
        assert "\n" not in str(e.value) and not (tmp_path / "me.fmu").exists()
    with pytest.raises(ValueError, match="vehicle 'm_s' = -1.0"):
        build_fmu(default_model(), tmp_path / "bad.fmu", interface="cs", what="quarter-car", vehicle={"m_s": -1.0})
    with pytest.raises(ValueError, match="unknown parameter.*m_x"):
        build_fmu(default_model(), tmp_path / "bad.fmu", interface="cs", what="quarter-car", vehicle={"m_x": 1.0})
    assert not (tmp_path / "bad.fmu").exists()


@pytest.mark.parametrize("fmi", [2, 3])
def test_the_binary_needs_only_libc_and_libm(fmus, tmp_path, fmi):
    with zipfile.ZipFile(fmus[fmi]) as z:
        names = set(z.namelist())
        z.extractall(tmp_path / "x")
    assert {"modelDescription.xml", BINARY[fmi], f"sources/fmu{fmi}.cpp", "sources/fmu_quarter_car.hpp",
            "sources/fmu_config.h", "sources/dampnet/loop.hpp"} <= names
    ldd = subprocess.run(["ldd", str(tmp_path / "x" / BINARY[fmi])], capture_output=True, text=True).stdout
    libs = {line.split()[0] for line in ldd.splitlines() if line.strip()}
    assert libs <= {"linux-vdso.so.1", "libm.so.6", "libc.so.6", "/lib64/ld-linux-x86-64.so.2"}, ldd


def test_export_quarter_car_command(tmp_path, capsys):
    """`dampnet export MODEL --fmu OUT --what quarter-car --controller LAW --set NAME=VALUE`: the start
    values land in modelDescription.xml (and the binary), co-simulation only, fixed step; a
    parameter the runtime refuses or an unknown name is one line, exit 2, nothing written."""
    from dampnet.cli import main
    from dampnet.modeldir import save_model_dir

    save_model_dir(default_model(), None, tmp_path / "model")
    out = tmp_path / "qc.fmu"
    assert main(["export", str(tmp_path / "model"), "--fmu", str(out), "--what", "quarter-car", "--fmi", "3",
                 "--controller", "skyhook_onoff", "--set", "m_s=450", "--set", "c_sky=3000"]) == 0
    assert "FMI 3.0 FMU dampnet_quarter_car (co-simulation;" in capsys.readouterr().out
    assert validate_fmu(str(out)) == []
    md = read_model_description(str(out))
    start = {v.name: v.start for v in md.modelVariables}
    assert float(start["m_s"]) == 450.0 and float(start["c_sky"]) == 3000.0 and int(start["kind"]) == 1
    assert md.modelExchange is None and md.coSimulation.canHandleVariableCommunicationStepSize is False
    for bad, said in ((["--set", "m_s=-1"], "m_s"), (["--set", "mass=3"], "not a vehicle or controller parameter"),
                      (["--interface", "me"], "co-simulation FMU only")):
        assert main(["export", str(tmp_path / "model"), "--fmu", str(tmp_path / "bad.fmu"), "--what", "quarter-car",
                     *bad]) == 2
        err = capsys.readouterr().err
        assert err.startswith("dampnet: error: ") and said in err and err.count("\n") == 1, err
        assert not (tmp_path / "bad.fmu").exists()
