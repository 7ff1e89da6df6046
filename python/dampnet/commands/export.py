"""`dampnet export MODEL --onnx OUT.onnx | --header OUT.h`: the model for other runtimes."""

from __future__ import annotations

import argparse
import sys


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "export", help="export a model: an FMI 2.0 FMU, an ONNX graph, a C/C++ header",
        description="Export MODEL (a model directory or model.json). --onnx: the network with its input "
                    "saturation and scalings as one ONNX graph (opset 17, float32, one input per feature "
                    "named as the feature, output 'force' [N]; a hybrid model's physics terms are listed "
                    "in its metadata, not in the graph). --fmu: the damper as an FMI 2.0 FMU, co-simulation and "
                    "model exchange "
                    "(inputs x, v, a, u, temperature; output force [N]; compiled here for linux64, sources "
                    "included). --header: the C/C++ header `dampnet train` writes.")
    p.add_argument("model")
    p.add_argument("--fmu", metavar="OUT.fmu",
                   help="write the damper FMU (FMI 2.0, co-simulation and model exchange) here")
    p.add_argument("--onnx", metavar="OUT.onnx", help="write the ONNX graph here")
    p.add_argument("--header", metavar="OUT.h", help="write the C/C++ header here")
    p.add_argument("--prefix", default="dn_model", help="the header's name prefix (default dn_model)")
    p.add_argument("--force", action="store_true", help="replace existing output files")
    p.set_defaults(handler=run)
    return p


def run(args) -> int:
    import os

    from dampnet.export import ONNX_OPSET, check_prefix, write_header, write_onnx
    from dampnet.model import ModelError
    from dampnet.modeldir import load_model

    if not args.onnx and not args.header and not args.fmu:
        print("dampnet: error: nothing to export: give --fmu OUT.fmu, --onnx OUT.onnx and/or --header OUT.h",
              file=sys.stderr)
        return 2
    try:
        model = load_model(args.model)
        if args.header:
            check_prefix(args.prefix)
        for out in (args.fmu, args.onnx, args.header):
            if out and os.path.exists(out) and not args.force:
                raise FileExistsError(f"{out}: exists; refusing to overwrite (use --force)")
        if args.fmu:
            from dampnet.fmu import MODEL_IDENTIFIER, build_damper_fmu

            build_damper_fmu(model, args.fmu, overwrite=args.force)
            print(f"{args.fmu}: FMI 2.0 FMU {MODEL_IDENTIFIER} (linux64 binary and sources), "
                  f"inputs x [m], v [m/s], a [m/s2], u, temperature [degC]; output force [N]")
        if args.onnx:
            try:
                import onnx  # noqa: F401
            except ImportError:
                raise ModelError("--onnx needs the onnx package: pip install 'dampnet[onnx]'") from None
            write_onnx(model, args.onnx, overwrite=args.force)
            print(f"{args.onnx}: ONNX opset {ONNX_OPSET}, inputs {', '.join(model.features)} "
                  f"({', '.join(model.units)}), output force [N]"
                  + (f"; the model's {len(model.terms)} physics term(s) are not in the graph" if model.terms else ""))
        if args.header:
            write_header(model, args.header, args.prefix, overwrite=args.force)
            print(f"{args.header}: C/C++ header, prefix {args.prefix}")
    except (ModelError, ValueError, OSError) as e:
        print(f"dampnet: error: {e}", file=sys.stderr)
        return 2
    return 0
