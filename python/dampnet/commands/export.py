"""`dampnet export MODEL --fmu OUT.fmu | --onnx OUT.onnx | --header OUT.h | --target CPU --out DIR`:
the model for other tools and runtimes. The targets, their options and writers:
dampnet.recipes.export_targets."""

from __future__ import annotations

import argparse
import sys


def add_parser(subparsers) -> argparse.ArgumentParser:
    from dampnet.recipes import export_targets

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
                    "envelope's bounded-time check (P_ENVELOPE_DESC_INIT; the FMU's envelope_flags output). "
                    "Targets (dampnet.recipes.export_targets; an option that applies to none of the targets "
                    "given is refused): " + export_targets.description() + ".")
    p.add_argument("model")
    export_targets.add_arguments(p)   # every option, with the targets it applies to
    p.set_defaults(handler=run)
    return p


def run(args) -> int:
    from dampnet.envelope import ENVELOPE_JSON, ENVELOPE_NPZ, EnvelopeError, envelope_files, read_envelope
    from dampnet.model import ModelError
    from dampnet.modeldir import load_model, model_file
    from dampnet.outputs import check_output_files
    from dampnet.recipes.export_targets import OPTIONS, Job, check_options

    try:
        targets = check_options(args)
        # every output file checked before anything is written: none is the model, its envelope or
        # an existing file of its model directory (model.json's folder), no two are the same file,
        # none exists without --force (a folder target checks its folder itself)
        files = {t.output: getattr(args, OPTIONS[t.output].dest) for t in targets if t.file_output}
        if files:
            model_json = model_file(args.model)
            check_output_files(files, [args.model, model_json, *envelope_files(args.model),
                                       model_json.parent if model_json.name == "model.json" else None], args.force)
        for t in targets:
            if t.check is not None:
                t.check(args)
        job = Job(args, load_model(args.model))  # refused here if the runtime's loader would refuse it
        if any(t.envelope for t in targets):
            try:
                job.envelope = read_envelope(args.model, job.model)
            except EnvelopeError as e:  # an export would carry the weaker ranges-only check for good
                raise EnvelopeError(f"{e} (to export with the training ranges only, move {ENVELOPE_NPZ} and "
                                    f"{ENVELOPE_JSON} away)") from None
            job.carries = ("the training envelope's grid (ranges and pairs of inputs)" if job.envelope is not None
                           else f"training ranges only (no {ENVELOPE_NPZ} beside the model)")
        for t in targets:
            print(t.write(job))
    except (ModelError, ValueError, OSError) as e:
        print(f"dampnet: error: {e}", file=sys.stderr)
        return 2
    return 0
