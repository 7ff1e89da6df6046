"""`dampnet export --fmu`: the damper as an FMU (FMI 2.0 and 3.0, co-simulation and model
exchange), checked by an independent importer (FMPy): no validation problems, a binary needing
only libc and libm, FMPy's simulations of a recorded rig test equal to the runtime's
Damper.forces to 1e-9 N, the derived features' states (lags, Dahl friction) equal to the
reference loop's updates (dampnet.features), settable parameters, the source FMU rebuilt by
FMPy and from buildDescription.xml alone, model exchange integrated by CVode following
co-simulation with its discrete outputs changing only at events, FMPy's default runs, no
step after a failed initialisation, and the damper's inverse (force_demand -> u_command,
inverse_status, force_at_command) equal to the host's Damper.inverse."""

import re
import subprocess
import zipfile

import numpy as np
import pytest

import fmi2_callbacks
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Model, FMU2Slave
from fmpy.fmi3 import FMU3Model, FMU3Slave
from fmpy.validation import validate_fmu

from dampnet import _core, features
from dampnet.cli import main
from dampnet.export.fmu import FmuError, build_damper_fmu, build_fmu
from dampnet.modeldir import default_model, save_model_dir
from dampnet.rig import generate
from dampnet.sim.quarter_car.loop import damper_from_model
from loop_helpers import inverse_allowance, random_model

HYBRID_FEATURES = ["velocity", "acceleration", "voltage_lag", "velocity_lag", "friction_state", "displacement"]
HYBRID_PARAMS = {"control_lag_tau_s": 0.004, "velocity_lag_tau_s": 0.002, "friction_presliding_m": 0.0005}
HYBRID_TERMS = [{"kind": "position_poly", "params": [-150.0, 3000.0, 1e4, 0.0]},
                {"kind": "bump_stop", "params": [0.01, 2e5, 1.5]}]
IN_VRS = [0, 1, 2, 3, 4]  # x, v, a, u, temperature
VR_FORCE, VR_DEMAND, VR_U_COMMAND, VR_INV_STATUS, VR_INV_FORCE = 5, 30, 31, 32, 33  # fmu_damper.hpp


def hybrid_model(**changes):
    """Six features, three of them with a state (control lag, velocity lag, Dahl friction), two terms."""
    params = {**HYBRID_PARAMS, **changes.get("feature_params", {})}
    return random_model(HYBRID_FEATURES, hidden=9, seed=4, feature_params=params,
                        terms=changes.get("terms", HYBRID_TERMS))


@pytest.fixture(scope="module")
def rig_signals():
    """A recorded quick-plan rig test (0.4 s at 5 kHz): t, x, v, a (the velocity's gradient), u;
    the control steps from 0 V to the test's level at 0.1 s, so the control lag moves."""
    test = generate("quick", seed=0, progress=False).tests[3]
    k = slice(0, 2000)
    t, v = test.time[k] - test.time[0], test.channels["velocity"][k]
    u = np.where(t < 0.1, 0.0, test.control[k])
    return t, test.channels["displacement"][k], v, np.gradient(v, t), u


@pytest.fixture(scope="module")
def default_fmus(tmp_path_factory):
    """The default 3-30-1 model's damper FMU (both interfaces), FMI 2 and 3: built once here."""
    d = tmp_path_factory.mktemp("fmu")
    return {fmi: build_fmu(default_model(), d / f"default{fmi}.fmu", fmi=fmi) for fmi in (2, 3)}


@pytest.fixture(scope="module")
def hybrid_fmus(tmp_path_factory):
    d = tmp_path_factory.mktemp("fmu")
    return {fmi: build_fmu(hybrid_model(), d / f"hybrid{fmi}.fmu", fmi=fmi) for fmi in (2, 3)}


def reference_states(model, t, x, v, u):
    """The derived features' states at every sample by the reference loop's updates
    (dampnet.features: the control held over a step, the velocity a ramp, the Dahl state by
    the step's net travel), from the steady state at the first sample (Dahl: 0)."""
    dt = float(t[1] - t[0])
    q = [{"x": x[k], "v": v[k], "u": u[k]} for k in range(t.size)]
    out = {}
    for name, field in (("voltage_lag", "u_lag"), ("velocity_lag", "v_lag"), ("friction_state", "z_fric")):
        if name not in model.features:
            continue
        f = features.feature(name)
        y = np.empty(t.size)
        y[0] = f.source.first(q[0]) if name == "friction_state" else q[0][f.source.loop_input]
        for k in range(1, t.size):
            y[k] = f.source.step(y[k - 1], q[k - 1], q[k], dt, model.feature_params[f.param])
        out[field] = y
    return out


def reference_forces(model, t, x, v, a, u, temperature=None):
    temp = np.full(t.size, 20.0) if temperature is None else temperature
    s = reference_states(model, t, x, v, u)
    return damper_from_model(model).forces(x, v, a, u, s.get("u_lag", u), temp, s.get("v_lag", v),
                                           s.get("z_fric", np.zeros(t.size)))


def drive(path, signals, start_values=None, read_before_step=True):
    """Co-simulation through FMPy's FMU classes: at each communication point t_k set that
    point's inputs, read the force (the force at t_k), then step to t_k+1. Returns the forces."""
    t, x, v, a, u = signals
    md = read_model_description(str(path))
    unzip = extract(str(path))
    cls = FMU2Slave if md.fmiVersion == "2.0" else FMU3Slave
    fmu = cls(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier,
              instanceName="damper")
    by_name = {sv.name: sv.valueReference for sv in md.modelVariables}
    set_real = fmu.setReal if md.fmiVersion == "2.0" else fmu.setFloat64
    get_real = fmu.getReal if md.fmiVersion == "2.0" else fmu.getFloat64
    cb = fmi2_callbacks.callbacks() if md.fmiVersion == "2.0" else None  # alive until the instance is freed
    fmu.instantiate(**({"callbacks": cb} if cb is not None else {}))
    if md.fmiVersion == "2.0":
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
    else:
        fmu.enterInitializationMode(startTime=0.0)
    for name, value in (start_values or {}).items():
        set_real([by_name[name]], [value])
    set_real(IN_VRS, [x[0], v[0], a[0], u[0], 20.0])
    fmu.exitInitializationMode()
    dt = float(t[1] - t[0])
    f = np.empty(t.size)
    for k in range(t.size):
        set_real(IN_VRS, [x[k], v[k], a[k], u[k], 20.0])
        f[k] = get_real([by_name["force"]])[0]
        fmu.doStep(k * dt, dt)
    fmu.terminate()
    fmu.freeInstance()
    return f


def _simulate(path, t, x, v, a, u, temperature=None, fmi_type="CoSimulation", **kw):
    names = ["x", "v", "a", "u"] + (["temperature"] if temperature is not None else [])
    sig = np.zeros(t.size, dtype=[("time", float)] + [(n, float) for n in names])
    sig["time"], sig["x"], sig["v"], sig["a"], sig["u"] = t, x, v, a, u
    if temperature is not None:
        sig["temperature"] = temperature
    dt = float(t[1] - t[0])
    return simulate_fmu(str(path), start_time=0.0, stop_time=float(t[-1]), step_size=dt, output_interval=dt, input=sig,
                        output=["force", "status"], fmi_type=fmi_type, **kw)


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("which", ["default", "hybrid"])
def test_fmpy_validates_and_simulates_the_damper_fmu(tmp_path, default_fmus, rig_signals, which, fmi):
    """FMPy: validate_fmu finds no problem; its co-simulation of a recorded rig test gives the
    runtime's forces to 1e-9 N (FMPy records the output at t_k after the step from t_k-1, with
    the inputs of t_k-1: the force of sample k-1). The plain 3-30-1 model and a stateless
    hybrid one (five features, a gas term and a bump stop), FMI 2 and FMI 3."""
    t, x, v, a, u = rig_signals
    if which == "default":
        model, temp = default_model(), None
        path = default_fmus[fmi]
    else:
        model = random_model(["velocity", "acceleration", "voltage", "displacement", "temperature"], hidden=9, seed=2,
                             terms=HYBRID_TERMS)
        temp = 20.0 + 10.0 * np.sin(3.0 * t)
        path = build_fmu(model, tmp_path / "d.fmu", fmi=fmi)
    assert validate_fmu(str(path)) == []
    res = _simulate(path, t, x, v, a, u, temp)
    f, status, _ = damper_from_model(model).forces(x, v, a, u, u, 20.0 + 0 * t if temp is None else temp)
    assert np.all(status >= 0) and np.all(res["status"] >= 0)
    n = len(res)
    assert n == t.size and np.ptp(f) > 100.0
    np.testing.assert_allclose(res["force"][1:], f[: n - 1], rtol=0, atol=1e-9)
    assert res["force"][0] == pytest.approx(f[0], abs=1e-9)


@pytest.mark.parametrize("fmi", [2, 3])
def test_derived_feature_states_advance_as_the_loop(hybrid_fmus, rig_signals, fmi):
    """A six-feature hybrid model with a control lag, a velocity lag and the Dahl friction state:
    the force at each communication point equals Damper.forces on the reference loop's states
    (dampnet.features' updates) to 1e-9 N, FMI 2 and 3. The states matter: the same forces with
    the lags replaced by their inputs differ by far more."""
    t, x, v, a, u = rig_signals
    model = hybrid_model()
    assert validate_fmu(str(hybrid_fmus[fmi])) == []
    f_fmu = drive(hybrid_fmus[fmi], rig_signals)
    f_ref, status, _ = reference_forces(model, t, x, v, a, u)
    assert np.all(status >= 0) and np.ptp(f_ref) > 100.0
    np.testing.assert_allclose(f_fmu, f_ref, rtol=0, atol=1e-9)
    f_no_state = damper_from_model(model).forces(x, v, a, u, u, np.full(t.size, 20.0), v, np.sign(v))[0]
    assert np.max(np.abs(f_no_state - f_ref)) > 1.0


def test_parameters_are_settable_and_checked(hybrid_fmus, rig_signals):
    """The feature constants and the terms' parameters are FMU parameters: start values given
    by the importer give the forces of the model with those values; a value the runtime refuses
    fails initialisation with a message naming it; a parameter is fixed after initialisation."""
    t, x, v, a, u = rig_signals
    changed = {"control_lag_tau_s": 0.02, "friction_presliding_m": 0.002, "position_poly_0.p0": -400.0,
               "bump_stop_1.k": 5e5}
    f_fmu = drive(hybrid_fmus[2], rig_signals, start_values=changed)
    terms = [{"kind": "position_poly", "params": [-400.0, 3000.0, 1e4, 0.0]},
             {"kind": "bump_stop", "params": [0.01, 5e5, 1.5]}]
    model = hybrid_model(feature_params={"control_lag_tau_s": 0.02, "friction_presliding_m": 0.002}, terms=terms)
    f_ref = reference_forces(model, t, x, v, a, u)[0]
    np.testing.assert_allclose(f_fmu, f_ref, rtol=0, atol=1e-9)
    assert np.max(np.abs(f_ref - reference_forces(hybrid_model(), t, x, v, a, u)[0])) > 10.0

    messages = []
    with pytest.raises(Exception, match="fmi2ExitInitializationMode"):
        simulate_fmu(str(hybrid_fmus[2]), stop_time=0.01, step_size=1e-3, start_values={"velocity_lag_tau_s": -1.0},
                     logger=lambda *args: messages.append(args[-1].decode() if isinstance(args[-1], bytes) else args[-1]))
    assert any("velocity_lag_tau_s = -1" in m for m in messages), messages


def test_model_exchange_with_cvode_follows_co_simulation(hybrid_fmus):
    """The lag and friction states as continuous states with their derivatives, integrated by
    FMPy's CVode (rtol 1e-8), follow the co-simulation's exact per-step updates (the reference
    loop's) on a smooth motion (3 Hz, 20 mm) and control (2.5 +- 2 V at 4 Hz) within 0.25 % of
    the force range. What remains is the sampling, not the FMU: co-simulation holds the control
    over a step, and FMPy applies model-exchange inputs only at its output points (piecewise
    constant: run here at a tenth of the sample time; at the sample time the difference is 0.8 %)."""
    n, dt, sub = 1500, 2e-4, 10
    t = np.arange(n) * dt
    w, amp = 2 * np.pi * 3.0, 0.02
    x, v, a = amp * np.sin(w * t), amp * w * np.cos(w * t), -amp * w * w * np.sin(w * t)
    u = 2.5 + 2.0 * np.sin(2 * np.pi * 4.0 * t)
    f_cs = reference_forces(hybrid_model(), t, x, v, a, u)[0]
    np.testing.assert_allclose(drive(hybrid_fmus[3], (t, x, v, a, u)), f_cs, rtol=0, atol=1e-9)
    sig = np.zeros(n, dtype=[("time", float)] + [(c, float) for c in "xvau"])
    sig["time"], sig["x"], sig["v"], sig["a"], sig["u"] = t, x, v, a, u
    for fmi in (2, 3):
        me = simulate_fmu(str(hybrid_fmus[fmi]), stop_time=float(t[-1]), step_size=dt / sub, output_interval=dt / sub,
                          input=sig, output=["force", "z_fric"], fmi_type="ModelExchange", solver="CVode",
                          relative_tolerance=1e-8)
        assert np.ptp(me["z_fric"]) > 1.5  # the friction state reverses with the motion
        err = np.max(np.abs(np.interp(t, me["time"], me["force"]) - f_cs))
        assert err < 2.5e-3 * np.ptp(f_cs), (fmi, err, np.ptp(f_cs))


def test_the_source_fmu_rebuilds_with_fmpy(tmp_path, hybrid_fmus, rig_signals):
    """sources/ (FMI 2: the SourceFiles listing; FMI 3: buildDescription.xml) compile with
    FMPy's build_platform_binary into a binary that gives the same forces."""
    from fmpy.build import build_platform_binary

    for fmi, fmu in hybrid_fmus.items():
        unzip = tmp_path / f"src{fmi}"
        with zipfile.ZipFile(fmu) as z:
            z.extractall(unzip)
        binary = next((unzip / "binaries").rglob("*.so"))
        binary.unlink()
        (tmp_path / f"build{fmi}").mkdir()
        build_platform_binary(unzip, build_dir=tmp_path / f"build{fmi}")
        assert binary.is_file()
        rebuilt = tmp_path / f"rebuilt{fmi}.fmu"
        with zipfile.ZipFile(rebuilt, "w") as z:
            for p in unzip.rglob("*"):
                if p.is_file():
                    z.write(p, p.relative_to(unzip).as_posix())
        np.testing.assert_allclose(drive(rebuilt, rig_signals), drive(fmu, rig_signals), rtol=0, atol=1e-9)


@pytest.mark.parametrize("fmi", [2, 3])
def test_the_fmu_binary_needs_only_libc_and_libm(hybrid_fmus, tmp_path, fmi):
    with zipfile.ZipFile(hybrid_fmus[fmi]) as z:
        names = set(z.namelist())
        z.extractall(tmp_path / "x")
    platform = {2: "linux64", 3: "x86_64-linux"}[fmi]
    expected = {"modelDescription.xml", f"binaries/{platform}/dampnet_damper.so", f"sources/fmu{fmi}.cpp",
                "sources/fmu_model.h", f"sources/fmi{fmi}Functions.h"} | ({"sources/buildDescription.xml"} if fmi == 3
                                                                         else set())
    assert expected <= names
    ldd = subprocess.run(["ldd", str(tmp_path / "x" / "binaries" / platform / "dampnet_damper.so")], capture_output=True,
                         text=True).stdout
    libs = {line.split()[0] for line in ldd.splitlines() if line.strip()}
    assert libs <= {"linux-vdso.so.1", "libm.so.6", "libc.so.6", "/lib64/ld-linux-x86-64.so.2"}, ldd
    assert "libstdc++" not in ldd


def test_interfaces_one_or_both(tmp_path):
    """--interface cs / me: the modelDescription declares only that interface (and the state
    derivatives only with model exchange); FMPy validates each."""
    model = hybrid_model()
    for fmi in (2, 3):
        for interface in ("cs", "me"):
            path = build_fmu(model, tmp_path / f"{interface}{fmi}.fmu", fmi=fmi, interface=interface)
            assert validate_fmu(str(path)) == []
            md = read_model_description(str(path))
            assert (md.coSimulation is not None) == (interface == "cs")
            assert (md.modelExchange is not None) == (interface == "me")
            assert len(md.derivatives) == (3 if interface == "me" else 0)
    with pytest.raises(FmuError, match="interface 'both-ish'"):
        build_fmu(model, tmp_path / "x.fmu", interface="both-ish")
    with pytest.raises(FmuError, match="FMI version 4"):
        build_fmu(model, tmp_path / "x.fmu", fmi=4)
    assert not (tmp_path / "x.fmu").exists()


def test_export_fmu_command_and_its_errors(tmp_path, capsys, monkeypatch):
    save_model_dir(default_model(), None, tmp_path / "model")
    out = tmp_path / "d.fmu"
    assert main(["export", str(tmp_path / "model"), "--fmu", str(out)]) == 0
    assert "FMI 2.0 FMU dampnet_damper" in capsys.readouterr().out and zipfile.is_zipfile(out)
    assert main(["export", str(tmp_path / "model"), "--fmu", str(out)]) == 2  # exists
    assert "refusing to overwrite" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "model"), "--fmu", str(tmp_path / "d3.fmu"), "--fmi", "3",
                 "--interface", "cs"]) == 0
    assert "FMI 3.0 FMU dampnet_damper (co-simulation" in capsys.readouterr().out
    assert read_model_description(str(tmp_path / "d3.fmu")).fmiVersion == "3.0"
    # a model with a feature the FMU cannot feed (one only a Python-side registry could know)
    odd = random_model(["velocity", "voltage"], seed=1)
    odd.features[1] = "voltage_squared"
    with pytest.raises(FmuError, match="cannot feed feature.*voltage_squared"):
        build_fmu(odd, tmp_path / "odd.fmu")
    assert not (tmp_path / "odd.fmu").exists()
    # no compiler: one line, nothing written
    monkeypatch.setenv("CXX", str(tmp_path / "no-such-compiler"))
    assert main(["export", str(tmp_path / "model"), "--fmu", str(tmp_path / "c.fmu")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("dampnet: error: ") and "no C++ compiler" in err and not (tmp_path / "c.fmu").exists()
    assert not list(tmp_path.glob(".dampnet-fmu-*"))
    monkeypatch.delenv("CXX")
    with pytest.raises(SystemExit) as exit_:
        main(["export", str(tmp_path / "model"), "--fmu", str(tmp_path / "m.fmu"), "--fmi", "4"])
    assert exit_.value.code == 2 and "invalid choice: 4" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "model"), "--fmu", str(tmp_path / "m.fmu"), "--set", "m_s=450"]) == 2
    assert "add --what quarter-car" in capsys.readouterr().err and not (tmp_path / "m.fmu").exists()


def test_extra_compile_flags_reach_the_compiler_and_bad_ones_are_named(tmp_path, monkeypatch):
    """$DAMPNET_FMU_CXXFLAGS comes after dampnet's own flags (the suite's -O0 is one: conftest); a
    flag the compiler refuses fails the export showing its command, a value a shell could not
    split is named. Cost: 0.3 s (one failed compile)."""
    model = default_model()
    monkeypatch.setenv("DAMPNET_FMU_CXXFLAGS", "-O0 -DDNFMU_FLAG_PROBE -fno-such-flag")
    with pytest.raises(FmuError, match=r"(?s)-O2 .*-O0 -DDNFMU_FLAG_PROBE -fno-such-flag .*error: .*fno-such-flag"):
        build_fmu(model, tmp_path / "x.fmu")
    monkeypatch.setenv("DAMPNET_FMU_CXXFLAGS", "-DX='unbalanced")
    with pytest.raises(FmuError, match=r"\$DAMPNET_FMU_CXXFLAGS: No closing quotation"):
        build_fmu(model, tmp_path / "x.fmu")
    assert not (tmp_path / "x.fmu").exists()


def test_non_finite_input_is_an_error_with_a_message(hybrid_fmus, rig_signals):
    """A NaN input: reading the force fails (fmi2Error), and the logged message says why."""
    t, x, v, a, u = rig_signals
    messages = []
    sig = np.zeros(50, dtype=[("time", float), ("v", float)])
    sig["time"], sig["v"] = t[:50], np.where(np.arange(50) < 20, 0.1, np.nan)
    with pytest.raises(Exception):
        simulate_fmu(str(hybrid_fmus[2]), stop_time=float(t[49]), step_size=float(t[1]), input=sig,
                     output=["force"], logger=lambda *args: messages.append(str(args[-1])))
    assert any("NaN or infinite" in m for m in messages), messages


def test_the_source_fmu_builds_from_its_build_description_alone(tmp_path, hybrid_fmus, rig_signals):
    """FMI 3: compiling exactly what sources/buildDescription.xml lists (its source files, include
    directories relative to sources/, definitions and language; run from elsewhere, so nothing
    is found by accident) gives a binary with the same forces."""
    import xml.etree.ElementTree as ET

    unzip = tmp_path / "src"
    with zipfile.ZipFile(hybrid_fmus[3]) as z:
        z.extractall(unzip)
    sources = unzip / "sources"
    fileset = ET.parse(sources / "buildDescription.xml").getroot().find("BuildConfiguration/SourceFileSet")
    assert fileset.get("language") == "C++17"
    cmd = ["g++", "-std=c++17", "-O2", "-fPIC", "-shared", "-o", str(tmp_path / "dampnet_damper.so")]
    cmd += [str(sources / f.get("name")) for f in fileset.findall("SourceFile")]
    cmd += [f"-I{sources / d.get('name')}" for d in fileset.findall("IncludeDirectory")]
    cmd += [f"-D{d.get('name')}" + (f"={d.get('value')}" if d.get("value") else "")
            for d in fileset.findall("PreprocessorDefinition")]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    binary = unzip / "binaries" / "x86_64-linux" / "dampnet_damper.so"
    binary.write_bytes((tmp_path / "dampnet_damper.so").read_bytes())
    rebuilt = tmp_path / "rebuilt.fmu"
    with zipfile.ZipFile(rebuilt, "w") as z:
        for p in unzip.rglob("*"):
            if p.is_file():
                z.write(p, p.relative_to(unzip).as_posix())
    np.testing.assert_allclose(drive(rebuilt, rig_signals), drive(hybrid_fmus[3], rig_signals), rtol=0, atol=1e-9)


@pytest.mark.parametrize("fmi", [2, 3])
def test_fmpy_default_runs(hybrid_fmus, fmi):
    """simulate_fmu with nothing but the file: co-simulation and model exchange run the default
    experiment (10 s) at the inputs' start values, status 0."""
    for fmi_type in ("CoSimulation", "ModelExchange"):
        res = simulate_fmu(str(hybrid_fmus[fmi]), fmi_type=fmi_type)
        assert res["time"][-1] == pytest.approx(10.0) and np.all(res["status"] == 0), fmi_type


def _model_exchange(path, fmi):
    """An initialised model-exchange instance in continuous-time mode, inputs in range."""
    md = read_model_description(str(path))
    cls = FMU2Model if fmi == 2 else FMU3Model
    fmu = cls(guid=md.guid, unzipDirectory=extract(str(path)), modelIdentifier=md.modelExchange.modelIdentifier,
              instanceName="me")
    fmu._test_callbacks = fmi2_callbacks.callbacks() if fmi == 2 else None  # alive as long as the instance
    fmu.instantiate(**({"callbacks": fmu._test_callbacks} if fmi == 2 else {}))
    if fmi == 2:
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
    else:
        fmu.enterInitializationMode(startTime=0.0)
    (fmu.setReal if fmi == 2 else fmu.setFloat64)(IN_VRS, [0.0, 0.1, 0.0, 2.0, 20.0])
    fmu.exitInitializationMode()
    fmu.newDiscreteStates() if fmi == 2 else fmu.updateDiscreteStates()
    fmu.enterContinuousTimeMode()
    return fmu


@pytest.mark.parametrize("fmi", [2, 3])
def test_discrete_outputs_change_only_at_events_in_model_exchange(hybrid_fmus, fmi):
    """status, clamped_mask and envelope_flags are discrete: in continuous-time mode an input
    leaving the training range does not change them; the completed integrator step asks for an
    event, and in event mode they take the new values (status 1, the velocity's bit); with
    nothing changing, no event."""
    fmu = _model_exchange(hybrid_fmus[fmi], fmi)
    get_int = fmu.getInteger if fmi == 2 else fmu.getInt32
    set_real = fmu.setReal if fmi == 2 else fmu.setFloat64
    assert get_int([6, 7, 8]) == [0, 0, 0]
    assert not fmu.completedIntegratorStep()[0]
    set_real([1], [50.0])  # v far outside the training range: clamped
    assert get_int([6, 7, 8]) == [0, 0, 0]  # between events: the last event's values
    enter_event = fmu.completedIntegratorStep()[0]
    assert enter_event
    fmu.enterEventMode()
    fmu.newDiscreteStates() if fmi == 2 else fmu.updateDiscreteStates()
    fmu.enterContinuousTimeMode()
    status, mask, flags = get_int([6, 7, 8])
    v_bit = 1 << HYBRID_FEATURES.index("velocity")
    assert status == 1 and mask & v_bit and flags & 1
    assert not fmu.completedIntegratorStep()[0]
    fmu.terminate()
    fmu.freeInstance()


@pytest.mark.parametrize("fmi", [2, 3])
def test_no_step_after_a_failed_initialisation(hybrid_fmus, fmi):
    """A parameter the runtime refuses fails ExitInitializationMode; a doStep after it is an
    error naming why (as the quarter-car FMU), not a step with the previous parameters."""
    md = read_model_description(str(hybrid_fmus[fmi]))
    messages = []
    cls = FMU2Slave if fmi == 2 else FMU3Slave
    fmu = cls(guid=md.guid, unzipDirectory=extract(str(hybrid_fmus[fmi])), modelIdentifier="dampnet_damper")
    if fmi == 2:
        cb = fmi2_callbacks.callbacks(messages)  # not FMPy's defaults: see fmi2_callbacks
        fmu.instantiate(callbacks=cb)
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.setReal([10], [-1.0])  # control_lag_tau_s (the first feature constant)
    else:
        fmu.instantiate(logMessage=lambda env, status, category, message: messages.append(message.decode()))
        fmu.enterInitializationMode(startTime=0.0)
        fmu.setFloat64([10], [-1.0])
    with pytest.raises(Exception, match=f"fmi{fmi}ExitInitializationMode"):
        fmu.exitInitializationMode()
    with pytest.raises(Exception, match=f"fmi{fmi}DoStep"):
        fmu.doStep(0.0, 1e-3)
    assert any(f"fmi{fmi}DoStep: the FMU is not initialized (fmi{fmi}ExitInitializationMode failed)" in m
               for m in messages), messages
    fmu.freeInstance()


# ---- the inverse: force_demand in, u_command, inverse_status and force_at_command out ----

def _co_simulation(path, messages=None, start=None):
    """An initialised co-simulation instance (FMI 2 or 3, from the file) and its typed accessors
    (set_real, get_real, get_int); messages collects the FMU's logged messages; start: the
    inputs x, v, a, u, temperature at initialisation (the states start at rest there)."""
    md = read_model_description(str(path))
    fmi2 = md.fmiVersion == "2.0"
    fmu = (FMU2Slave if fmi2 else FMU3Slave)(guid=md.guid, unzipDirectory=extract(str(path)),
                                             modelIdentifier="dampnet_damper", instanceName="inverse")
    if fmi2:
        fmu._test_callbacks = fmi2_callbacks.callbacks(messages)  # alive as long as the instance
        fmu.instantiate(callbacks=fmu._test_callbacks)
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
    else:
        if messages is not None:
            fmu.instantiate(logMessage=lambda env, status, category, message: messages.append(message.decode()))
        else:
            fmu.instantiate()
        fmu.enterInitializationMode(startTime=0.0)
    if start is not None:
        (fmu.setReal if fmi2 else fmu.setFloat64)(IN_VRS, list(start))
    fmu.exitInitializationMode()
    if fmi2:
        return fmu, fmu.setReal, fmu.getReal, fmu.getInteger
    return fmu, fmu.setFloat64, fmu.getFloat64, fmu.getInt32


def _inverse_grid(damper):
    """Motion points (x, v, a, temperature: both signs of v, in the default model's range and
    beyond it) and at each demands inside [F(u_min), F(u_max)] (its ends and 0.1 .. 0.9 of it)
    and 200 N outside it on either side; -Inf and +Inf for the first two."""
    lo, hi = damper.control_range()
    x, v, a, temp = (q.ravel() for q in np.meshgrid([-0.02, 0.03], np.r_[np.linspace(-0.6, 0.6, 13), -3.0, 3.0],
                                                    [0.0, 4.0], [20.0, 45.0], indexing="ij"))
    z = np.zeros(x.size)
    f_lo = damper.forces(x, v, a, np.full(x.size, lo), z, temp)[0]
    f_hi = damper.forces(x, v, a, np.full(x.size, hi), z, temp)[0]
    f_min, f_max = np.minimum(f_lo, f_hi), np.maximum(f_lo, f_hi)
    shares = [0.0, 0.1, 0.3, 0.5, 0.7, 0.9, 1.0]
    demand = np.stack([f_min + s * (f_max - f_min) for s in shares] + [f_min - 200.0, f_max + 200.0], axis=1)
    x, v, a, temp = (np.repeat(q, demand.shape[1]) for q in (x, v, a, temp))
    demand = demand.ravel()
    demand[:2] = -np.inf, np.inf
    return x, v, a, temp, demand, (lo, hi)


@pytest.mark.parametrize("fmi", [2, 3])
def test_the_inverse_equals_the_hosts(default_fmus, fmi):
    """The default model's damper FMU (co-simulation) at 1080 points (both velocity signs,
    velocities beyond the training range: DN_W_SATURATED; demands inside [F(u_min), F(u_max)],
    on its ends, 200 N outside it: DN_W_UNREACHABLE, and +-Inf) gives the host's Damper.inverse:
    u_command to 1e-9 of the control range, inverse_status equal, force_at_command the host's
    force to 1e-9 N; the u input set to u_command gives the demanded force where it is reachable
    (to the inverse's tolerance: its control within DN_INVERSE_TOL_REL of the range), and force_at_command everywhere, and leaves u_command as it was. The
    description documents the status codes the inverse gives and declares the inverse's outputs
    independent of u (ModelStructure dependencies: wiring u_command into u is no algebraic
    loop). About 0.1 s (the FMU: the module's default_fmus)."""
    damper = damper_from_model(default_model())
    x, v, a, temp, demand, (lo, hi) = _inverse_grid(damper)
    u_ref, f_ref, st_ref, _ = damper.inverse(demand, x, v, a, np.zeros(x.size), temp)
    fmu, set_real, get_real, get_int = _co_simulation(default_fmus[fmi])
    n = x.size
    u, f_cmd, f_at_u, st = np.empty(n), np.empty(n), np.empty(n), np.empty(n, dtype=int)
    for k in range(n):
        set_real([0, 1, 2, 4, VR_DEMAND], [x[k], v[k], a[k], temp[k], demand[k]])
        u[k], f_cmd[k] = get_real([VR_U_COMMAND, VR_INV_FORCE])
        st[k] = get_int([VR_INV_STATUS])[0]
        set_real([3], [u[k]])
        f_at_u[k] = get_real([VR_FORCE])[0]
        assert get_real([VR_DEMAND, VR_U_COMMAND]) == [demand[k], u[k]]
    fmu.terminate()
    fmu.freeInstance()
    np.testing.assert_allclose(u, u_ref, rtol=0, atol=1e-9 * (hi - lo))
    np.testing.assert_array_equal(st, st_ref)
    np.testing.assert_allclose(f_cmd, f_ref, rtol=0, atol=1e-9)
    reach = (st & _core.DN_W_UNREACHABLE) == 0
    assert 0.5 < reach.mean() < 0.9 and np.any(st == _core.DN_W_SATURATED), reach.mean()
    assert np.any(st == _core.DN_W_SATURATED | _core.DN_W_UNREACHABLE) and set(np.unique(st)) <= {0, 1, 16, 17}
    assert np.all(u >= lo) and np.all(u <= hi) and np.all(np.isin(u[~reach], [lo, hi]))
    # the inverse's contract: the control within DN_INVERSE_TOL_REL of the range of the root
    allow = inverse_allowance(damper, u[reach], {"x": x[reach], "v": v[reach], "a": a[reach], "u_lag": 0.0,
                                                 "temperature": temp[reach]})
    assert np.all(np.abs(f_at_u[reach] - demand[reach]) <= 1.01 * allow + 1e-9)
    np.testing.assert_allclose(f_at_u, f_cmd, rtol=0, atol=1e-9)
    md = read_model_description(str(default_fmus[fmi]))
    doc = next(sv for sv in md.modelVariables if sv.name == "inverse_status").description
    assert {int(c) for c in re.findall(r"(-?\d+) \(DN_", doc)} == {0, 1, 16, -8, -10, -7}, doc
    deps = {o.variable.name: o.dependencies for o in md.outputs}
    for name in ("u_command", "inverse_status", "force_at_command"):
        assert [d.name for d in deps[name]] == ["x", "v", "a", "temperature", "force_demand"], name
    assert deps["force"] is None  # the force depends on everything


@pytest.mark.parametrize("fmi", [2, 3])
def test_the_inverse_is_computed_once_a_point_and_again_when_anything_it_reads_changes(default_fmus, fmi):
    """The FMU keeps its last inverse (u_command, force_at_command and inverse_status are read at
    one point: one inverse for the three) and computes it again when any input it reads changes:
    from one point, each of x, v, a, temperature and force_demand changed alone (and the u input,
    which it ignores) gives the host's Damper.inverse at the new point, read before and after the
    other two outputs; a communication step (the states and time move) too. About 0.05 s."""
    damper = damper_from_model(default_model())
    base = {"x": 0.01, "v": 0.25, "a": 1.0, "temperature": 20.0, "demand": 900.0}
    vr = {"x": 0, "v": 1, "a": 2, "temperature": 4, "demand": VR_DEMAND}
    fmu, set_real, get_real, get_int = _co_simulation(default_fmus[fmi])

    def host(p):
        u, f, st, _ = damper.inverse(p["demand"], p["x"], p["v"], p["a"], 0.0, p["temperature"])
        return u[0], f[0], st[0]

    set_real([vr[k] for k in base], list(base.values()))
    first = get_real([VR_U_COMMAND, VR_INV_FORCE]) + [get_int([VR_INV_STATUS])[0]]
    assert first == pytest.approx(host(base), abs=1e-9)
    for field, moved in (("x", -0.01), ("v", 0.4), ("a", -3.0), ("temperature", 40.0), ("demand", 1400.0)):
        p = dict(base, **{field: moved})
        set_real([vr[field]], [moved])
        ref = host(p)
        if field in ("v", "a", "demand"):  # (the default model reads neither x nor the temperature)
            assert ref[0] != pytest.approx(first[0], abs=1e-6), field  # the answer moves
        assert get_int([VR_INV_STATUS])[0] == ref[2]
        assert get_real([VR_U_COMMAND, VR_INV_FORCE]) == pytest.approx(ref[:2], abs=1e-9), field
        assert get_real([VR_INV_FORCE, VR_U_COMMAND]) == pytest.approx(ref[1::-1], abs=1e-9), field
        set_real([3], [2.0])  # u: not read by the inverse
        assert get_real([VR_U_COMMAND]) == pytest.approx([ref[0]], abs=1e-9), field
        set_real([vr[field]], [base[field]])
        assert get_real([VR_U_COMMAND]) == pytest.approx([first[0]], abs=1e-9), field
    fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=1e-3)
    assert get_real([VR_U_COMMAND, VR_INV_FORCE]) == pytest.approx(host(base)[:2], abs=1e-9)
    fmu.terminate()
    fmu.freeInstance()


@pytest.mark.parametrize("fmi", [2, 3])
def test_the_inverse_without_a_control_input_and_on_errors(default_fmus, hybrid_fmus, fmi):
    """A model without a control input (the hybrid model reads voltage_lag, not u: the runtime's
    control_range is DN_E_MISMATCH) loads and runs: u_command 0, inverse_status -8 and
    force_at_command the force at u = 0, no error. A NaN demand: inverse_status -10 and reading
    u_command fails with a message naming it (the force still reads). About 0.05 s."""
    fmu, set_real, get_real, get_int = _co_simulation(hybrid_fmus[fmi])
    set_real([1, 3, VR_DEMAND], [0.3, 2.0, 500.0])
    u, f_cmd = get_real([VR_U_COMMAND, VR_INV_FORCE])
    assert u == 0.0 and get_int([VR_INV_STATUS]) == [_core.DN_E_MISMATCH]
    set_real([3], [0.0])
    assert f_cmd == get_real([VR_FORCE])[0]
    fmu.doStep(0.0, 1e-3)  # the run goes on
    fmu.terminate()
    fmu.freeInstance()

    messages = []
    fmu, set_real, get_real, get_int = _co_simulation(default_fmus[fmi], messages)
    set_real([1, VR_DEMAND], [0.1, float("nan")])
    assert get_int([VR_INV_STATUS]) == [_core.DN_E_NONFINITE_INPUT]
    assert np.isfinite(get_real([VR_FORCE])[0])
    with pytest.raises(Exception):
        get_real([VR_U_COMMAND])
    assert any("u_command cannot be evaluated" in m and "force_demand = nan" in m for m in messages), messages
    fmu.freeInstance()


@pytest.mark.parametrize("fmi", [2, 3])
def test_the_inverse_in_model_exchange(default_fmus, fmi):
    """Model exchange: u_command is continuous (the host's inverse at the inputs as soon as
    they are set), inverse_status discrete: it keeps the last event's value until the completed
    integrator step asks for an event, and takes the new one in event mode. About 0.05 s."""
    damper = damper_from_model(default_model())
    fmu = _model_exchange(default_fmus[fmi], fmi)  # x 0, v 0.1, a 0, u 2, temperature 20; demand 0
    get_int = fmu.getInteger if fmi == 2 else fmu.getInt32
    set_real = fmu.setReal if fmi == 2 else fmu.setFloat64
    get_real = fmu.getReal if fmi == 2 else fmu.getFloat64

    def host(demand):
        u, _f, st, _n = damper.inverse(demand, 0.0, 0.1, 0.0, 0.0, 20.0)
        return float(u[0]), int(st[0])

    assert get_int([VR_INV_STATUS]) == [host(0.0)[1]] and not fmu.completedIntegratorStep()[0]
    lo, hi = damper.control_range()
    f_lo, f_hi = damper.forces(0.0, 0.1, 0.0, [lo, hi], 0.0, 20.0)[0]
    changed = 0
    for demand in (0.5 * (f_lo + f_hi), max(f_lo, f_hi) + 300.0, min(f_lo, f_hi) - 300.0):
        before = get_int([VR_INV_STATUS])[0]
        set_real([VR_DEMAND], [demand])
        u, st = host(demand)
        assert get_real([VR_U_COMMAND])[0] == pytest.approx(u, abs=1e-9 * (hi - lo))
        assert get_int([VR_INV_STATUS]) == [before]  # between events: the last event's value
        assert fmu.completedIntegratorStep()[0] == (st != before)
        changed += st != before
        fmu.enterEventMode()
        fmu.newDiscreteStates() if fmi == 2 else fmu.updateDiscreteStates()
        fmu.enterContinuousTimeMode()
        assert get_int([VR_INV_STATUS]) == [st] and not fmu.completedIntegratorStep()[0]
    assert changed >= 1
    fmu.terminate()
    fmu.freeInstance()


def test_the_inverse_reads_the_forces_states(tmp_path, rig_signals):
    """A model with a control input and the three states (control lag, velocity lag, Dahl
    friction), FMI 3 co-simulation driven over the recorded rig test: at every communication
    point u_command and inverse_status equal the host's Damper.inverse on the reference loop's
    states (those of the force, advanced to the point), u to 1e-9 of the control range; with the
    states replaced by their inputs the controls differ; a new u set before the step leaves
    u_command as it was (the control lag holds the step's first u). One FMU build: about 3 s."""
    t, x, v, a, u = rig_signals
    model = random_model(["velocity", "acceleration", "voltage", "voltage_lag", "velocity_lag", "friction_state",
                          "displacement"], hidden=9, seed=7, feature_params=HYBRID_PARAMS)
    path = build_fmu(model, tmp_path / "states3.fmu", fmi=3, interface="cs")
    damper = damper_from_model(model)
    lo, hi = damper.control_range()
    s = reference_states(model, t, x, v, u)
    temp = np.full(t.size, 20.0)
    f_lo, f_hi = (damper.forces(x, v, a, np.full(t.size, c), s["u_lag"], temp, s["v_lag"], s["z_fric"])[0]
                  for c in (lo, hi))
    demand = f_lo + (f_hi - f_lo) * (0.5 + 0.8 * np.sin(2 * np.pi * 9.0 * t))  # reachable and not, in turns
    u_ref, _f, st_ref, _n = damper.inverse(demand, x, v, a, s["u_lag"], temp, s["v_lag"], s["z_fric"])
    fmu, set_real, get_real, get_int = _co_simulation(path, start=[x[0], v[0], a[0], u[0], 20.0])
    dt = float(t[1] - t[0])
    u_fmu, st_fmu = np.empty(t.size), np.empty(t.size, dtype=int)
    for k in range(t.size):
        set_real(IN_VRS + [VR_DEMAND], [x[k], v[k], a[k], u[k], 20.0, demand[k]])
        u_fmu[k] = get_real([VR_U_COMMAND])[0]
        st_fmu[k] = get_int([VR_INV_STATUS])[0]
        if k % 50 == 0:
            set_real([3], [5.0 - u[k]])
            assert get_real([VR_U_COMMAND])[0] == u_fmu[k]
            set_real([3], [u[k]])
        fmu.doStep(k * dt, dt)
    fmu.terminate()
    fmu.freeInstance()
    reach = (st_ref & _core.DN_W_UNREACHABLE) == 0
    assert 0.2 < reach.mean() < 0.95, reach.mean()
    np.testing.assert_array_equal(st_fmu, st_ref)
    np.testing.assert_allclose(u_fmu, u_ref, rtol=0, atol=1e-9 * (hi - lo))
    u_stateless = damper.inverse(demand, x, v, a, u, temp, v, np.sign(v))[0]
    assert np.max(np.abs(u_stateless - u_ref)[reach]) > 0.01 * (hi - lo)
