"""`dampnet export --fmu`: the damper as an FMI 2.0 FMU (co-simulation and model exchange), checked by an independent
importer (FMPy): no validation problems, a binary needing only libc and libm, and FMPy's
simulation of a recorded rig test equal to the runtime's Damper.forces to 1e-9 N."""

import subprocess
import zipfile

import numpy as np
import pytest
from fmpy import simulate_fmu
from fmpy.validation import validate_fmu

from dampnet.cli import main
from dampnet.fmu import FmuError, build_damper_fmu
from dampnet.modeldir import default_model, save_model_dir
from dampnet.rig import generate
from dampnet.sim.loop import damper_from_model
from loop_helpers import random_model


@pytest.fixture(scope="module")
def rig_signals():
    """A recorded quick-plan rig test (0.4 s at 5 kHz): x, v, a (the velocity's gradient), u."""
    test = generate("quick", seed=0, progress=False).tests[3]
    k = slice(0, 2000)
    t, v = test.time[k] - test.time[0], test.channels["velocity"][k]
    return t, test.channels["displacement"][k], v, np.gradient(v, t), test.control[k]


def _simulate(path, t, x, v, a, u, temperature=None):
    names = ["x", "v", "a", "u"] + (["temperature"] if temperature is not None else [])
    sig = np.zeros(t.size, dtype=[("time", float)] + [(n, float) for n in names])
    sig["time"], sig["x"], sig["v"], sig["a"], sig["u"] = t, x, v, a, u
    if temperature is not None:
        sig["temperature"] = temperature
    dt = float(t[1] - t[0])
    return simulate_fmu(str(path), start_time=0.0, stop_time=float(t[-1]), step_size=dt, output_interval=dt, input=sig,
                        output=["force", "status"], fmi_type="CoSimulation")


@pytest.mark.parametrize("which", ["default", "hybrid"])
def test_fmpy_validates_and_simulates_the_damper_fmu(tmp_path, rig_signals, which):
    """FMPy: validate_fmu finds no problem; its co-simulation of a recorded rig test gives the
    runtime's forces to 1e-9 N (FMPy records the output at t_k after the step from t_k-1, with
    the inputs of t_k-1: the force of sample k-1). The plain 3-30-1 model and a hybrid one
    (five features, a gas term and a bump stop)."""
    t, x, v, a, u = rig_signals
    if which == "default":
        model, temp = default_model(), None
    else:
        model = random_model(["velocity", "acceleration", "voltage", "displacement", "temperature"], hidden=9, seed=2,
                             terms=[{"kind": "position_poly", "params": [-150.0, 3000.0, 1e4, 0.0]},
                                    {"kind": "bump_stop", "params": [0.01, 2e5, 1.5]}])
        temp = 20.0 + 10.0 * np.sin(3.0 * t)
    path = build_damper_fmu(model, tmp_path / "d.fmu")
    assert validate_fmu(str(path)) == []
    res = _simulate(path, t, x, v, a, u, temp)
    f, status, _ = damper_from_model(model).forces(x, v, a, u, u, 20.0 + 0 * t if temp is None else temp)
    assert np.all(status >= 0) and np.all(res["status"] >= 0)
    n = len(res)
    assert n == t.size and np.ptp(f) > 100.0
    np.testing.assert_allclose(res["force"][1:], f[: n - 1], rtol=0, atol=1e-9)
    assert res["force"][0] == pytest.approx(f[0], abs=1e-9)


def test_the_fmu_binary_needs_only_libc_and_libm(tmp_path):
    path = build_damper_fmu(default_model(), tmp_path / "d.fmu")
    with zipfile.ZipFile(path) as z:
        names = set(z.namelist())
        z.extractall(tmp_path / "x")
    assert {"modelDescription.xml", "binaries/linux64/dampnet_damper.so", "sources/fmu2.cpp",
            "sources/fmu_model.h", "sources/fmi2Functions.h"} <= names
    ldd = subprocess.run(["ldd", str(tmp_path / "x/binaries/linux64/dampnet_damper.so")], capture_output=True,
                         text=True).stdout
    libs = {line.split()[0] for line in ldd.splitlines() if line.strip()}
    assert libs <= {"linux-vdso.so.1", "libm.so.6", "libc.so.6", "/lib64/ld-linux-x86-64.so.2"}, ldd
    assert "libstdc++" not in ldd


def test_export_fmu_command_and_its_errors(tmp_path, capsys, monkeypatch):
    save_model_dir(default_model(), None, tmp_path / "model")
    out = tmp_path / "d.fmu"
    assert main(["export", str(tmp_path / "model"), "--fmu", str(out)]) == 0
    assert "FMI 2.0 FMU dampnet_damper" in capsys.readouterr().out and zipfile.is_zipfile(out)
    assert main(["export", str(tmp_path / "model"), "--fmu", str(out)]) == 2  # exists
    assert "refusing to overwrite" in capsys.readouterr().err
    # a model with a feature the FMU cannot feed
    lagged = random_model(["velocity", "voltage_lag"], seed=1, feature_params={"control_lag_tau_s": 0.02})
    save_model_dir(lagged, None, tmp_path / "lagged")
    assert main(["export", str(tmp_path / "lagged"), "--fmu", str(tmp_path / "l.fmu")]) == 2
    assert "cannot feed feature(s) voltage_lag" in capsys.readouterr().err
    # no compiler: one line, nothing written
    monkeypatch.setenv("CXX", str(tmp_path / "no-such-compiler"))
    assert main(["export", str(tmp_path / "model"), "--fmu", str(tmp_path / "c.fmu")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("dampnet: error: ") and not (tmp_path / "c.fmu").exists()
    assert not list(tmp_path.glob(".dampnet-fmu-*"))
    with pytest.raises(FmuError, match="cannot feed"):
        build_damper_fmu(lagged, tmp_path / "z.fmu")


def test_model_exchange_follows_co_simulation(tmp_path, rig_signals):
    """The same FMU imported for model exchange (no continuous states: FMPy's solver only
    advances time and samples the outputs) gives the co-simulation's forces."""
    t, x, v, a, u = rig_signals
    path = build_damper_fmu(default_model(), tmp_path / "d.fmu")
    cs = _simulate(path, t, x, v, a, u)
    names = ["x", "v", "a", "u"]
    sig = np.zeros(t.size, dtype=[("time", float)] + [(n, float) for n in names])
    sig["time"], sig["x"], sig["v"], sig["a"], sig["u"] = t, x, v, a, u
    dt = float(t[1] - t[0])
    me = simulate_fmu(str(path), start_time=0.0, stop_time=float(t[-1]), step_size=dt, output_interval=dt,
                      input=sig, output=["force"], fmi_type="ModelExchange", solver="Euler")
    f = damper_from_model(default_model()).forces(x, v, a, u, u, np.full(t.size, 20.0))[0]
    assert len(me) == len(cs)
    # model exchange samples the outputs with the inputs of the same instant (no step delay;
    # FMPy interpolates the inputs at its own float times: 7e-11 N measured)
    np.testing.assert_allclose(me["force"], f, rtol=0, atol=1e-9)
    np.testing.assert_allclose(cs["force"][1:], me["force"][:-1], rtol=0, atol=1e-9)
