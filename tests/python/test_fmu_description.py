"""What the FMUs' modelDescription.xml declares, checked against the XML itself and against the
FMU's own behaviour (issue 29): every Real variable with a physical dimension has a unit, every
unit used is defined (a state derivative's base units are its state's per second); every
parameter the runtime limits has min/max, and the FMU refuses a value just outside each bound
and accepts one just inside; the choice parameters are FMI Enumerations of the runtime's names
(FMI 3: set as Int64); the status codes documented are the ones the FMU gives; the quarter car's
default experiment follows its dt and runs in FMPy as it is."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest

import fmi2_callbacks
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave

from dampnet import _core
from dampnet.export.fmu import build_fmu
from dampnet.export.fmu.damper import damper_description
from dampnet.export.fmu.description import model_description
from dampnet.export.fmu.quarter_car import quarter_car_description
from dampnet.modeldir import default_model
from test_export_fmu import hybrid_model

#: the parameters the runtime refuses outside a range of their own (its docs in dampnet.h and
#: its checks: cpp/include/dampnet/loop.hpp, damper.hpp, terms.hpp); the others are unbounded
#: or bounded only by another parameter (u_min <= u_max, c_min < c_max)
RANGED = {"m_s", "m_us", "k_s", "k_t", "c_t", "dt", "c_sky", "c_gnd", "u_tau_s", "control_lag_tau_s",
          "velocity_lag_tau_s", "friction_presliding_m", "bump_stop_1.x_free", "bump_stop_1.k", "bump_stop_1.n"}
#: the Real variables without a physical dimension: the Dahl state, a bump stop's exponent
DIMENSIONLESS = {"z_fric", "bump_stop_1.n", "alpha"}  # alpha: hybrid_force's skyhook share [-]
#: the Enumeration parameters and the runtime's name tables
ENUMERATIONS = {"integrator": _core.INTEGRATORS, "damper_eval": _core.DAMPER_EVALS,
                "accel_feature": _core.ACCEL_FEATURES, "kind": _core.CONTROLLER_KINDS}
DT = 0.002  # the quarter car's step here: not the default 1 ms
#: a vehicle slow enough for any step (w_hop^2 = k_s/m_s + (k_s + k_t)/m_us = 1e-12 s^-2), so that
#: the step's stability limit (a joint condition of dt, masses and stiffnesses: dampnet.h's dt)
#: does not decide a probe near one field's own bound
SLOW_VEHICLE = {"m_s": 1.0, "m_us": 1.0, "k_s": 0.0, "k_t": 1e-12}


def descriptions() -> dict[str, str]:
    """The XML of the hybrid model's damper (both interfaces) and quarter car (dt = DT), FMI 2 and 3."""
    model = hybrid_model()
    damper = damper_description(model)
    qc = quarter_car_description(model, vehicle={"dt": DT})
    return {f"{what}{fmi}": model_description(d, fmi, None) for what, d in (("damper", damper), ("qc", qc))
            for fmi in (2, 3)}


def variables(xml: str) -> dict[str, dict]:
    """name -> {type, unit, min, max, start, declaredType, derivative, vr} of either standard."""
    root = ET.fromstring(xml)
    out = {}
    if root.get("fmiVersion") == "2.0":
        svs = root.find("ModelVariables").findall("ScalarVariable")
        for sv in svs:
            typed = sv[0]
            out[sv.get("name")] = {**typed.attrib, "type": typed.tag, "vr": sv.get("valueReference"),
                                   "causality": sv.get("causality")}
        for v in out.values():  # FMI 2 refers to the state by its 1-based index
            if "derivative" in v:
                v["derivative"] = svs[int(v["derivative"]) - 1].get("name")
    else:
        for el in root.find("ModelVariables"):
            out[el.get("name")] = {**el.attrib, "type": {"Float64": "Real", "Int32": "Integer"}.get(el.tag, el.tag),
                                   "vr": el.get("valueReference")}
        by_vr = {v["vr"]: name for name, v in out.items()}
        for v in out.values():
            if "derivative" in v:
                v["derivative"] = by_vr[v["derivative"]]
    return out


def base_units(xml: str) -> dict[str, dict[str, float]]:
    """Unit name -> its SI base-unit exponents (and offset/factor) as declared."""
    root = ET.fromstring(xml)
    units = {}
    for u in root.find("UnitDefinitions"):
        b = u.find("BaseUnit")
        units[u.get("name")] = {k: float(x) for k, x in (b.attrib.items() if b is not None else ())}
    return units


@pytest.mark.parametrize("which", ["damper2", "damper3", "qc2", "qc3"])
def test_units_declared_and_defined(which, tmp_path):
    """FMPy's schema validation passes; every Real with a dimension has a unit (der(u_lag) V/s,
    position_poly p2, p3 N/m2, N/m3, bump_stop k N/m^n among them), every unit is defined, and
    a derivative's base units are its state's per second."""
    xml = descriptions()[which]
    (tmp_path / "modelDescription.xml").write_text(xml)
    read_model_description(str(tmp_path / "modelDescription.xml"), validate=True)  # the FMI XSD
    vs, units = variables(xml), base_units(xml)
    unitless = {n for n, v in vs.items() if v["type"] == "Real" and not v.get("unit")}
    assert unitless <= DIMENSIONLESS, unitless
    assert {v["unit"] for v in vs.values() if v.get("unit")} <= set(units)
    assert vs["position_poly_0.p2"]["unit"] == "N/m2" and vs["position_poly_0.p3"]["unit"] == "N/m3"
    assert units["N/m2"] == {"kg": 1, "m": -1, "s": -2} and units["N/m3"] == {"kg": 1, "m": -2, "s": -2}
    assert vs["bump_stop_1.k"]["unit"] == "N/m^n"
    derivs = {n: v for n, v in vs.items() if "derivative" in v}
    assert bool(derivs) == which.startswith("damper")
    for name, v in derivs.items():
        state = vs[v["derivative"]].get("unit")
        expected = dict(units[state]) if state else {}
        expected["s"] = expected.get("s", 0) - 1
        assert units[v["unit"]] == {k: x for k, x in expected.items() if x}, name
    if derivs:
        assert vs["der(u_lag)"]["unit"] == "V/s"


@pytest.mark.parametrize("which", ["damper2", "damper3", "qc2", "qc3"])
def test_ranges_and_enumerations_declared(which):
    """min/max on exactly the parameters the runtime limits (min <= start <= max); the choice
    parameters are Enumerations of the runtime's names and values, no longer plain integers."""
    xml = descriptions()[which]
    vs = variables(xml)
    bounded = {n for n, v in vs.items() if "min" in v or "max" in v}
    expected = {n for n in RANGED if n in vs}
    assert bounded == expected
    assert expected >= ({"dt", "m_s", "c_sky"} if which.startswith("qc") else {"control_lag_tau_s", "bump_stop_1.n"})
    for n in bounded:
        v = vs[n]
        assert float(v.get("min", "-inf")) <= float(v["start"]) <= float(v.get("max", "inf")), n
    if which.startswith("qc"):
        assert float(vs["dt"]["min"]) == 1e-9 and float(vs["dt"]["max"]) == 0.1
        root = ET.fromstring(xml)
        for name, table in ENUMERATIONS.items():
            v = vs[name]
            assert v["type"] == "Enumeration", name
            items = root.findall(f".//*[@name='{v['declaredType']}']//Item")
            assert {i.get("name"): int(i.get("value")) for i in items} == {k: t[0] for k, t in table.items()}
        assert not [n for n, v in vs.items() if v["type"] == "Integer" and v["causality"] == "parameter"]


def documented_codes(text: str) -> set[int]:
    """The status codes a status description lists ("CODE (NAME: ...)")."""
    import re

    return {int(c) for c in re.findall(r"(-?\d+) \(DN_", text)}


def test_the_damper_status_codes_documented_are_the_real_ones(tmp_path):
    """The damper FMU documents 0, 1, -10 and -7 (not the "2 a NaN input replaced" it never
    gives) and gives each: in range, a clamped input, a NaN input, a term overflowing."""
    path = build_fmu(hybrid_model(), tmp_path / "d.fmu", fmi=2, interface="cs")
    md = read_model_description(str(path))
    status = next(v for v in md.modelVariables if v.name == "status")
    assert documented_codes(status.description) == {0, 1, -10, -7}, status.description
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(path)), modelIdentifier="dampnet_damper")
    cb = fmi2_callbacks.callbacks()  # not FMPy's defaults (fmi2_callbacks); alive until freed
    fmu.instantiate(callbacks=cb)
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    seen = {}
    for label, x, v in (("ok", 0.0, 0.1), ("clamped", 0.0, 50.0), ("nan", 0.0, np.nan), ("overflow", 1e300, 0.1)):
        fmu.setReal([0, 1], [x, v])
        seen[label] = fmu.getInteger([6])[0]
    fmu.terminate()
    fmu.freeInstance()
    assert seen == {"ok": 0, "clamped": _core.DN_W_SATURATED, "nan": _core.DN_E_NONFINITE_INPUT,
                    "overflow": _core.DN_E_NONFINITE_OUTPUT}
    # the quarter car: a loop step's warnings (OR-ed) and errors, no "NaN replaced" (2) either
    qc = ET.fromstring(descriptions()["qc2"]).find(".//ScalarVariable[@name='status']").get("description")
    assert documented_codes(qc) == {0, 1, 4, 8, -10, -11}, qc


@pytest.fixture(scope="module")
def quarter_car3(tmp_path_factory):
    """The hybrid model's quarter car, FMI 3, dt = DT (its every kind of parameter: vehicle,
    controller, feature constants, term parameters, enumerations)."""
    return build_fmu(hybrid_model(), tmp_path_factory.mktemp("qc") / "qc.fmu", fmi=3, what="quarter-car",
                     vehicle={"dt": DT})


def probe(path):
    """A function (name, value) -> None if the FMU initialises with that parameter value (a
    vehicle field's on SLOW_VEHICLE), else the error it logged (one FMI 3 instance, reset
    between calls)."""
    md = read_model_description(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    kinds = {v.name: v.type for v in md.modelVariables}
    log = []
    fmu = FMU3Slave(guid=md.guid, unzipDirectory=extract(str(path)), modelIdentifier=md.coSimulation.modelIdentifier)
    fmu.instantiate(logMessage=lambda env, status, category, message: log.append(message.decode()))

    def run(name, value):
        log.clear()
        fmu.reset()
        fmu.enterInitializationMode(startTime=0.0)
        if name in _core.VEHICLE_FIELDS:
            fmu.setFloat64([vr[n] for n in SLOW_VEHICLE], list(SLOW_VEHICLE.values()))
        (fmu.setInt64 if kinds[name] == "Enumeration" else fmu.setFloat64)([vr[name]], [value])
        try:
            fmu.exitInitializationMode()
        except Exception:
            return " ".join(log) or "refused"
        return None

    return run


def test_every_bound_is_the_runtimes(quarter_car3):
    """For each declared min/max: a value just outside is refused at initialisation (the message
    naming the parameter), a value just inside is accepted (a vehicle field's with the others
    of a slow vehicle: the step's stability limit is a condition of several fields). The
    runtime's own checks decide (loop.hpp's check_vehicle/check_controller, the damper's
    feature and term checks)."""
    md = read_model_description(str(quarter_car3))
    run = probe(quarter_car3)
    checked = set()
    for v in md.modelVariables:
        for bound, outward in ((v.min, -1.0), (v.max, 1.0)):
            if bound is None:
                continue
            b = float(bound)
            step = abs(b) * 1e-6 if b else 1e-12
            refused = run(v.name, b + outward * step)
            assert refused and f"parameter {v.name} = " in refused, (v.name, b, refused)
            assert run(v.name, b - outward * step) is None, (v.name, b)
            checked.add(v.name)
    assert checked == RANGED
    # the enumerations: an item is accepted, a value that is none is refused naming the field
    assert run("kind", 2) is None and run("integrator", 1) is None
    past = max(v for v, _ in _core.CONTROLLER_KINDS.values()) + 1   # one past the last law
    refused = run("kind", past)
    assert refused and f"kind = {past}" in refused and "skyhook_onoff=1" in refused


def test_the_quarter_cars_default_experiment_follows_dt_and_runs(tmp_path):
    """stepSize and fixedInternalStepSize are the dt compiled in; FMPy's run with all its
    defaults (10 s; its interval dt doubled while beyond 1000 points: 8 dt here) runs (the
    default model: the hybrid one's random network is no physical damper)."""
    path = build_fmu(default_model(), tmp_path / "qc.fmu", fmi=3, what="quarter-car", vehicle={"dt": DT})
    md = read_model_description(str(path))
    assert float(md.defaultExperiment.stepSize) == DT and float(md.coSimulation.fixedInternalStepSize) == DT
    res = simulate_fmu(str(path))
    assert res["time"][-1] == pytest.approx(float(md.defaultExperiment.stopTime))
    assert np.diff(res["time"])[0] == pytest.approx(8 * DT) and np.all(res["status"] >= 0)
