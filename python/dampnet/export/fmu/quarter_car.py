"""The quarter-car FMU's variables (cpp/fmu/fmu_quarter_car.hpp: the same value references).

Co-simulation only. A communication step is n steps of dampnet's quarter-car loop
(cpp/include/dampnet/loop.hpp) at the vehicle's fixed dt (h = n dt; the road inside it the cubic
Hermite interpolant of its two ends, as the loop assumes within a step): a step that is not a
whole multiple of dt is refused with an error naming h and dt.

- inputs (0-2): z_r [m], v_r [m/s], the road at the END of the coming step (t + h, as
  dn_loop_input: an importer that sets the road of the step's start gets the response one step
  late), and u (the 'external' law's control over the coming step);
- outputs at each communication point, all at that instant: the loop state (200 + i,
  DN_LOOP_STATE_LIST order; z_s, v_s, z_us, v_us are outputs, the loop's internal states
  locals), the step quantities of dampnet::forward at the current state (230 + j,
  DN_LOOP_OUT_LIST order: force, control, x, v, a, acc_s, acc_us), suspension travel (240),
  dynamic tyre force (241), status, clamped_mask and envelope_flags (250-252);
- parameters: the vehicle's fields (1000 + i, DN_VEHICLE_FIELDS order) and the controller's
  (1100 + i, DN_CONTROLLER_FIELDS order), enum fields as Enumeration parameters (FMI
  TypeDefinitions from the runtime's lists), and the damper's feature constants and term
  parameters (10 + k, 100 + 10 i + j, as the damper FMU); all fixed, with the ranges the runtime's
  docs state as min/max, validated at initialisation by the runtime's checks.

Importers: run it with a fixed communication step n dt (FMPy's default run of the default
experiment takes 16 dt), and with dt itself and the road fed one sample ahead to get
QuarterCar.simulate's run exactly (see tests/python/test_export_fmu_quarter_car.py). The vehicle's f_static starts at the runtime's
0 N: for a damper with a force at rest (a gas force), set it to that force.

The state and step-report names and docs, like the parameters', are dampnet._core's (expanded
from dampnet.h's X-macro lists, as the C++ side's tables are); the
parameters' start values are compiled into the binary (fmu_config.h: DNFMU_VEHICLE_START,
DNFMU_CONTROLLER_START), and non-default ones give the FMU its own GUID.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

from dampnet import _core
from dampnet.export.header import _package_version
from dampnet.export.fmu.damper import (FmuError, check_model, control_unit, damper_variables, data_label, envelope_doc,
                                status_doc, term_names_config)
from dampnet.export.fmu.description import Description, Variable, range_in, unit_in
from dampnet.model import MlpModel

MODEL_IDENTIFIER = "dampnet_quarter_car"
VR_Z_R, VR_V_R, VR_U, VR_TIME = 0, 1, 2, 9
VR_STATE, VR_OUT, VR_TRAVEL, VR_TYRE, VR_STATUS, VR_MASK, VR_ENVELOPE = 200, 230, 240, 241, 250, 251, 252
VR_VEHICLE, VR_CONTROLLER = 1000, 1100
#: the loop-state columns that are outputs (the others are the loop's internal states: locals)
OUTPUT_STATES = ("z_s", "v_s", "z_us", "v_us")
#: step quantities named otherwise in the FMU ("u" is the input's name; simulate calls it "control")
RENAMED = {"u": "control"}
#: the name tables of the enum (Integer) fields, by the enum type their doc names first
ENUMS = {"dn_integrator": _core.INTEGRATORS, "dn_damper_eval": _core.DAMPER_EVALS,
         "dn_accel_feature": _core.ACCEL_FEATURES, "dn_controller_kind": _core.CONTROLLER_KINDS}
#: the status codes of a loop step and of the evaluation at a communication point (loop.hpp)
LOOP_STATUSES = ("DN_OK", "DN_W_SATURATED", "DN_W_ACCEL_UNCONVERGED", "DN_W_ACCEL_FALLBACK", "DN_E_NONFINITE_INPUT",
                 "DN_E_DIVERGED")
#: the default experiment: 10 s of road, or 10,000 steps when dt is so small that 10 s would take longer
DEFAULT_STOP_S, DEFAULT_STOP_STEPS = 10.0, 10_000


def loop_states() -> list[tuple[str, str]]:
    """The loop's state (DN_LOOP_STATE_LIST, then the damper's DN_DAMPER_STATE_LIST): (name, doc) in order."""
    return list(_core.STATE_DOCS.items())


def loop_outputs() -> list[tuple[str, str]]:
    """DN_LOOP_OUT_LIST: (name, doc) in dn_loop_out order."""
    return list(_core.LOOP_OUT_FIELDS.items())


def _enum_table(doc: str) -> dict | None:
    return ENUMS.get(doc.split(" ")[0])


def _enum_text(doc: str, table: dict) -> str:
    names = "; ".join(f"{name}={value} ({what})" for name, (value, what) in table.items())
    rest = doc.split(" ", 1)[1] if " " in doc else ""
    return f"{doc.split(' ')[0]}{' ' + rest if rest else ''}: {names}"


def _start_values(fields: dict, given: dict | None, what: str, check) -> list[float | int]:
    """The start values of one parameter group in field order: the runtime's defaults with
    `given` on top (enum fields by name or value), validated by the runtime's check."""
    given = dict(given or {})
    unknown = [k for k in given if k not in fields]
    if unknown:
        raise FmuError(f"{what}: unknown parameter(s) {', '.join(map(str, unknown))}; known: {', '.join(fields)}")
    full = {}
    for name, (default, doc) in fields.items():
        value = given.get(name, default)
        table = _enum_table(doc) if isinstance(default, int) else None
        if table is not None and isinstance(value, float) and value.is_integer():
            value = int(value)  # --set integrator=1 arrives as 1.0
        full[name] = value
    try:
        check(full)
    except (TypeError, ValueError) as e:
        raise FmuError(str(e)) from None
    out = []
    for name, (default, doc) in fields.items():
        value = full[name]
        table = _enum_table(doc) if isinstance(default, int) else None
        out.append(int(table[value][0] if isinstance(value, str) else value) if table is not None else float(value))
    return out


def _parameters(fields: dict, starts: list, base: int, u_unit: str | None, group: str) -> list[Variable]:
    out = []
    for i, ((name, (default, doc)), start) in enumerate(zip(fields.items(), starts)):
        if isinstance(default, int):
            table = _enum_table(doc)
            if table is None:
                raise FmuError(f"{group} field {name}: an Integer field whose doc {doc!r} names no known enum")
            items = tuple((item, int(value), what) for item, (value, what) in table.items())
            out.append(Variable(name, base + i, "Enumeration", "parameter", "fixed",
                                f"{group}: {_enum_text(doc, table)}", None, int(start), initial="exact",
                                enum=(doc.split(" ")[0], items)))
        else:
            text, unit = _doc_unit(doc, u_unit)
            lo, hi = range_in(doc, name)
            out.append(Variable(name, base + i, "Real", "parameter", "fixed", f"{group}: {text}", unit, float(start),
                                initial="exact", min=lo, max=hi))
    return out


def _doc_unit(doc: str, u_unit: str | None) -> tuple[str, str | None]:
    """A runtime doc without its [unit] (the description adds the unit), and the unit (V: the
    model's control unit: the loop's control is the damper model's)."""
    unit = unit_in(doc)
    if unit == "V":
        unit = u_unit
    text = re.sub(r"\s*\[[^\]]*\]", "", doc, count=1).strip()
    return text, unit


def quarter_car_variables(model: MlpModel, vehicle: list, controller: list, with_grid: bool = False) -> list[Variable]:
    """The quarter car's variables (vehicle, controller: the start values in field order)."""
    u_unit = control_unit(model)
    v = [Variable("z_r", VR_Z_R, "Real", "input", "continuous",
                  "road displacement from the static equilibrium at the END of the coming step (t + h): set before "
                  "the step from t; the value at initialisation is the road at the start", "m", 0.0),
         Variable("v_r", VR_V_R, "Real", "input", "continuous",
                  "road rate at the END of the coming step (t + h); the loop interpolates the road over the step "
                  "(cubic Hermite)", "m/s", 0.0),
         Variable("u", VR_U, "Real", "input", "continuous",
                  "control over the coming step, for the external controller (kind = external) only; ignored by "
                  "the other laws", u_unit, 0.0)]
    inputs_and_params = {"z_r", "v_r", "u", *_core.VEHICLE_FIELDS, *_core.CONTROLLER_FIELDS}
    for i, (name, doc) in enumerate(loop_states()):
        text, unit = _doc_unit(doc, u_unit)
        out = name in OUTPUT_STATES
        fmu_name = f"loop.{name}" if name in inputs_and_params else name
        v.append(Variable(fmu_name, VR_STATE + i, "Real", "output" if out else "local", "continuous",
                          f"loop state {name}: {text}, at the communication point", unit, initial="calculated"))
    for j, (name, doc) in enumerate(loop_outputs()):
        text, unit = _doc_unit(doc, u_unit)
        if name == "force":
            text = "damper force (model plus terms), positive resisting extension"
        v.append(Variable(RENAMED.get(name, name), VR_OUT + j, "Real", "output", "continuous",
                          f"{text}, at the communication point (what the next step starts with)", unit,
                          initial="calculated"))
    v += [Variable("travel", VR_TRAVEL, "Real", "output", "continuous",
                   "suspension travel z_s - z_us from the static equilibrium, extension positive (the damper "
                   "displacement x is travel + x_static)", "m", initial="calculated"),
          Variable("tyre_force", VR_TYRE, "Real", "output", "continuous",
                   "dynamic tyre force k_t (z_us - z_r) + c_t (v_us - v_r): the part from the static equilibrium "
                   "(the static load (m_s + m_us) g excluded), positive when the tyre unloads (as "
                   "dampnet.sim.ride's dynamic tyre load); the tyre never lifts off in this model", "N",
                   initial="calculated"),
          Variable("status", VR_STATUS, "Integer", "output", "discrete",
                   "dampnet status: the last communication step's (its loop steps' warnings OR-ed) with the "
                   "evaluation at the communication point: 0 ok, > 0 warnings OR-ed, < 0 an error: "
                   + status_doc(LOOP_STATUSES), initial="calculated"),
          Variable("clamped_mask", VR_MASK, "Integer", "output", "discrete",
                   "bit i set: network input i was clamped to its training range at the communication point",
                   initial="calculated"),
          Variable("envelope_flags", VR_ENVELOPE, "Integer", "output", "discrete",
                   "at the communication point, " + envelope_doc(with_grid), initial="calculated")]
    v += _parameters(_core.VEHICLE_FIELDS, vehicle, VR_VEHICLE, u_unit, "vehicle")
    v += _parameters(_core.CONTROLLER_FIELDS, controller, VR_CONTROLLER, u_unit, "controller")
    v += [p for p in damper_variables(model) if p.causality == "parameter"]
    names = [x.name for x in v]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise FmuError(f"quarter-car FMU: variable name(s) {', '.join(dup)} used twice")
    return v


def _c_array(values: list) -> str:
    return "{" + ", ".join(repr(float(x)) for x in values) + "}"


def quarter_car_description(model: MlpModel, vehicle: dict | None = None,
                            controller: dict | None = None, with_grid: bool = False,
                            law: str | None = None) -> Description:
    """The quarter car's Description; vehicle / controller: start values by field name
    (dampnet._core.VEHICLE_FIELDS / CONTROLLER_FIELDS; enum fields by name or value; defaults
    the runtime's: thesis Table 5, passive); law: the control law's registered name, said in the
    description beside the runtime's kind. Refused with FmuError naming the field."""
    check_model(model)
    veh = _start_values(_core.VEHICLE_FIELDS, vehicle, "vehicle", _core.check_vehicle)
    ctrl = _start_values(_core.CONTROLLER_FIELDS, controller, "controller", _core.check_controller)
    defaults = ([_start_values(_core.VEHICLE_FIELDS, None, "vehicle", _core.check_vehicle),
                 _start_values(_core.CONTROLLER_FIELDS, None, "controller", _core.check_controller)])
    guid = f"{model.model_id()}-quarter-car"
    if [veh, ctrl] != defaults:  # another binary (other compiled start values): another token
        guid += "-" + hashlib.sha256(repr((veh, ctrl)).encode()).hexdigest()[:12]
    dt = float(veh[list(_core.VEHICLE_FIELDS).index("dt")])
    kind_value = ctrl[list(_core.CONTROLLER_FIELDS).index("kind")]
    kind = next(name for name, (value, _) in _core.CONTROLLER_KINDS.items() if value == kind_value)
    text = (f"dampnet quarter car (2-DOF, thesis Table 5 defaults; fixed step dt = {dt:g} s, communication steps "
            f"n dt, co-simulation only; road inputs are the road at the end of each step) with damper model "
            f"{model.model_id()}: a "
            f"{model.n_inputs}-input MLP on {', '.join(model.features)}"
            + (f" plus {len(model.terms)} physics term(s)" if model.terms else "")
            + f"; trained on {data_label(model)}; controller {kind}"
            + (f" (control law {law}, calibrated on this damper)" if law else ""))
    return Description(
        MODEL_IDENTIFIER, guid, text, f"dampnet {_package_version()}",
        quarter_car_variables(model, veh, ctrl, with_grid), step_s=dt, stop_s=min(DEFAULT_STOP_S, DEFAULT_STOP_STEPS * dt),
        time_vr=VR_TIME, co_simulation_only=True, fixed_step=True,
        config_lines=(f"#define DNFMU_VEHICLE_START {_c_array(veh)}",
                      f"#define DNFMU_CONTROLLER_START {_c_array(ctrl)}", *term_names_config(model)))
