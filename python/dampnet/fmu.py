"""The damper model as an FMI 2.0 FMU (co-simulation and model exchange), for vehicle-simulation tools that import
FMUs (CarSim, CarMaker, Simulink, Dymola, OpenModelica, Silver, FMPy, ...).

`build_damper_fmu(model, out)` writes the model's header (export.header_text), the
modelDescription.xml and compiles cpp/fmu/damper_fmu2.cpp (dampnet's header-only damper and
MLP kernel behind the FMI 2 C API; FMI 2.0.1 headers, 2-clause BSD, in cpp/fmu/fmi2/) into
binaries/linux64/, with the sources in sources/ so an importer elsewhere can rebuild it. The
binary depends on libc and libm only. Inputs x [m], v [m/s], a [m/s2], u (the model's control
unit), temperature [degC]; outputs force [N], status, clamped_mask. The model must be one the
FMU can feed: its features among velocity, acceleration, displacement, voltage / current and
temperature (features with a state of their own, e.g. voltage_lag, are not in the FMU yet).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
import zipfile
from pathlib import Path
from xml.sax.saxutils import escape

from dampnet import paths
from dampnet.export import _package_version, header_text
from dampnet.model import MlpModel, ModelError

MODEL_IDENTIFIER = "dampnet_damper"
#: features the FMU feeds from its inputs (the others have a state the FMU does not keep yet)
FMU_FEATURES = ("velocity", "acceleration", "displacement", "voltage", "current", "temperature")
HEADER_PREFIX = "fmu_model"


class FmuError(ModelError):
    """A model the FMU cannot carry, a missing compiler, a failed build."""


def fmu_sources() -> Path:
    """cpp/fmu (damper_fmu2.cpp, fmi2/), installed with the package or in the source tree."""
    root = Path(paths.include_dirs()[0]).parent
    for base in (root / "fmu_src", Path(__file__).resolve().parents[2] / "cpp" / "fmu"):
        if (base / "damper_fmu2.cpp").is_file():
            return base
    raise FmuError("cpp/fmu/damper_fmu2.cpp not found with the installed dampnet; reinstall (python/env.sh)")


def check_model(model: MlpModel) -> None:
    bad = [f for f in model.features if f not in FMU_FEATURES]
    if bad:
        raise FmuError(f"the FMU cannot feed feature(s) {', '.join(bad)}: it takes "
                       f"{', '.join(FMU_FEATURES)} (features with a state of their own are not in the FMU yet)")


def _unit_of_control(model: MlpModel) -> str:
    for name in ("voltage", "current"):
        if name in model.features:
            return model.units[model.features.index(name)] or ("V" if name == "voltage" else "A")
    return "V"


def model_description(model: MlpModel, step_s: float = 1e-3) -> str:
    """FMI 2.0 modelDescription.xml of the damper FMU."""
    u_unit = _unit_of_control(model)
    desc = (f"dampnet damper model {model.model_id()}: a {model.n_inputs}-input MLP on "
            f"{', '.join(model.features)}" + (f" plus {len(model.terms)} physics term(s)" if model.terms else "")
            + f"; trained on {model.meta.get('data_hash', model.meta.get('dataset', 'unknown data'))}")
    rows = [("x", 0, "input", "relative displacement, extension positive, from the mid position", "m", 0.0),
            ("v", 1, "input", "relative velocity, extension positive", "m/s", 0.0),
            ("a", 2, "input", "relative acceleration, extension positive", "m/s2", 0.0),
            ("u", 3, "input", "control (the model's control unit)", u_unit, 0.0),
            ("temperature", 4, "input", "damper temperature", "degC", 20.0)]
    var = []
    for name, vr, caus, doc, unit, start in rows:
        var.append(f'    <ScalarVariable name="{name}" valueReference="{vr}" causality="{caus}" '
                   f'variability="continuous" description="{escape(doc)} [{escape(unit)}]">\n'
                   f'      <Real start="{start}" unit="{escape(unit)}"/>\n    </ScalarVariable>')
    var.append('    <ScalarVariable name="force" valueReference="5" causality="output" variability="continuous" '
               'initial="calculated" description="damper force, positive resisting extension [N]">\n'
               '      <Real unit="N"/>\n    </ScalarVariable>')
    var.append('    <ScalarVariable name="status" valueReference="6" causality="output" variability="discrete" '
               'initial="calculated" description="dampnet status of the evaluation: 0 ok, 1 an input clamped, '
               '2 a NaN input replaced, negative an error">\n      <Integer/>\n    </ScalarVariable>')
    var.append('    <ScalarVariable name="clamped_mask" valueReference="7" causality="output" variability="discrete" '
               'initial="calculated" description="bit i set: the MLP input i was clamped to its training range">\n'
               '      <Integer/>\n    </ScalarVariable>')
    deps = 'dependencies="1 2 3 4 5"'
    unknowns = "\n".join(f'      <Unknown index="{i}" {deps}/>' for i in (6, 7, 8))
    units = {"m": 'm="1"', "m/s": 'm="1" s="-1"', "m/s2": 'm="1" s="-2"', "N": 'kg="1" m="1" s="-2"',
             "degC": 'K="1" offset="273.15"', "V": 'kg="1" m="2" s="-3" A="-1"', "A": 'A="1"'}
    unit_defs = "\n".join(f'    <Unit name="{escape(u)}"><BaseUnit {b}/></Unit>' for u, b in units.items()
                          if u in {r[4] for r in rows} | {"N"})
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n'
            f'<fmiModelDescription fmiVersion="2.0" modelName="{MODEL_IDENTIFIER}" guid="{model.model_id()}" '
            f'description="{escape(desc)}" generationTool="dampnet {escape(_package_version())}" '
            f'variableNamingConvention="flat" numberOfEventIndicators="0">\n'
            f'  <ModelExchange modelIdentifier="{MODEL_IDENTIFIER}" canGetAndSetFMUstate="false" '
            f'canSerializeFMUstate="false" providesDirectionalDerivative="false">\n'
            f'    <SourceFiles><File name="damper_fmu2.cpp"/></SourceFiles>\n  </ModelExchange>\n'
            f'  <CoSimulation modelIdentifier="{MODEL_IDENTIFIER}" canHandleVariableCommunicationStepSize="true" '
            f'canGetAndSetFMUstate="false" canSerializeFMUstate="false" providesDirectionalDerivative="false">\n'
            f'    <SourceFiles><File name="damper_fmu2.cpp"/></SourceFiles>\n  </CoSimulation>\n'
            f'  <UnitDefinitions>\n{unit_defs}\n  </UnitDefinitions>\n'
            f'  <DefaultExperiment startTime="0" stopTime="10" stepSize="{step_s}"/>\n'
            f'  <ModelVariables>\n' + "\n".join(var) + '\n  </ModelVariables>\n'
            f'  <ModelStructure>\n    <Outputs>\n{unknowns}\n    </Outputs>\n'
            f'    <InitialUnknowns>\n{unknowns}\n    </InitialUnknowns>\n  </ModelStructure>\n'
            f'</fmiModelDescription>\n')


def _compiler() -> str:
    cxx = os.environ.get("CXX") or shutil.which("c++") or shutil.which("g++")
    if not cxx:
        raise FmuError("no C++ compiler found (c++/g++, or $CXX): the FMU's binary is compiled here")
    return cxx


def build_damper_fmu(model: MlpModel, out: str | os.PathLike, overwrite: bool = False) -> Path:
    """Build OUT.fmu for the model (see the module docstring): staged in a temporary directory
    and moved into place, so a failure leaves nothing half-written."""
    check_model(model)
    out = Path(out)
    if out.exists() and not overwrite:
        raise FileExistsError(f"{out}: exists; refusing to overwrite (use --force)")
    src = fmu_sources()
    cxx = _compiler()
    include = Path(paths.include_dirs()[0])
    with tempfile.TemporaryDirectory(prefix=".dampnet-fmu-", dir=out.parent if str(out.parent) else ".") as tmp:
        t = Path(tmp)
        (t / "sources").mkdir()
        (t / "binaries" / "linux64").mkdir(parents=True)
        (t / "sources" / "fmu_model.h").write_text(header_text(model, HEADER_PREFIX))
        shutil.copy(src / "damper_fmu2.cpp", t / "sources" / "damper_fmu2.cpp")
        for h in (src / "fmi2").glob("*.h"):
            shutil.copy(h, t / "sources" / h.name)
        shutil.copytree(include / "dampnet", t / "sources" / "dampnet")
        (t / "modelDescription.xml").write_text(model_description(model))
        so = t / "binaries" / "linux64" / f"{MODEL_IDENTIFIER}.so"
        cmd = [cxx, "-std=c++17", "-O2", "-fPIC", "-shared", "-fno-exceptions", "-fno-rtti", "-DDN_STATIC",
               "-fvisibility=hidden", f"-I{t / 'sources'}", str(t / "sources" / "damper_fmu2.cpp"), "-o", str(so),
               "-static-libgcc"]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            raise FmuError(f"compiling the FMU failed: {' '.join(cmd)}\n{proc.stderr[-2000:]}")
        part = t / "out.fmu"
        with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
            for f in sorted(p for p in t.rglob("*") if p.is_file() and p != part):
                z.write(f, f.relative_to(t).as_posix())
        os.replace(part, out)
    return out
