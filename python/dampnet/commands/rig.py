"""`dampnet rig OUT`: generate a virtual shock-dyno dataset (the truth damper on a test plan)."""

from __future__ import annotations

import argparse
import os
import sys
import time

from dampnet.commands.common import error


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register the `rig` subcommand; its handler is `run`."""
    from dampnet.rig.effects import EFFECTS

    p = subparsers.add_parser(
        "rig", help="generate a dataset on the virtual shock dyno",
        description="Run a test plan on the physical truth damper and write a dataset directory "
                    "(manifest.csv + one CSV per test, SI units).")
    p.add_argument("out", nargs="?", help="output dataset directory (must not exist unless --force)")
    p.add_argument("--plan", default=None,
                   help="'thesis' (Table 2: 12 frequencies x 15 voltages), 'quick', or a JSON plan file")
    p.add_argument("--effects", default="",
                   help=f"comma-separated effects to switch on: {', '.join(sorted(EFFECTS))} "
                        "(--list-effects says what each is)")
    p.add_argument("--list-effects", action="store_true",
                   help="list the effect catalogue (dampnet.effects): each effect, its role in the rig, the "
                        "diagnosis candidate that detects it and what `dampnet train --add` adds; then exit")
    p.add_argument("--seed", type=int, default=0, help="random seed (noise, temperatures)")
    p.add_argument("--replay", default=None, metavar="ROAD[;ROAD...]",
                   help="track replay instead of the plan: one test per road (dampnet.recipes.roads, e.g. rough, "
                        "iso:C, or a CSV profile), whose displacement is a quarter car's damper stroke over it "
                        "(the truth damper in the car) at --speed under --control, played on the rig like a drive "
                        "file; each test is written as RPC III (<test>.rsp) beside its CSV (dampnet.campaign.replay)")
    p.add_argument("--speed", type=float, default=20.0, help="--replay: speed over the road [m/s] (default 20)")
    p.add_argument("--control", default="passive",
                   help="--replay: the car's control law (dampnet.recipes.control_laws, e.g. passive, "
                        "skyhook_onoff; default passive at high damping)")
    p.add_argument("--duration", type=float, default=6.0, help="--replay: seconds of each road kept (default 6)")
    p.add_argument("--corner", default=None, metavar="CORNER",
                   help="--replay: the stroke of this corner of the full vehicle (front/rear left/right: "
                        "dampnet.sim.full_car.runs.CORNERS; two tracks of each road, as `dampnet vehicle --test road "
                        "--road ROAD`; --control low, high or skyhook) instead of the quarter car")
    p.add_argument("--truth-channels", action="store_true",
                   help="also write noise-free true_force and true_acceleration columns")
    p.add_argument("--force", action="store_true", help="replace OUT if it exists")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(handler=run)
    return p


def run(args) -> int:
    """Generate and write the dataset; 0 on success, 2 (one-line message) on bad input."""
    from dampnet.data import DataError, write_dataset
    from dampnet.outputs import check_output_dir
    from dampnet.rig import generate, noise_floor_nrmse

    if args.list_effects:
        print(effect_list())
        return 0
    if args.out is None:
        return error("rig: the output dataset directory OUT is required (or --list-effects)")
    effects = [e.strip() for e in args.effects.split(",") if e.strip()]
    progress = not args.no_progress and sys.stderr.isatty()
    replaying = args.replay is not None  # `--replay ''` is a replay of nothing, not the thesis plan
    if replaying and not [r for r in args.replay.split(";") if r.strip()]:
        return error(f"rig: --replay: expected one or more roads separated by ';', got {args.replay!r}")
    if replaying and args.plan is not None:
        return error("rig: --replay and --plan: a replay runs roads, not a plan; give one of them")
    if args.corner is not None and not replaying:
        return error("rig: --corner: the corner of a full-car replay; give --replay ROAD too")
    plan = args.plan or "thesis"
    inputs = [] if plan in ("thesis", "quick") else [plan]
    if replaying:   # road CSV profiles are inputs too
        inputs = [r.strip() for r in args.replay.split(";") if os.path.exists(r.strip())]
    try:
        check_output_dir(args.out, "dataset", inputs, args.force)  # before the work, again when writing
        t0 = time.perf_counter()
        extras = {}
        if replaying:
            ds, extras = replay(args, effects)
        else:
            ds = generate(plan, effects=effects, seed=args.seed, progress=not args.no_progress,
                          truth_channels=args.truth_channels)
        t1 = time.perf_counter()
        out = write_dataset(ds, args.out, overwrite=args.force, progress=progress, inputs=inputs, extras=extras)
        t2 = time.perf_counter()
    except (DataError, ValueError, FileExistsError, OSError) as e:
        return error(str(e))
    if replaying:
        for t in ds.tests:
            m = t.meta
            print(f"{out / (t.test_id + '.csv')} (and .rsp): {m['road']}"
                  + (f" at {m['speed_m_s']:g} m/s" if m.get("speed_m_s") else "") + f", {m['control_law']}, "
                  f"{len(t)} samples over {t.time[-1]:.2f} s, stroke RMS {1e3 * m['stroke_rms_m']:.1f} mm, "
                  f"velocity RMS {m['velocity_rms_m_s']:.3f} m/s")
    n = sum(len(t) for t in ds.tests)
    print(f"{out}: {len(ds.tests)} tests, {n} samples, plan {ds.meta['plan']['name']}, effects "
          f"{','.join(effects) or 'none'}, seed {args.seed}; generated in {t1 - t0:.1f} s, written in "
          f"{t2 - t1:.1f} s; noise-floor NRMSE {noise_floor_nrmse(ds):.4f}")
    return 0


def replay(args, effects):
    """The replay dataset of --replay and its RPC III copies ({file name: writer}) for write_dataset."""
    from dampnet.data.lab.raw import require
    from dampnet.data.lab.rpc import write_test
    from dampnet.campaign.replay import replay_tests
    from dampnet.sim.roads import RoadError
    from dampnet.sim.vehicle import LoopError

    require("rpc3", "rpc3-file", args.out, "writing the replay tests as RPC III")   # before the simulation
    roads = [r.strip() for r in args.replay.split(";") if r.strip()]
    try:
        ds = replay_tests(roads, speed_m_s=args.speed, law=args.control, effects=effects, seed=args.seed,
                          duration_s=args.duration, truth_channels=args.truth_channels, corner=args.corner)
    except (RoadError, LoopError) as e:
        raise ValueError(f"--replay: {e}") from None
    return ds, {f"{t.test_id}.rsp": (lambda path, t=t: write_test(path, t)) for t in ds.tests}


def effect_list() -> str:
    """The effect catalogue in words: id, title, rig role, diagnosis, what --add adds."""
    from textwrap import fill

    from dampnet.effects import CATALOGUE, additions

    def para(text: str) -> str:
        return fill(text, width=100, initial_indent="    ", subsequent_indent="      ")

    lines = []
    for e in CATALOGUE.values():
        lines.append(f"{e.id}: {e.title}")
        lines.append(para(e.physics))
        lines.append(f"    rig: {e.rig_words()}")
        lines.append("    diagnosis: " + ("none detects it" if e.diagnosed_by is None else
                                          f"the {e.diagnosed_by} candidate (dampnet diagnose)"))
        if e.adds is not None:
            a = additions(e.id)
            what = ", ".join(a["features"]) + "".join(f", {k}" for k in a["feature_params"])
            lines.append(para(f"dampnet train --add {e.id}: {what} ({a['how']}: {a['why']})"))
    return "\n".join(lines)


def main(argv=None) -> int:
    """Run `rig` alone (python -m dampnet.commands.rig OUT ...)."""
    parser = argparse.ArgumentParser(prog="dampnet")
    sub = parser.add_subparsers(dest="command", required=True)
    add_parser(sub)
    args = parser.parse_args(["rig", *(sys.argv[1:] if argv is None else argv)])
    return args.handler(args)


if __name__ == "__main__":
    sys.exit(main())
