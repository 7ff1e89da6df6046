"""The damper FMU's variables (cpp/fmu/fmu_damper.hpp: the same value references).

Inputs x [m], v [m/s], a [m/s2], u (the model's control unit), temperature [degC]; outputs
force [N], status, clamped_mask, envelope_flags; the inverse (value references 30-33): input
force_demand [N], outputs u_command (the control at which the force equals the demand),
inverse_status, force_at_command [N]; parameters: the model's feature constants (lags, pre-sliding
travel) and its physics terms' parameters, settable before initialisation; the damper's states
the model reads (dampnet.h DN_DAMPER_STATE_LIST, `_core.DAMPER_STATES`: value reference 40 + k
for state k, its derivative 50 + k) as local variables, continuous states in model exchange.
"""

from __future__ import annotations

import json

from dampnet import _core
from dampnet.export.header import _package_version
from dampnet.features import CONTROL_FIELDS, param_doc
from dampnet.export.fmu.description import Description, FmuError, Variable, fmi_unit, range_in, unit_in
from dampnet.model import MlpModel
from dampnet.terms import KINDS

MODEL_IDENTIFIER = "dampnet_damper"
#: the features the FMU feeds: every feature the runtime knows (from its inputs, or from the
#: states it keeps for the derived ones)
FMU_FEATURES = tuple(_core.FEATURE_NAMES)
VR_FPARAM, VR_TERM, VR_STATE, VR_DERIV, VR_TIME, VR_ENVELOPE = 10, 100, 40, 50, 9, 8
#: the inverse's variables (fmu_damper.hpp: VR_DEMAND ..): force_demand, u_command, inverse_status, force_at_command
VR_DEMAND, VR_U_COMMAND, VR_INV_STATUS, VR_INV_FORCE = 30, 31, 32, 33
VR_U = 3  # the control input: the inverse's outputs do not depend on it (ModelStructure dependencies)
if VR_FPARAM + len(_core.FEATURE_PARAM_NAMES) > VR_DEMAND or VR_INV_FORCE >= VR_STATE:  # fmu_damper.hpp's static_assert
    raise ImportError(f"the {len(_core.FEATURE_PARAM_NAMES)} feature constants ({VR_FPARAM}..) reach the inverse's "
                      f"value references ({VR_DEMAND}..{VR_INV_FORCE}: fmu_damper.hpp)")
#: the damper's states (the runtime's registry, _core.DAMPER_STATES, in block order), by the
#: dn_damper_input field a feature reads: (field, k: value references VR_STATE + k and
#: VR_DERIV + k in fmu_damper.hpp, description)
STATES = tuple((name, k, doc) for k, (name, (_unit, _dyn, _source, _param, doc))
               in enumerate(_core.DAMPER_STATES.items()))
if VR_STATE + len(STATES) > VR_DERIV or VR_DERIV + len(STATES) > VR_TERM:  # fmu_damper.hpp's static_assert
    raise ImportError(f"the damper's {len(STATES)} states outgrew their value references "
                      f"({VR_STATE}.., {VR_DERIV}..: fmu_damper.hpp)")


def _fields(model: MlpModel) -> set[str]:
    return {_core.FEATURE_INPUTS[f] for f in model.features if f in _core.FEATURE_INPUTS}


__all__ = ["FMU_FEATURES", "MODEL_IDENTIFIER", "FmuError", "check_model", "damper_description", "damper_variables"]


def check_model(model: MlpModel) -> None:
    bad = [f for f in model.features if f not in FMU_FEATURES]
    if bad:
        raise FmuError(f"the FMU cannot feed feature(s) {', '.join(bad)}: it takes {', '.join(FMU_FEATURES)}")
    for term in model.terms:
        if len(term.get("params") or []) > 10:  # value references 100 + 10 i + j
            raise FmuError(f"term {term['kind']!r} has more than 10 parameters: the FMU exposes at most 10")


def control_unit(model: MlpModel) -> str | None:
    """The unit of the model's control feature (the first reading u or a state of it,
    CONTROL_FIELDS), V by default."""
    for name, unit in zip(model.features, model.units):
        if _core.FEATURE_INPUTS.get(name) in CONTROL_FIELDS:
            return fmi_unit(unit) or "V"
    return "V"


def state_unit(name: str, u_unit: str | None) -> str | None:
    """The FMI unit of damper state `name` (_core.DAMPER_STATES): a state of the control (source
    u) in the model's control unit u_unit, another in the registry's unit (None: dimensionless)."""
    unit, _dyn, source, _param, _doc = _core.DAMPER_STATES[name]
    return u_unit if source == "u" else fmi_unit(unit)


def data_label(model: MlpModel) -> str:
    """The training data, as training recorded it (meta["data"]: the dataset's source, e.g. its
    folder or "dampnet rig: plan quick, ...", and how many tests), or "unknown data"."""
    data = model.meta.get("data")
    if not isinstance(data, dict) or not data.get("source"):
        return "unknown data"
    n = data.get("n_tests")
    return str(data["source"]) + (f" ({n} tests)" if isinstance(n, int) and not isinstance(n, bool) else "")


#: the status codes one damper evaluation gives (cpp/include/dampnet/damper.hpp: Damper::force)
DAMPER_STATUSES = ("DN_OK", "DN_W_SATURATED", "DN_E_NONFINITE_INPUT", "DN_E_NONFINITE_OUTPUT")


def status_doc(names: tuple[str, ...]) -> str:
    """'CODE (NAME: the runtime's text)' for each status, from the runtime's status list."""
    return "; ".join(f"{getattr(_core, n)} ({_core.status_str(getattr(_core, n))})" for n in names)


#: the status codes the inverse gives (damper.hpp: Damper::inverse; warnings OR-ed)
INVERSE_STATUSES = ("DN_OK", "DN_W_SATURATED", "DN_W_UNREACHABLE", "DN_E_MISMATCH", "DN_E_NONFINITE_INPUT",
                    "DN_E_NONFINITE_OUTPUT")

#: how the damper's discrete outputs behave in model exchange (cpp/fmu/fmu_damper.hpp)
LATCHED = ("; model exchange: the value at the last event (discrete: it changes only at events; after an "
           "integrator step that would change it the FMU asks for a step event)")


def envelope_doc(with_grid: bool) -> str:
    """What the envelope_flags output means, with or without the training envelope's grid."""
    return ("the network's inputs against the model's training envelope: 0 inside; bit 0 (1) an input outside "
            "its training range or not finite; bit 1 (2) two inputs, each in range, in a cell of their plane "
            "(32 x 32 over the ranges) no training sample is near"
            + ("" if with_grid else " (not computed: this FMU was exported without the model's envelope, "
               "so it carries the training ranges only)"))


def term_param_name(term: dict, i: int, j: int) -> str:
    """The FMU's name of parameter j of term i ("bump_stop_1.k")."""
    return f"{term['kind']}_{i}.{KINDS[term['kind']].params[j].partition(' [')[0]}"


def term_names_config(model: MlpModel) -> tuple[str, ...]:
    """fmu_config.h's DNFMU_TERM_PARAM_NAMES: the terms' parameters by their FMU names, for the
    binary's messages (cpp/fmu/fmu_damper_params.hpp)."""
    if not model.terms:
        return ()
    rows = ", ".join("{" + ", ".join(json.dumps(term_param_name(t, i, j)) for j in range(len(t.get("params") or [])))
                     + "}" for i, t in enumerate(model.terms))
    return (f"#define DNFMU_TERM_PARAM_NAMES {{{rows}}}",)


def damper_variables(model: MlpModel, with_grid: bool = False) -> list[Variable]:
    """The damper's variables, in value-reference order within each group (with_grid: the FMU
    carries the training envelope's grid)."""
    u_unit = control_unit(model)
    v = [Variable("x", 0, "Real", "input", "continuous",
                  "damper displacement, extension positive, from the mid position", "m", 0.0),
         Variable("v", 1, "Real", "input", "continuous", "damper velocity, extension positive", "m/s", 0.0),
         Variable("a", 2, "Real", "input", "continuous", "damper relative acceleration, extension positive",
                  "m/s2", 0.0),
         Variable("u", 3, "Real", "input", "continuous", "control (the model's control unit)", u_unit, 0.0),
         Variable("temperature", 4, "Real", "input", "continuous", "damper temperature", "degC", 20.0),
         Variable("force", 5, "Real", "output", "continuous",
                  "damper force, positive resisting extension (network plus physics terms)", "N", initial="calculated"),
         Variable("status", 6, "Integer", "output", "discrete",
                  "dampnet status of the evaluation: " + status_doc(DAMPER_STATUSES) + "; an error also fails "
                  "reading the force" + LATCHED, initial="calculated"),
         Variable("clamped_mask", 7, "Integer", "output", "discrete",
                  "bit i set: network input i was clamped to its training range" + LATCHED, initial="calculated"),
         Variable("envelope_flags", VR_ENVELOPE, "Integer", "output", "discrete", envelope_doc(with_grid) + LATCHED,
                  initial="calculated"),
         Variable("force_demand", VR_DEMAND, "Real", "input", "continuous",
                  "the force demanded of the damper (a controller's): u_command is the control giving it", "N", 0.0),
         Variable("u_command", VR_U_COMMAND, "Real", "output", "continuous",
                  "the control within the model's control range at which the force at the current x, v, a, "
                  "temperature and states (u ignored) equals force_demand (the runtime's Damper::inverse); the "
                  "nearer control limit when the demand is out of reach (inverse_status); 0 for a model without a "
                  "control input", u_unit, initial="calculated", independent_of=(VR_U,)),
         Variable("inverse_status", VR_INV_STATUS, "Integer", "output", "discrete",
                  "dampnet status of the inverse (u_command), warnings OR-ed: " + status_doc(INVERSE_STATUSES)
                  + "; -8: the model has no control input (u_command 0, not an error of the FMU); -10, -7 also fail "
                  "reading u_command" + LATCHED, initial="calculated", independent_of=(VR_U,)),
         Variable("force_at_command", VR_INV_FORCE, "Real", "output", "continuous",
                  "damper force at u = u_command (force_demand where it is reachable)", "N", initial="calculated",
                  independent_of=(VR_U,))]
    for k, (name, value) in enumerate(sorted(model.feature_params.items())):  # the header's order
        doc = param_doc(name)
        lo, hi = range_in(doc, name)
        v.append(Variable(name, VR_FPARAM + k, "Real", "parameter", "fixed", doc.split(" [")[0],
                          unit_in(doc), float(value), initial="exact", min=lo, max=hi))
    for i, term in enumerate(model.terms):
        names = KINDS[term["kind"]].params
        runtime_doc = _core.TERM_KINDS[term["kind"]][1]  # the runtime's, with its parameters' ranges
        for j, value in enumerate(term.get("params") or []):
            pname, _, unit = names[j].partition(" [")
            lo, hi = range_in(runtime_doc, pname, named_only=True)
            v.append(Variable(term_param_name(term, i, j), VR_TERM + 10 * i + j, "Real", "parameter", "fixed",
                              f"physics term {i} ({term['kind']}): {KINDS[term['kind']].doc}", fmi_unit(unit.rstrip("]")),
                              float(value), initial="exact", min=lo, max=hi))
    used = _fields(model)
    for name, slot, doc in STATES:
        if name in used:
            unit = state_unit(name, u_unit)
            d_unit = {"V": "V/s", "A": "A/s", "m": "m/s", "m/s": "m/s2", None: "1/s"}.get(unit)
            v.append(Variable(name, VR_STATE + slot, "Real", "local", "continuous", doc, unit,
                              initial="calculated", state=True))
            v.append(Variable(f"der({name})", VR_DERIV + slot, "Real", "local", "continuous",
                              f"time derivative of {name}", d_unit, initial="calculated",
                              derivative_of=VR_STATE + slot))
    return v


def damper_description(model: MlpModel, with_grid: bool = False, step_s: float = 1e-3) -> Description:
    check_model(model)
    text = (f"dampnet damper model {model.model_id()}: a {model.n_inputs}-input MLP on {', '.join(model.features)}"
            + (f" plus {len(model.terms)} physics term(s)" if model.terms else "")
            + f"; trained on {data_label(model)}")
    return Description(MODEL_IDENTIFIER, model.model_id(), text, f"dampnet {_package_version()}",
                       damper_variables(model, with_grid), step_s=step_s, time_vr=VR_TIME,
                       config_lines=term_names_config(model))
