"""What `dampnet export` writes: one entry per target (the C/C++ header, the ONNX graph, the
damper and quarter-car FMUs, the microcontroller folder), each naming the command's options that
apply to it. The command builds its options, their help and its checks from OPTIONS and
TARGETS: an option given to targets it does not apply to is refused naming the targets it does.

A command line selects a target by its output option (--header OUT.h, --onnx OUT.onnx,
--fmu OUT.fmu, --out DIR) and, where two targets share one, the options in `when`
(--what quarter-car). The writers stay where they are (dampnet.export, dampnet.export.fmu,
dampnet.export.mcu); this module is the vocabulary and the wiring.

Adding a target (docs/recipes.md, "Export targets"): `option(...)` for each new option, then
`register(ExportTarget(...))`.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
from typing import Any, Callable


@dataclass(frozen=True)
class Option:
    """One option of `dampnet export`: its flag, argparse's keywords (help, metavar, type,
    choices, action) and its default, applied after the command line is checked (the parser's
    own default is None, so that an option given can be told from one left out)."""

    flag: str
    help: str
    default: Any = None
    kwargs: dict = field(default_factory=dict)

    @property
    def dest(self) -> str:
        return self.flag.lstrip("-").replace("-", "_")


@dataclass
class Job:
    """One export: the command line (args, defaults applied), the model (dampnet.model.MlpModel),
    its training envelope (or None) and what the envelope check carries, in words."""

    args: argparse.Namespace
    model: Any = None
    envelope: Any = None
    carries: str = ""


@dataclass(frozen=True)
class ExportTarget:
    """A target: `output` the option naming what it writes (a file, or a folder when
    `file_output` is False: the writer checks that one itself); `when`: other options' values
    that select it among targets sharing the output; `options`: the flags that apply to it
    (its output and `when` included); `check(args)`: before anything is written (ValueError);
    `write(job) -> str`: writes, returns the line the command prints; `output_text`: its output
    in help and messages when it needs more than the output option; `envelope`: reads the
    model's training envelope (dampnet.envelope) before writing (a broken one refuses the export,
    as `dampnet export` always did for its file targets)."""

    name: str
    doc: str
    output: str
    options: tuple[str, ...]
    write: Callable[[Job], str]
    when: dict[str, Any] = field(default_factory=dict)
    check: Callable[[argparse.Namespace], None] | None = None
    file_output: bool = True
    envelope: bool = True
    output_text: str = ""

    def output_usage(self) -> str:
        """Its output on a command line ("--header OUT.h"; `output_text` when it needs more)."""
        return self.output_text or f"{self.output} {OPTIONS[self.output].kwargs.get('metavar', 'OUT')}"

    def usage(self) -> str:
        """How a command line selects it: its output option and `when`."""
        return " ".join([self.output_usage(), *(f"{k} {v}" for k, v in self.when.items())])


#: every option of `dampnet export`, in the order its help lists them
OPTIONS: dict[str, Option] = {}
#: every target, in the order the command writes them
TARGETS: dict[str, ExportTarget] = {}


def option(o: Option) -> Option:
    """Register an option (refused when its flag is taken)."""
    if o.flag in OPTIONS:
        raise ValueError(f"export option {o.flag} is already registered")
    OPTIONS[o.flag] = o
    return o


def register(t: ExportTarget) -> ExportTarget:
    """Register a target (refused when its name is taken or it names an unregistered option)."""
    if t.name in TARGETS:
        raise ValueError(f"export target {t.name!r} is already registered")
    for flag in (t.output, *t.when, *t.options):
        if flag not in OPTIONS:
            raise ValueError(f"export target {t.name!r}: option {flag} is not registered (recipes.export_targets.option)")
    if t.output not in t.options or not set(t.when) <= set(t.options):
        raise ValueError(f"export target {t.name!r}: its output and `when` options must be among its options")
    TARGETS[t.name] = t
    return t


def unregister(name: str) -> None:
    """Remove a target (a test's own) and the options no other target takes."""
    t = TARGETS.pop(name)
    for flag in t.options:
        if flag not in BUILTIN_OPTIONS and not any(flag in o.options for o in TARGETS.values()):
            OPTIONS.pop(flag, None)


def get(name: str) -> ExportTarget:
    """The target `name` (ValueError listing the registered ones)."""
    try:
        return TARGETS[name]
    except KeyError:
        raise ValueError(f"{name!r} is not an export target; valid: {', '.join(TARGETS)}") from None


def applies_to(flag: str) -> list[str]:
    """The targets an option applies to."""
    return [t.name for t in TARGETS.values() if flag in t.options]


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Every option, its help ending with the targets it applies to (its parser default None:
    `check_options` fills the option's own default in once the command line is checked)."""
    for o in OPTIONS.values():
        names = applies_to(o.flag)
        where = "every target" if len(names) == len(TARGETS) else ", ".join(names)
        p.add_argument(o.flag, **{**o.kwargs, "default": None}, help=f"{o.help} [{where}]")


def description() -> str:
    """The targets in words, for the command's help."""
    return "; ".join(f"{t.name} ({t.usage()}): {t.doc}" for t in TARGETS.values())


def _given(args: argparse.Namespace, flag: str) -> bool:
    return getattr(args, OPTIONS[flag].dest, None) not in (None, False)


def _value(args: argparse.Namespace, flag: str) -> Any:
    v = getattr(args, OPTIONS[flag].dest, None)
    return OPTIONS[flag].default if v is None else v


def selected(args: argparse.Namespace) -> list[ExportTarget]:
    """The targets a command line selects (its output given, its `when` met)."""
    return [t for t in TARGETS.values()
            if _given(args, t.output) and all(_value(args, k) == v for k, v in t.when.items())]


def check_options(args: argparse.Namespace) -> list[ExportTarget]:
    """The targets the command line selects, each option given applying to one of them
    (ValueError naming the option and the targets it applies to otherwise); then the options
    not given set to their defaults."""
    targets = selected(args)
    names = [t.name for t in targets]
    for flag in (f for f in OPTIONS if _given(args, f)):
        to = applies_to(flag)
        if set(names) & set(to) or (not names and len(to) == len(TARGETS)):
            continue
        add = min((_missing(args, t) for t in to), key=len) if to else ""
        where = f"does not apply to {', '.join(names)}" if names else "alone selects nothing to export"
        raise ValueError(f"{flag} {where}; it applies to {', '.join(to) or 'no target'}" + (f": add {add}" if add else ""))
    if not targets:
        outs = dict.fromkeys(t.output_usage() for t in TARGETS.values())
        raise ValueError("nothing to export: give " + ", ".join(outs) + " (dampnet export --help lists the targets)")
    for o in OPTIONS.values():
        if getattr(args, o.dest, None) is None:
            setattr(args, o.dest, list(o.default) if isinstance(o.default, list) else o.default)
    return targets


def _missing(args: argparse.Namespace, name: str) -> str:
    """What the command line lacks to select target `name` (its output, its `when`)."""
    t = TARGETS[name]
    parts = [] if _given(args, t.output) else [f"{t.output} {OPTIONS[t.output].kwargs.get('metavar', 'OUT')}"]
    return " ".join(parts + [f"{k} {v}" for k, v in t.when.items() if _value(args, k) != v])


# -- the built-in options and targets -------------------------------------------------------


option(Option("--fmu", "write an FMU here (see --fmi, --interface, --what)", kwargs=dict(metavar="OUT.fmu")))
option(Option("--fmi", "FMI version of the FMU (default 2)", 2, dict(type=int, choices=(2, 3))))
option(Option("--interface", "co-simulation, model exchange or both in one FMU (default: both for the damper, "
              "cs for the quarter car, which is co-simulation only)", None, dict(choices=("cs", "me", "both"))))
option(Option("--what", "the damper alone (default), or the quarter car with this damper (thesis Table 5 "
              "vehicle; fixed step = its dt)", "damper", dict(choices=("damper", "quarter-car"))))
option(Option("--controller", "quarter car: the control law (dampnet.recipes.control_laws: passive, passive_low, "
              "skyhook_onoff, ...), its start values calibrated on the model as `dampnet simulate --control` "
              "does; --set values go over them (default: the runtime's, passive)", None, dict(metavar="LAW")))
option(Option("--set", "quarter car: a vehicle or controller parameter's start value, e.g. --set m_s=450 "
              "--set c_sky=3000 (repeatable; the importer can change them too)", [],
              dict(metavar="NAME=VALUE", action="append")))
option(Option("--onnx", "write the ONNX graph here", kwargs=dict(metavar="OUT.onnx")))
option(Option("--header", "write the C/C++ header here", kwargs=dict(metavar="OUT.h")))
option(Option("--prefix", "the header's name prefix (default dn_model)", "dn_model"))
option(Option("--force", "replace existing output files (never the model, its envelope or another file of its "
              "directory; all outputs are checked before the first is written)", False,
              dict(action="store_true")))
option(Option("--target", "a ready-to-build folder for this core (with --out DIR): model.h, the library's "
              "sources, a CMakeLists.txt with the model's capacities, the toolchain file, an example firmware",
              None, dict(choices=("cortex-m4", "cortex-m7"))))
option(Option("--out", "--target: the folder to write", kwargs=dict(metavar="DIR")))


def _fmu_start_values(args, model=None) -> tuple[dict, dict, str | None]:
    """--controller and --set NAME=VALUE as the quarter car's vehicle and controller start values, and
    the law's registered name: the law built and calibrated on `model` (an MlpModel) by the control-law
    registry, the --set values over its fields."""
    from dampnet import _core
    from dampnet.model import ModelError

    vehicle, controller = {}, {}
    for item in args.set:
        name, sep, text = item.partition("=")
        if not sep or not name:
            raise ModelError(f"--set {item!r}: expected NAME=VALUE, e.g. --set m_s=450")
        target = vehicle if name in _core.VEHICLE_FIELDS else controller if name in _core.CONTROLLER_FIELDS else None
        if target is not None and name in target:
            raise ModelError(f"--set {name}: given twice: give each parameter once")
        if target is None:
            raise ModelError(f"--set {name}: not a vehicle or controller parameter; known: "
                             f"{', '.join([*_core.VEHICLE_FIELDS, *_core.CONTROLLER_FIELDS])}")
        try:
            target[name] = float(text)
        except ValueError:
            target[name] = text  # an enum field's name (integrator, damper_eval, accel_feature, kind)
    from dampnet.recipes import control_laws

    if not args.controller or args.controller == control_laws.EXTERNAL:   # external: the importer's u input
        return vehicle, {"kind": args.controller, **controller} if args.controller else controller, None
    from dampnet.sim.dampers import neural_spec
    from dampnet.sim.vehicle import LoopError, Vehicle

    try:
        law = control_laws.get(args.controller).name
        veh = Vehicle(**{k: v for k, v in vehicle.items() if k in Vehicle.__dataclass_fields__})
        veh.validate()
        tau = controller.get("u_tau_s")
        ctrl = control_laws.make(law, neural_spec(model), veh, u_tau_s=tau if isinstance(tau, float) else None)
    except (LoopError, TypeError) as e:
        raise ModelError(f"--controller: {e}") from None
    return vehicle, {**ctrl.to_dict(), **controller}, law


def _write_fmu(job: Job) -> str:
    from dampnet.export.fmu import build_fmu
    from dampnet.export.fmu.damper import MODEL_IDENTIFIER as DAMPER
    from dampnet.export.fmu.description import PLATFORM
    from dampnet.export.fmu.quarter_car import MODEL_IDENTIFIER as QUARTER_CAR

    args = job.args
    vehicle, controller, law = _fmu_start_values(args, job.model)
    interface = args.interface or ("both" if args.what == "damper" else "cs")
    build_fmu(job.model, args.fmu, fmi=args.fmi, interface=interface, what=args.what, overwrite=args.force,
              vehicle=vehicle or None, controller=controller or None, envelope=job.envelope, law=law)
    kinds = {"cs": "co-simulation", "me": "model exchange", "both": "co-simulation and model exchange"}[interface]
    ident = DAMPER if args.what == "damper" else QUARTER_CAR
    io = ("inputs x [m], v [m/s], a [m/s2], u, temperature [degC]; output force [N]" if args.what == "damper"
          else "inputs z_r [m], v_r [m/s], u; outputs the quarter car's motion and forces")
    return (f"{args.fmu}: FMI {args.fmi}.0 FMU {ident} ({kinds}; {PLATFORM[args.fmi]} binary and sources), {io}; "
            f"envelope_flags from {job.carries}")


def _check_onnx(args) -> None:
    from dampnet.model import ModelError

    try:
        import onnx  # noqa: F401
    except ImportError:
        raise ModelError("--onnx needs the onnx package: pip install 'dampnet[onnx]'") from None


def _write_onnx(job: Job) -> str:
    from dampnet.export import ONNX_OPSET, write_onnx

    model = job.model
    write_onnx(model, job.args.onnx, overwrite=job.args.force)
    return (f"{job.args.onnx}: ONNX opset {ONNX_OPSET}, inputs {', '.join(model.features)} "
            f"({', '.join(model.units)}), output force [N]"
            + (f"; the model's {len(model.terms)} physics term(s) are not in the graph" if model.terms else ""))


def _check_header(args) -> None:
    from dampnet.export import check_prefix

    check_prefix(args.prefix)


def _write_header(job: Job) -> str:
    from dampnet.export import write_header

    args = job.args
    write_header(job.model, args.header, args.prefix, overwrite=args.force, envelope=job.envelope)
    return (f"{args.header}: C/C++ header, prefix {args.prefix}; "
            + ("with the training envelope (P_ENVELOPE_DESC_INIT)" if job.envelope is not None else job.carries))


def _check_mcu(args) -> None:
    """Before any output is written (issue 49: `--header DIR/model.h --out DIR` wrote the header,
    then refused DIR): the folder may be written, and no file output lies inside it."""
    from pathlib import Path

    from dampnet.outputs import OutputError, check_output_dir

    if not args.target:
        raise ValueError("--out is the microcontroller folder: give --target cortex-m4|cortex-m7 with it")
    check_output_dir(args.out, "export-target", [args.model], force=args.force)
    folder = Path(args.out).resolve()
    for flag in sorted({t.output for t in TARGETS.values() if t.file_output}):
        value = getattr(args, OPTIONS[flag].dest, None)
        if value and Path(value).resolve().is_relative_to(folder):
            raise OutputError(f"{flag} {value}: is inside the --out folder {args.out}, which the export writes "
                              "whole: name a file outside it")


def _write_mcu(job: Job) -> str:
    from dampnet.export.mcu import capacities_for

    args = job.args
    out = export_firmware_folder(job.model, args.target, args.out, overwrite=args.force, model_name=args.model,
                                 inputs=[args.model])
    caps = ", ".join(f"{k.lower()} {v}" for k, v in capacities_for(job.model).items())
    return (f"{out}: dampnet for {args.target} (model.h, library sources, CMakeLists.txt with capacities {caps}, "
            f"toolchain file, example firmware, README.md)")


_FMU = ("--fmu", "--fmi", "--interface", "--what", "--force")
register(ExportTarget("fmu-damper", "an FMI 2.0/3.0 FMU of the damper (dampnet.export.fmu)", "--fmu", _FMU, _write_fmu,
                      when={"--what": "damper"}))
register(ExportTarget("fmu-quarter-car", "an FMI 2.0/3.0 co-simulation FMU of the quarter car with this damper",
                      "--fmu", (*_FMU, "--controller", "--set"), _write_fmu, when={"--what": "quarter-car"}))
register(ExportTarget("onnx", "the network as one ONNX graph (dampnet.export.write_onnx)", "--onnx",
                      ("--onnx", "--force"), _write_onnx, check=_check_onnx))
register(ExportTarget("header", "the C/C++ header `dampnet train` writes (dampnet.export.write_header)", "--header",
                      ("--header", "--prefix", "--force"), _write_header, check=_check_header))
register(ExportTarget("mcu", "a ready-to-build microcontroller folder (dampnet.export.mcu.export_target)", "--out",
                      ("--target", "--out", "--force"), _write_mcu, check=_check_mcu, file_output=False,
                      envelope=False, output_text="--target cortex-m4|cortex-m7 --out DIR"))

#: the built-in options (unregister keeps them)
BUILTIN_OPTIONS = tuple(OPTIONS)


def export_firmware_folder(model, target: str, out_dir, **kwargs):
    """dampnet.export.mcu.export_target with the example firmware's controller made for `model` by
    the control-law registry (control_laws.firmware_controller): `dampnet export --target`'s folder."""
    from dampnet.export.mcu import export_target
    from dampnet.recipes.control_laws import firmware_controller

    return export_target(model, target, out_dir, firmware_controller(model), **kwargs)


def write_firmware_vectors(path, vectors=None, model=None, controller=None):
    """The firmware's stored inputs, road and controller (dampnet.export.mcu.write_vectors) for `model`
    (default: the embedded default model): `vectors` (default make_vectors's) and `controller`
    (default the one the control-law registry makes for it, control_laws.firmware_controller). What
    cpp/embedded/CMakeLists.txt runs when the firmware is built without a vectors header (`python -m
    dampnet.recipes.export_targets vectors OUT.h`), and the firmware lab's write_vectors."""
    from dampnet.export.mcu import make_vectors, write_vectors
    from dampnet.modeldir import default_model
    from dampnet.recipes.control_laws import firmware_controller

    model = model or default_model()
    return write_vectors(path, make_vectors(model) if vectors is None else vectors,
                         controller or firmware_controller(model))


def main(argv=None) -> int:
    import argparse

    p = argparse.ArgumentParser(prog="python -m dampnet.recipes.export_targets",
                                description="the Cortex-M firmware's inputs, road and controller header")
    sub = p.add_subparsers(dest="cmd", required=True)
    v = sub.add_parser("vectors", help="write the firmware's inputs, road and controller header (dn_fw_vectors.h)")
    v.add_argument("out")
    a = p.parse_args(argv)
    write_firmware_vectors(a.out)
    return 0


if __name__ == "__main__":
    import sys

    sys.exit(main())
