"""`dampnet study MODEL [DATA]`: the thesis's chapter 5 quarter-car study (Tables 6 and 7, skyhook)."""

from __future__ import annotations

import argparse
import sys


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "study", help="reproduce the thesis's quarter-car study (Tables 6, 7, skyhook)",
        description="Impulse and sine sweep at low and high damping, rough road at 10 and 20 m/s, skyhook "
                    "against passive - for MODEL, the lookup-table model fitted to DATA and, when DATA "
                    "comes from the virtual rig, the truth damper (with each model's error against it).")
    p.add_argument("model", help="model directory or model.json")
    p.add_argument("data", nargs="?", default=None, help="dataset (for the lookup table and the truth)")
    p.add_argument("--dt", type=float, default=1e-3)
    p.add_argument("--seed", type=int, default=0, help="seed of the rough road")
    p.add_argument("--out", default="study_out", help="output directory (study.json, study.txt, PNGs)")
    p.add_argument("--no-plots", action="store_true")
    p.add_argument("--quick", action="store_true",
                   help="shortened roads: a 5x faster sweep (0.5 octave/s) and half the rough road (92 m)")
    p.add_argument("--vehicle", action="store_true",
                   help="also the full vehicle (chapter 5.2): the bounce sine sweep and the ISO 3888-1 lane "
                        "change at 120 km/h, every model at low and high damping and under skyhook")
    p.add_argument("--control", action="store_true",
                   help="also semi-active control against the ideal (MODEL only): the force-tracking laws "
                        "(skyhook, groundhook, hybrid, clipped-optimal) through the damper's inverse beside "
                        "passive low and high, skyhook_continuous, the ideal semi-active damper and the ideal "
                        "active actuator, quarter car and full car, on ISO 8608 roads (200 m): Wk-weighted body "
                        "acceleration, travel, tyre load, force tracking; control_vs_ideal.png. About a minute "
                        "(--quick: class C at 80 km/h only)")
    p.add_argument("--control-classes", nargs="+", metavar="CLASS", default=None,
                   help="ISO 8608 road classes of --control, A to H (default B C D; C with --quick)")
    p.add_argument("--control-speeds", nargs="+", type=float, metavar="KMH", default=None,
                   help="vehicle speeds of --control [km/h] (default 40 80 120; 80 with --quick)")
    p.add_argument("--force", action="store_true", help="replace an existing study in --out")
    p.set_defaults(handler=run)
    return p


def run(args) -> int:
    """Check the options and the output, run the study (dampnet.recipes.study.run), write it
    (dampnet.recipes.study.save), print its tables; 0, or 2 with one line on bad input."""
    from dampnet.recipes import study
    from dampnet.sim import limits

    try:
        limits.check_number("--dt", args.dt, limits.STEP_S)
        limits.check_seed("--seed", args.seed)
        classes = _control_classes(args)
        study.check(args.out, (args.model, args.data), args.force)
        res = study.run(args.model, args.data, dt=args.dt, seed=args.seed, quick=args.quick, vehicle=args.vehicle,
                        control=args.control, control_classes=classes,
                        control_speeds=args.control_speeds, keep_runs=not args.no_plots,
                        progress=lambda s: print(f"  {s}", file=sys.stderr))
    except (ValueError, OSError) as e:
        print(f"dampnet: error: {e}", file=sys.stderr)
        return 2
    try:
        study.save(args.out, res, plots=not args.no_plots)
    except OSError as e:
        print(f"dampnet: error: {args.out}: cannot write the study ({e.strerror or e})", file=sys.stderr)
        return 2
    for line in study.lines(res, args.out, plots=not args.no_plots):
        print(line)
    return 0


def _control_classes(args) -> list[str] | None:
    """--control-classes and --control-speeds: only with --control, each class one the road registry
    builds (dampnet.sim.roads.iso_class_bounds checks it) and each speed in the simulation's range;
    the classes in capitals, or None (the study's default). ValueError naming the option."""
    from dampnet.sim import limits
    from dampnet.sim.roads import RoadError, iso_class_bounds

    for opt, given in (("--control-classes", args.control_classes), ("--control-speeds", args.control_speeds)):
        if given is not None and not args.control:
            raise ValueError(f"{opt} sets the control study's roads: give --control too")
    for s in args.control_speeds or ():
        limits.check_number("--control-speeds", s, limits.SPEED_KMH)
    if not args.control_classes:
        return None
    try:
        for c in args.control_classes:
            iso_class_bounds(c)
    except RoadError as e:
        raise ValueError(f"--control-classes: {e}") from None
    return [c.strip().upper() for c in args.control_classes]
