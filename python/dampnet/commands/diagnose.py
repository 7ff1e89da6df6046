"""`dampnet diagnose MODEL DATA`: compare with measurements, localise the error, name the missing physics."""

from __future__ import annotations

import argparse

from dampnet.commands.common import DATA_HELP, add_channel_map_option, add_data_fix_options, apply_data_fixes, error, load_data
from dampnet.outputs import json_text


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "diagnose", help="find which physical effect a model is missing",
        description="Compare a model with measured data, localise its error (by test, within the cycle), "
                    "and test a catalogue of candidate physical effects against the residual "
                    "(cross-validation over tests, a phase-randomised null); test, without the catalogue, whether "
                    "structure is left in the residual at all, and for measurement artefacts (a force channel "
                    "recorded late, a drift over the run order). Prints a summary and a three-way verdict "
                    "(a catalogue effect explains it / structure left that no known effect explains / nothing "
                    "above the noise floor; or an artefact and its data fix); --json writes overall, worst_tests, "
                    "candidates (most likely first), leftover, artefacts, finding and verdict; "
                    "`dampnet train DATA --add EFFECT --diagnosis FILE` adds an effect with the parameters "
                    "estimated here. The effects are the catalogue's (`dampnet rig --list-effects`).")
    p.add_argument("model", help="model directory (or its model.json)")
    p.add_argument("data", help=f"dataset: {DATA_HELP}; 'utfsm' or 'labcontrol' for the real data")
    add_channel_map_option(p)
    p.add_argument("--json", metavar="FILE", help="write the diagnosis as JSON to FILE ('-' for stdout)")
    p.add_argument("--report", metavar="DIR", help="write an HTML report with pictures to DIR")
    p.add_argument("--surrogates", type=int, default=49, help="null surrogates (default 49)")
    p.add_argument("--seed", type=int, default=0)
    add_data_fix_options(p)
    p.set_defaults(handler=run)
    return p


def summary(d: dict, diagnosis_file: str | None = None) -> str:
    """The printed summary; with the JSON file written, each 'add it' command takes its parameters from it."""
    from dampnet.diagnosis.report import not_addable_words

    ov = d["overall"]
    lines = [f"overall: NRMSE {ov['nrmse']:.5f}, RMSE {ov['rmse_n']:.2f} N, max |error| {ov['max_abs_error_n']:.1f} N "
             f"over {ov['n_tests']} tests",
             "worst tests: " + ", ".join(f"{w['test_id']} (NRMSE {w['nrmse']:.4f})" for w in d["worst_tests"]),
             "where: " + ", ".join(f"{k} x{v['ratio']:.2f}" for k, v in d["localisation"]["regions"].items()
                                   if v["ratio"] is not None),
             "candidates (most likely first; score = held-out share of residual variance explained):"]
    for i, c in enumerate(d["candidates"], 1):
        if not c["testable"]:
            lines.append(f" {i}. {c['effect']} ({c['title']}): not testable ({c['note']})")
            continue
        par = ", ".join(f"{k} {v:.4g}" + (f" +- {c['uncertainty'][k]:.2g}" if c["uncertainty"].get(k) else "")
                        for k, v in c["parameters"].items() if isinstance(v, (int, float)))
        lines.append(f" {i}. {c['effect']} ({c['title']}): score {100 * c['score']:.2f} %, z {c['z']:.1f}, "
                     f"{'SIGNIFICANT' if c['significant'] else 'not significant'}; {par}")
        if c["significant"]:
            lines.append(f"    {c['evidence']}")
            if c.get("add_command"):
                lines.append(f"    add it: {c['add_command']}" + (f" --diagnosis {diagnosis_file}" if diagnosis_file else ""))
            else:
                lines.append(f"    cannot be added: {not_addable_words(c['effect'], c['missing_channels'])}")
    lines += leftover_lines(d)
    f = d["finding"]
    lines.append(f"verdict ({f['kind'].replace('_', ' ')}): {f['sentence']}")
    together = together_command(d, diagnosis_file)
    if together:
        lines.append(f"add them together, in this order (each explains what is left after the ones before it): {together}")
    return "\n".join(lines)


def together_command(d: dict, diagnosis_file: str | None = None) -> str | None:
    """`dampnet train DATA --add A --add B ...` for the effects the verdict names that the data can
    carry, when there are two or more (the diagnosis loop adds them so: dampnet.recipes.loop)."""
    commands = {c["effect"]: c.get("add_command") for c in d["candidates"]}
    named = [e for e in d["finding"].get("effects") or [] if commands.get(e)]
    if len(named) < 2:
        return None
    return (commands[named[0]] + "".join(f" --add {e}" for e in named[1:])
            + (f" --diagnosis {diagnosis_file}" if diagnosis_file else ""))


def leftover_lines(d: dict) -> list[str]:
    """The catalogue-independent test's answer and the artefact tests, in words."""
    lines = []
    for when, left in (("before the catalogue's effects", d["leftover"]["before_effects"]),
                       ("after the accepted effects", d["leftover"]["after_effects"]),
                       ("on the data with the artefacts' fixes applied", d["leftover"].get("after_artefact_fixes"))):
        if left is None:
            continue
        w = left["where"]
        lines.append(f"structure left {when}: {'YES' if left['significant'] else 'no'}, "
                     f"{left['structure_rms_n']:.1f} N RMS ({100 * left['score']:.1f} % of the residual's variance "
                     f"held out, z {left['z']:.1f}); model residual {left['model_residual_rms_n']:.1f} N RMS, noise "
                     f"floor {left['noise_floor_rms_n']:.2f} N RMS" + (f"; most uneven by {w['most_uneven'].replace('_', ' ')}"
                                                                    if w.get("most_uneven") else ""))
    for a in d["artefacts"]:
        if a.get("detected"):
            lines.append(f"ARTEFACT {a['artefact']}: {a['sentence']}")
        elif not a.get("testable", True):
            lines.append(f"artefact {a['artefact']}: not testable here: {a.get('note', '')}")
        elif a.get("note"):
            lines.append(f"artefact {a['artefact']}: not found: {a['note']}")
        some = a.get("not_testable") or []
        if some and a.get("testable", True):   # tested, but not in every test: which, and why
            lines.append(f"artefact {a['artefact']}: not testable here in {len(some)} test(s): "
                         + "; ".join(f"{x['test_id']} ({x['channel']}): {x['note']}" for x in some[:3])
                         + ("; ..." if len(some) > 3 else ""))
    return lines


def run(args) -> int:
    from dampnet.data import DataError
    from dampnet.diagnosis.context import build_context
    from dampnet.diagnosis.run import diagnose
    from dampnet.model import MlpModel, ModelError
    from dampnet.outputs import check_output_file, check_report_dir

    try:
        if args.surrogates < 1:
            raise ValueError(f"--surrogates: expected a positive count of null surrogates, got {args.surrogates}")
        if args.json and args.json != "-":
            check_output_file(args.json, [args.model, args.data])
        if args.report:
            check_report_dir(args.report, [args.model, args.data])
        model = MlpModel.load(args.model)
        ds = apply_data_fixes(load_data(args.data, args.channel_map), args)
        ctx = build_context(model, ds)
        d = diagnose(model, ds, ctx=ctx, n_surrogates=args.surrogates, seed=args.seed, dataset_label=args.data)
    except (DataError, ModelError, ValueError, OSError) as e:
        return error(str(e))
    print(summary(d, args.json if args.json and args.json != "-" else None))
    if args.json:
        text = json_text(d).rstrip("\n")
        if args.json == "-":
            print(text)
        else:
            from dampnet.outputs import atomic_write_text

            try:
                atomic_write_text(args.json, text + "\n", overwrite=True)
            except OSError as e:
                return error(f"{args.json}: cannot write ({e.strerror or e})")
    if args.report:
        from pathlib import Path

        from dampnet.diagnosis.report import write_report
        from dampnet.outputs import staged_files

        try:
            with staged_files(args.report) as tmp:
                write_report(ctx, d, tmp)
        except OSError as e:
            return error(f"{args.report}: cannot write the report ({e.strerror or e})")
        print(f"report: {Path(args.report) / 'index.html'}")
    return 0
