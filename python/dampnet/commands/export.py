"""`dampnet export MODEL --fmu OUT.fmu | --onnx OUT.onnx | --header OUT.h`: the model for other
tools and runtimes."""

from __future__ import annotations

import argparse
import sys


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "export", help="export a model: an FMI 2.0/3.0 FMU, an ONNX graph, a C/C++ header",
        description="Export MODEL (a model directory or model.json). --onnx: the network with its input "
                    "saturation and scalings as one ONNX graph (opset 17, float32, one input per feature "
                    "named as the feature, output 'force' [N]; a hybrid model's physics terms are listed "
                    "in its metadata, not in the graph). --fmu: an FMU (FMI 2.0 or 3.0; co-simulation, model "
                    "exchange or both) of the damper (inputs x, v, a, u, temperature; output force [N]; "
                    "parameters the feature constants and physics terms; the lag and friction states inside) "
                    "or of the quarter car (co-simulation: road in, motion out, every vehicle and controller "
                    "parameter exposed); compiled here for Linux x86-64, sources included so an importer can "
                    "rebuild it elsewhere. --header: the C/C++ header `dampnet train` writes. With an envelope.npz "
                    "beside the model (`dampnet train` writes one), the header and the FMU carry the training "
                    "envelope's bounded-time check (P_ENVELOPE_DESC_INIT; the FMU's envelope_flags output).")
    p.add_argument("model")
    p.add_argument("--fmu", metavar="OUT.fmu", help="write an FMU here (see --fmi, --interface, --what)")
    p.add_argument("--fmi", type=int, choices=(2, 3), default=2, help="FMI version of the FMU (default 2)")
    p.add_argument("--interface", choices=("cs", "me", "both"), default=None,
                   help="co-simulation, model exchange or both in one FMU (default: both for the damper, "
                        "cs for the quarter car, which is co-simulation only)")
    p.add_argument("--what", choices=("damper", "quarter-car"), default="damper",
                   help="the damper alone (default), or the quarter car with this damper (thesis Table 5 "
                        "vehicle; fixed step = its dt)")
    p.add_argument("--controller", metavar="LAW", default=None,
                   help="quarter car: the control law's start value (passive, skyhook_onoff, ...; default passive)")
    p.add_argument("--set", metavar="NAME=VALUE", action="append", default=[],
                   help="quarter car: a vehicle or controller parameter's start value, e.g. --set m_s=450 "
                        "--set c_sky=3000 (repeatable; the importer can change them too)")
    p.add_argument("--onnx", metavar="OUT.onnx", help="write the ONNX graph here")
    p.add_argument("--header", metavar="OUT.h", help="write the C/C++ header here")
    p.add_argument("--prefix", default="dn_model", help="the header's name prefix (default dn_model)")
    p.add_argument("--force", action="store_true",
                   help="replace existing output files (never the model, its envelope or another file of its "
                        "directory; all outputs are checked before the first is written)")
    # a microcontroller: dampnet.export.mcu (README: On a microcontroller)
    p.add_argument("--target", choices=("cortex-m4", "cortex-m7"), default=None,
                   help="a ready-to-build folder for this core (with --out DIR): model.h, the library's sources, "
                        "a CMakeLists.txt with the model's capacities, the toolchain file, an example firmware")
    p.add_argument("--out", metavar="DIR", help="--target: the folder to write")
    p.set_defaults(handler=run)
    return p


def run(args) -> int:
    from dampnet.envelope import ENVELOPE_JSON, ENVELOPE_NPZ, EnvelopeError, envelope_files, read_envelope
    from dampnet.export import ONNX_OPSET, check_prefix, write_header, write_onnx
    from dampnet.model import ModelError
    from dampnet.modeldir import load_model, model_file
    from dampnet.outputs import check_output_files

    if args.target or args.out:
        return _export_target(args)
    if not args.onnx and not args.header and not args.fmu:
        print("dampnet: error: nothing to export: give --fmu OUT.fmu, --onnx OUT.onnx and/or --header OUT.h",
              file=sys.stderr)
        return 2
    try:
        # every output checked before anything is written: none is the model, its envelope or an
        # existing file of its model directory (model.json's folder), no two are the same file, none
        # exists without --force
        model_json = model_file(args.model)
        check_output_files({"--fmu": args.fmu, "--onnx": args.onnx, "--header": args.header},
                           [args.model, model_json, *envelope_files(args.model),
                            model_json.parent if model_json.name == "model.json" else None], args.force)
        if args.header:
            check_prefix(args.prefix)
        if args.onnx:
            try:
                import onnx  # noqa: F401
            except ImportError:
                raise ModelError("--onnx needs the onnx package: pip install 'dampnet[onnx]'") from None
        model = load_model(args.model)  # refused here if the runtime's loader would refuse it
        try:
            envelope = read_envelope(args.model, model)
        except EnvelopeError as e:  # an export would carry the weaker ranges-only check for good
            raise EnvelopeError(f"{e} (to export with the training ranges only, move {ENVELOPE_NPZ} and "
                                f"{ENVELOPE_JSON} away)") from None
        carries = ("the training envelope's grid (ranges and pairs of inputs)" if envelope is not None
                   else f"training ranges only (no {ENVELOPE_NPZ} beside the model)")
        if args.fmu:
            _export_fmu(model, args, envelope, carries)
        if args.onnx:
            write_onnx(model, args.onnx, overwrite=args.force)
            print(f"{args.onnx}: ONNX opset {ONNX_OPSET}, inputs {', '.join(model.features)} "
                  f"({', '.join(model.units)}), output force [N]"
                  + (f"; the model's {len(model.terms)} physics term(s) are not in the graph" if model.terms else ""))
        if args.header:
            write_header(model, args.header, args.prefix, overwrite=args.force, envelope=envelope)
            print(f"{args.header}: C/C++ header, prefix {args.prefix}; "
                  + ("with the training envelope (P_ENVELOPE_DESC_INIT)" if envelope is not None else carries))
    except (ModelError, ValueError, OSError) as e:
        print(f"dampnet: error: {e}", file=sys.stderr)
        return 2
    return 0


def _fmu_start_values(args) -> tuple[dict, dict]:
    """--controller and --set NAME=VALUE as the quarter car's vehicle and controller start values."""
    from dampnet import _core
    from dampnet.model import ModelError

    if args.what != "quarter-car" and (args.controller or args.set):
        raise ModelError("--controller and --set are the quarter car's parameters: add --what quarter-car")
    vehicle, controller = {}, {}
    if args.controller:
        controller["kind"] = args.controller
    for item in args.set:
        name, sep, text = item.partition("=")
        if not sep or not name:
            raise ModelError(f"--set {item!r}: expected NAME=VALUE, e.g. --set m_s=450")
        target = vehicle if name in _core.VEHICLE_FIELDS else controller if name in _core.CONTROLLER_FIELDS else None
        if target is None:
            raise ModelError(f"--set {name}: not a vehicle or controller parameter; known: "
                             f"{', '.join([*_core.VEHICLE_FIELDS, *_core.CONTROLLER_FIELDS])}")
        try:
            target[name] = float(text)
        except ValueError:
            target[name] = text  # an enum field's name (integrator, damper_eval, accel_feature, kind)
    return vehicle, controller


def _export_fmu(model, args, envelope, carries: str) -> None:
    from dampnet.export.fmu import build_fmu
    from dampnet.export.fmu.damper import MODEL_IDENTIFIER as DAMPER
    from dampnet.export.fmu.description import PLATFORM
    from dampnet.export.fmu.quarter_car import MODEL_IDENTIFIER as QUARTER_CAR

    vehicle, controller = _fmu_start_values(args)
    interface = args.interface or ("both" if args.what == "damper" else "cs")
    build_fmu(model, args.fmu, fmi=args.fmi, interface=interface, what=args.what, overwrite=args.force,
              vehicle=vehicle or None, controller=controller or None, envelope=envelope)
    kinds = {"cs": "co-simulation", "me": "model exchange", "both": "co-simulation and model exchange"}[interface]
    ident = DAMPER if args.what == "damper" else QUARTER_CAR
    io = ("inputs x [m], v [m/s], a [m/s2], u, temperature [degC]; output force [N]" if args.what == "damper"
          else "inputs z_r [m], v_r [m/s], u; outputs the quarter car's motion and forces")
    print(f"{args.fmu}: FMI {args.fmi}.0 FMU {ident} ({kinds}; {PLATFORM[args.fmi]} binary and sources), {io}; "
          f"envelope_flags from {carries}")


def _export_target(args) -> int:
    """--target CPU --out DIR: dampnet.export.mcu.export_target."""
    from dampnet.export.mcu import capacities_for, export_target
    from dampnet.model import ModelError
    from dampnet.modeldir import load_model

    if not (args.target and args.out):
        print("dampnet: error: --target and --out go together: --target cortex-m4|cortex-m7 --out DIR",
              file=sys.stderr)
        return 2
    try:
        model = load_model(args.model)
        out = export_target(model, args.target, args.out, overwrite=args.force, model_name=args.model,
                            inputs=[args.model])
    except (ModelError, ValueError, OSError) as e:
        print(f"dampnet: error: {e}", file=sys.stderr)
        return 2
    caps = ", ".join(f"{k.lower()} {v}" for k, v in capacities_for(model).items())
    print(f"{out}: dampnet for {args.target} (model.h, library sources, CMakeLists.txt with capacities {caps}, "
          f"toolchain file, example firmware, README.md)")
    return 0
