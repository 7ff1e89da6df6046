"""modelDescription.xml (FMI 2.0 and 3.0) and buildDescription.xml (FMI 3.0) from one list of
variables: the damper's and the quarter car's variable tables (damper.py, quarter_car.py)
are written once and rendered for either standard here."""

from __future__ import annotations

import re
from dataclasses import dataclass
from xml.sax.saxutils import quoteattr

from dampnet.model import ModelError

#: SI base-unit exponents of every unit a dampnet FMU variable may carry (FMI <Unit>/<BaseUnit>);
#: None: a unit with no fixed base units (a bump stop's k [N/m^n] depends on its exponent n)
BASE_UNITS = {
    "m": 'm="1"', "m/s": 'm="1" s="-1"', "m/s2": 'm="1" s="-2"', "N": 'kg="1" m="1" s="-2"',
    "degC": 'K="1" offset="273.15"', "V": 'kg="1" m="2" s="-3" A="-1"', "A": 'A="1"', "kg": 'kg="1"',
    "s": 's="1"', "N/m": 'kg="1" s="-2"', "N.s/m": 'kg="1" s="-1"', "1/s": 's="-1"',
    "V/s": 'kg="1" m="2" s="-4" A="-1"', "A/s": 'A="1" s="-1"', "N/m2": 'kg="1" m="-1" s="-2"',
    "N/m3": 'kg="1" m="-2" s="-2"', "N.s2/m2": 'kg="1" m="-1"', "N/m^n": None,
}
#: the sources an FMI version's binary is built from, and its platform folder
SOURCE = {2: "fmu2.cpp", 3: "fmu3.cpp"}
#: a variable's FMI 3 element by its (FMI 2) type
FMI3_TYPE = {"Real": "Float64", "Integer": "Int32", "Enumeration": "Enumeration"}
PLATFORM = {2: "linux64", 3: "x86_64-linux"}
INTERFACES = ("cs", "me", "both")


class FmuError(ModelError):
    """A model the FMU cannot carry, an interface it does not have, a missing compiler, a failed build."""


def fmi_unit(text: str | None) -> str | None:
    """An FMI unit name from dampnet's notation ("m/s^2" -> "m/s2", "N s/m" -> "N.s/m");
    None for dimensionless or unknown ("-", "")."""
    if not text:
        return None
    u = re.sub(r"\^(?=-?\d)", "", text.strip()).replace(" ", ".")
    return u if u in BASE_UNITS else None


def unit_in(doc: str) -> str | None:
    """The unit in a dampnet doc string's first [...] ("sprung mass [kg], > 0" -> "kg")."""
    m = re.search(r"\[([^\]]+)\]", doc)
    return fmi_unit(m.group(1)) if m else None


_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


def range_in(doc: str, name: str, named_only: bool = False) -> tuple[float | None, float | None]:
    """(min, max) of `name` as a runtime doc states them: the range the runtime's check enforces
    and its messages quote ("sprung mass [kg], > 0" -> (0, None); "step [s], 1e-9 <= dt <= 0.1"
    -> (1e-9, 0.1)). A clause of the doc (between , ; ( )) states a bound: "> 0", ">= 0",
    "NAME >= 0", "1e-9 <= NAME <= 0.1" (a leading "params" allowed: the terms' docs list their
    parameters so). named_only: only clauses naming `name` count (a doc of several parameters).
    Bounds relative to another parameter ("<= u_max") are not ranges of this one: left out.
    FMI's min/max are inclusive: a strict bound ("> 0") is given as the bound itself."""
    lo = hi = None
    who = rf"(?:{re.escape(name)}\s*)" + ("" if named_only else "?")
    for clause in re.split(r"[,;()]", re.sub(r"\s*\[[^\]]*\]", "", doc)):
        c = re.sub(r"^\s*params\s+", "", clause).strip()
        if m := re.fullmatch(rf"({_NUM})\s*<=?\s*{re.escape(name)}\s*<=?\s*({_NUM})", c):
            lo, hi = float(m.group(1)), float(m.group(2))
        elif m := re.fullmatch(rf"{who}>=?\s*({_NUM})", c):
            lo = float(m.group(1))
        elif m := re.fullmatch(rf"{who}<=?\s*({_NUM})", c):
            hi = float(m.group(1))
    return lo, hi


@dataclass(frozen=True)
class Variable:
    """One FMU variable. type: "Real" (FMI 3 Float64), "Integer" (Int32) or "Enumeration" (its
    declared type `enum`: a name and its items (name, value, doc); FMI 3 accesses it as Int64).
    causality: input, output, parameter, local; variability: continuous, discrete, fixed, tunable.
    min, max: the runtime's range (inclusive bounds; dampnet's checks refuse a value outside).
    independent_of: for an output, the inputs (value references) it does not depend on: its
    ModelStructure entry then lists its dependencies (the other inputs, and the continuous states
    with model exchange), so that an importer wiring it back into one of them sees no algebraic
    loop; empty: no list (an output depends on every input and state)."""
    name: str
    vr: int
    type: str
    causality: str
    variability: str
    description: str
    unit: str | None = None
    start: float | int | None = None
    initial: str | None = None
    derivative_of: int | None = None  # the state's value reference, for a state derivative
    state: bool = False  # a continuous state (model exchange)
    min: float | None = None
    max: float | None = None
    enum: tuple[str, tuple[tuple[str, int, str], ...]] | None = None  # (type name, items), Enumeration only
    independent_of: tuple[int, ...] = ()  # an output: the inputs it does not depend on


@dataclass
class Description:
    """What a modelDescription says: identity, variables, interfaces and the default experiment."""
    model_identifier: str
    guid: str  # FMI 2 guid, FMI 3 instantiationToken: the binary checks it
    description: str
    tool: str
    variables: list[Variable]
    step_s: float = 1e-3
    stop_s: float = 10.0
    time_vr: int = 9  # FMI 3's independent variable
    co_simulation_only: bool = False  # the model has no model-exchange form
    fixed_step: bool = False  # co-simulation takes exactly step_s per communication step
    config_lines: tuple[str, ...] = ()  # more lines for fmu_config.h (e.g. compiled start values)

    def by_vr(self) -> dict[int, Variable]:
        return {v.vr: v for v in self.variables}


def _units_block(variables: list[Variable], extra: tuple[str, ...] = ()) -> str:
    used = sorted({v.unit for v in variables if v.unit} | set(extra))
    rows = "\n".join(f"    <Unit name={quoteattr(u)}><BaseUnit {BASE_UNITS[u]}/></Unit>" if BASE_UNITS[u]
                     else f"    <Unit name={quoteattr(u)}/>" for u in used)
    return f"  <UnitDefinitions>\n{rows}\n  </UnitDefinitions>\n" if used else ""


def _enum_types(variables: list[Variable]) -> dict[str, tuple[tuple[str, int, str], ...]]:
    """The Enumeration types the variables declare, by name (one definition each)."""
    types: dict[str, tuple[tuple[str, int, str], ...]] = {}
    for v in variables:
        if v.enum is not None:
            if types.setdefault(v.enum[0], v.enum[1]) != v.enum[1]:
                raise FmuError(f"enumeration type {v.enum[0]}: two different item lists")
    return types


def _items(items: tuple[tuple[str, int, str], ...], indent: str) -> str:
    return "".join(f"{indent}<Item name={quoteattr(n)} value=\"{int(value)}\" description={quoteattr(doc)}/>\n"
                   for n, value, doc in items)


def _type_definitions_2(variables: list[Variable]) -> str:
    types = _enum_types(variables)
    if not types:
        return ""
    rows = "".join(f"    <SimpleType name={quoteattr(t)}>\n      <Enumeration>\n{_items(items, ' ' * 8)}"
                   f"      </Enumeration>\n    </SimpleType>\n" for t, items in types.items())
    return f"  <TypeDefinitions>\n{rows}  </TypeDefinitions>\n"


def _type_definitions_3(variables: list[Variable]) -> str:
    types = _enum_types(variables)
    if not types:
        return ""
    rows = "".join(f"    <EnumerationType name={quoteattr(t)}>\n{_items(items, ' ' * 6)}    </EnumerationType>\n"
                   for t, items in types.items())
    return f"  <TypeDefinitions>\n{rows}  </TypeDefinitions>\n"


def _bounds(v: Variable) -> list[str]:
    return [f'{k}="{_num(x)}"' for k, x in (("min", v.min), ("max", v.max)) if x is not None]


def _num(x: float | int) -> str:
    return repr(int(x)) if isinstance(x, int) else repr(float(x))


def default_interface(d: Description) -> str:
    return "cs" if d.co_simulation_only else "both"


def _interfaces(d: Description, interface: str | None) -> tuple[bool, bool]:
    interface = interface or default_interface(d)
    if interface not in INTERFACES:
        raise FmuError(f"interface {interface!r}: expected one of {', '.join(INTERFACES)}")
    if d.co_simulation_only and interface != "cs":
        raise FmuError(f"{d.model_identifier} is a co-simulation FMU only: use interface 'cs' (got {interface!r})")
    return interface in ("cs", "both"), interface in ("me", "both")


def _dependencies(v: Variable, variables: list[Variable], me: bool) -> list[Variable] | None:
    """The knowns output v depends on (every input but v.independent_of; the continuous states
    with model exchange), or None: no list (it depends on all)."""
    if not v.independent_of:
        return None
    return [w for w in variables if (w.causality == "input" and w.vr not in v.independent_of) or (me and w.state)]


def _variable_step(d: Description) -> str:
    return "false" if d.fixed_step else "true"


def model_description_2(d: Description, interface: str | None = None) -> str:
    """FMI 2.0 modelDescription.xml."""
    cs, me = _interfaces(d, interface)
    variables = [v for v in d.variables if me or v.derivative_of is None]
    index = {v.vr: i + 1 for i, v in enumerate(variables)}  # FMI 2 refers to variables by 1-based index
    rows = []
    for v in variables:
        attrs = [f"name={quoteattr(v.name)}", f'valueReference="{v.vr}"', f'causality="{v.causality}"',
                 f'variability="{v.variability}"']
        if v.initial:
            attrs.append(f'initial="{v.initial}"')
        doc = v.description + (f" [{v.unit}]" if v.unit else "")
        attrs.append(f"description={quoteattr(doc)}")
        typed = []
        if v.enum is not None:
            typed.append(f"declaredType={quoteattr(v.enum[0])}")
        if v.type == "Real" and v.unit:
            typed.append(f"unit={quoteattr(v.unit)}")
        typed += _bounds(v)
        if v.derivative_of is not None:
            typed.append(f'derivative="{index[v.derivative_of]}"')
        if v.start is not None:
            typed.append(f'start="{_num(v.start)}"')
        rows.append(f"    <ScalarVariable {' '.join(attrs)}>\n      <{v.type}{''.join(' ' + t for t in typed)}/>\n"
                    f"    </ScalarVariable>")
    outputs = [v for v in variables if v.causality == "output"]
    derivs = [v for v in variables if v.derivative_of is not None]
    initial = sorted([v for v in variables if v.causality == "output" or v.derivative_of is not None
                      or (me and v.state and v.initial in (None, "calculated", "approx"))], key=lambda v: index[v.vr])

    def unknowns(vs, with_dependencies=False):
        rows = ""
        for v in vs:
            deps = _dependencies(v, variables, me) if with_dependencies else None
            listed = "" if deps is None else f' dependencies="{" ".join(str(index[w.vr]) for w in deps)}"'
            rows += f'      <Unknown index="{index[v.vr]}"{listed}/>\n'
        return rows

    structure = f"    <Outputs>\n{unknowns(outputs, True)}    </Outputs>\n"
    if derivs:
        structure += f"    <Derivatives>\n{unknowns(derivs)}    </Derivatives>\n"
    structure += f"    <InitialUnknowns>\n{unknowns(initial)}    </InitialUnknowns>\n"
    src = f'    <SourceFiles><File name="{SOURCE[2]}"/></SourceFiles>\n'
    head = (f'<?xml version="1.0" encoding="UTF-8"?>\n'
            f'<fmiModelDescription fmiVersion="2.0" modelName="{d.model_identifier}" guid={quoteattr(d.guid)} '
            f"description={quoteattr(d.description)} generationTool={quoteattr(d.tool)} "
            f'variableNamingConvention="flat" numberOfEventIndicators="0">\n')
    if me:
        head += (f'  <ModelExchange modelIdentifier="{d.model_identifier}" canGetAndSetFMUstate="false" '
                 f'canSerializeFMUstate="false" providesDirectionalDerivative="false">\n{src}  </ModelExchange>\n')
    if cs:
        head += (f'  <CoSimulation modelIdentifier="{d.model_identifier}" canHandleVariableCommunicationStepSize="{_variable_step(d)}" '
                 f'canGetAndSetFMUstate="false" canSerializeFMUstate="false" providesDirectionalDerivative="false">\n'
                 f"{src}  </CoSimulation>\n")
    return (head + _units_block(variables) + _type_definitions_2(variables)
            + f'  <DefaultExperiment startTime="0" stopTime="{_num(d.stop_s)}" stepSize="{_num(d.step_s)}"/>\n'
            + "  <ModelVariables>\n" + "\n".join(rows) + "\n  </ModelVariables>\n"
            + f"  <ModelStructure>\n{structure}  </ModelStructure>\n</fmiModelDescription>\n")


def model_description_3(d: Description, interface: str | None = None) -> str:
    """FMI 3.0 modelDescription.xml (the independent variable `time` first)."""
    cs, me = _interfaces(d, interface)
    variables = [v for v in d.variables if me or v.derivative_of is None]
    rows = [f'    <Float64 name="time" valueReference="{d.time_vr}" causality="independent" '
            f'variability="continuous" description="simulation time [s]" unit="s"/>']
    for v in variables:
        attrs = [f"name={quoteattr(v.name)}", f'valueReference="{v.vr}"', f'causality="{v.causality}"',
                 f'variability="{v.variability}"']
        if v.initial:
            attrs.append(f'initial="{v.initial}"')
        doc = v.description + (f" [{v.unit}]" if v.unit else "")
        attrs.append(f"description={quoteattr(doc)}")
        if v.enum is not None:
            attrs.append(f"declaredType={quoteattr(v.enum[0])}")
        if v.type == "Real" and v.unit:
            attrs.append(f"unit={quoteattr(v.unit)}")
        attrs += _bounds(v)
        if v.derivative_of is not None:
            attrs.append(f'derivative="{v.derivative_of}"')
        if v.start is not None:
            attrs.append(f'start="{_num(v.start)}"')
        rows.append(f"    <{FMI3_TYPE[v.type]} {' '.join(attrs)}/>")
    outputs = [v for v in variables if v.causality == "output"]
    derivs = [v for v in variables if v.derivative_of is not None]
    initial = [v for v in variables if v.causality == "output" or v.derivative_of is not None
               or (me and v.state and v.initial in (None, "calculated", "approx"))]

    def listed(v):
        deps = _dependencies(v, variables, me)
        return "" if deps is None else f' dependencies="{" ".join(str(w.vr) for w in deps)}"'

    structure = "".join(f'    <Output valueReference="{v.vr}"{listed(v)}/>\n' for v in outputs)
    structure += "".join(f'    <ContinuousStateDerivative valueReference="{v.vr}"/>\n' for v in derivs)
    structure += "".join(f'    <InitialUnknown valueReference="{v.vr}"/>\n' for v in initial)
    head = (f'<?xml version="1.0" encoding="UTF-8"?>\n'
            f'<fmiModelDescription fmiVersion="3.0" modelName="{d.model_identifier}" '
            f"instantiationToken={quoteattr(d.guid)} description={quoteattr(d.description)} "
            f'generationTool={quoteattr(d.tool)} variableNamingConvention="flat">\n')
    if me:
        head += (f'  <ModelExchange modelIdentifier="{d.model_identifier}" canGetAndSetFMUState="false" '
                 f'canSerializeFMUState="false"/>\n')
    if cs:
        fixed = f'fixedInternalStepSize="{_num(d.step_s)}" ' if d.fixed_step else ""
        head += (f'  <CoSimulation modelIdentifier="{d.model_identifier}" '
                 f'canHandleVariableCommunicationStepSize="{_variable_step(d)}" {fixed}'
                 f'canGetAndSetFMUState="false" canSerializeFMUState="false" providesIntermediateUpdate="false" '
                 f'canReturnEarlyAfterIntermediateUpdate="false" hasEventMode="false"/>\n')
    return (head + _units_block(variables, extra=("s",)) + _type_definitions_3(variables)  # "s": `time`'s unit
            + f'  <DefaultExperiment startTime="0" stopTime="{_num(d.stop_s)}" stepSize="{_num(d.step_s)}"/>\n'
            + "  <ModelVariables>\n" + "\n".join(rows) + "\n  </ModelVariables>\n"
            + f"  <ModelStructure>\n{structure}  </ModelStructure>\n</fmiModelDescription>\n")


def build_description_3(d: Description) -> str:
    """FMI 3.0 sources/buildDescription.xml: one C++17 source, sources/ on the include path
    (IncludeDirectory names are relative to sources/: "." is sources/ itself)."""
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<fmiBuildDescription fmiVersion="3.0">\n'
            f'  <BuildConfiguration modelIdentifier="{d.model_identifier}">\n'
            f'    <SourceFileSet language="C++17">\n      <SourceFile name="{SOURCE[3]}"/>\n'
            f'      <IncludeDirectory name="."/>\n    </SourceFileSet>\n'
            f"  </BuildConfiguration>\n</fmiBuildDescription>\n")


def model_description(d: Description, fmi: int, interface: str | None = None) -> str:
    if fmi == 2:
        return model_description_2(d, interface)
    if fmi == 3:
        return model_description_3(d, interface)
    raise ValueError(f"FMI version {fmi!r}: expected 2 or 3")
