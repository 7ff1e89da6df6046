"""`dampnet plan-tests MODEL RUN... --budget N`: the dyno sines that would cover what the runs need
and the model's training data lack (dampnet.campaign.planning), as a rig plan and an operator's table."""

from __future__ import annotations

import argparse

from dampnet.commands.common import error


def _floats(text: str, name: str) -> list[float]:
    try:
        vals = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise ValueError(f"--{name}: expected comma-separated numbers, got {text!r}") from None
    if not vals:
        raise ValueError(f"--{name}: expected at least one number")
    return vals


def add_parser(subparsers) -> argparse.ArgumentParser:
    from dampnet.campaign import planning as P

    p = subparsers.add_parser(
        "plan-tests", help="propose the dyno tests that cover where runs leave the model's training data",
        description="From the damper inputs of RUNs that leave MODEL's training envelope, propose N sine tests "
                    "(frequency, amplitude, control) within the dyno's limits that cover them best (greedy set "
                    "cover); write them as a rig plan (--out, for `dampnet rig OUT --plan PLAN.json`) and a table "
                    "for the dyno operator (--table CSV; also printed).")
    p.add_argument("model", help="model directory (with envelope.npz: the joint envelope) or model.json")
    p.add_argument("runs", nargs="+", metavar="RUN",
                   help="a `dampnet simulate` or `dampnet vehicle` output directory (run.npz keeps each step's "
                        f"damper inputs), or a built-in case run with MODEL on the quarter car: a road, {P.case_names()}, "
                        f"e.g. {', '.join(P.CASES)} (both damping levels; NAME:low or NAME:high for one; "
                        "distance profiles such as rough-road at 10 and 20 m/s)")
    p.add_argument("--budget", type=int, required=True, help="number of tests to propose")
    p.add_argument("--out", help="write the plan (JSON) the rig reads: dampnet rig DATA --plan PLAN.json")
    p.add_argument("--table", help="write the operator's table (CSV)")
    p.add_argument("--max-stroke-m", type=float, default=P.DEFAULT_MAX_STROKE_M,
                   help=f"dyno stroke, peak to peak (2 x amplitude) [m] (default {P.DEFAULT_MAX_STROKE_M})")
    p.add_argument("--max-velocity-m-s", type=float, default=P.DEFAULT_MAX_VELOCITY_M_S,
                   help=f"dyno peak velocity [m/s] (default {P.DEFAULT_MAX_VELOCITY_M_S})")
    p.add_argument("--max-force-n", type=float, default=P.DEFAULT_MAX_FORCE_N,
                   help=f"dyno force [N], checked against the expected peak force (default {P.DEFAULT_MAX_FORCE_N:g})")
    p.add_argument("--frequencies", default=",".join(f"{f:g}" for f in P.DEFAULT_FREQUENCIES_HZ),
                   help="candidate frequencies [Hz], comma-separated (default %(default)s)")
    p.add_argument("--amplitudes", default=",".join(f"{a:g}" for a in P.DEFAULT_AMPLITUDES_M),
                   help="candidate amplitudes [m], comma-separated (default %(default)s)")
    p.add_argument("--controls", default=None,
                   help="candidate control levels [V or A, the model's control], comma-separated (default: the "
                        "training range's ends and middle and the runs' most common levels)")
    p.add_argument("--radius", type=float, default=None,
                   help="coverage radius in the planning space (default: the envelope's threshold)")
    p.add_argument("--force", action="store_true", help="replace existing --out / --table files")
    p.set_defaults(handler=run)
    return p


def run(args) -> int:
    import os

    from dampnet.campaign import planning as P
    from dampnet.envelope import load_envelope
    from dampnet.model import ModelError
    from dampnet.modeldir import load_model
    from dampnet.outputs import OutputError, atomic_write_text, check_output_files, json_text
    from dampnet.sim.roads import RoadError
    from dampnet.sim.vehicle import LoopError

    inputs = [args.model] + [r for r in args.runs if os.path.exists(r)]
    try:
        check_output_files({"--out": args.out, "--table": args.table}, inputs, args.force)
        model = load_model(args.model)
        env, note = load_envelope(args.model, model)
        runs = P.load_runs(model, env, args.runs, note)
        res = P.plan_tests(model, env, runs, args.budget, frequencies_hz=_floats(args.frequencies, "frequencies"),
                           amplitudes_m=_floats(args.amplitudes, "amplitudes"),
                           controls=None if args.controls is None else _floats(args.controls, "controls"),
                           max_stroke_m=args.max_stroke_m, max_velocity_m_s=args.max_velocity_m_s,
                           max_force_n=args.max_force_n, radius=args.radius)
        if args.out:
            atomic_write_text(args.out, json_text(P.rig_plan(res, os.path.splitext(os.path.basename(args.out))[0])),
                              overwrite=args.force)
        if args.table:
            atomic_write_text(args.table, P.csv_text(res), overwrite=args.force)
    except (ModelError, OutputError, RoadError, LoopError, ValueError, OSError, KeyError, FileExistsError) as e:
        return error(str(e))
    if env is None:
        print(f"note: {note}")
    print(P.summary(res))
    print(P.format_table(res) if res["tests"] else "no test covers any required point within the limits")
    for p in (args.out, args.table):
        if p:
            print(f"-> {p}")
    return 0

