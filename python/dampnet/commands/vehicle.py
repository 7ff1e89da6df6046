"""`dampnet vehicle MODEL --test NAME`: one full-vehicle test (the thesis's chapter 5.2: bsst, dlc,
road; every test of dampnet.recipes.maneuvers) with the damper model at all four corners, in the
runtime's FullCar."""

from __future__ import annotations

import argparse
import sys


def add_parser(subparsers) -> argparse.ArgumentParser:
    from dampnet.recipes import maneuvers
    from dampnet.recipes.control_laws import VEHICLE_DAMPING

    tests = "; ".join(f"{m.name} ({m.doc})" for m in maneuvers.MANEUVERS.values())
    p = subparsers.add_parser(
        "vehicle", help="run a damper model in the full vehicle: " + ", ".join(maneuvers.names()),
        description="Run MODEL (a model directory or model.json, a lookup-table JSON, 'truth' or "
                    "'truth:EFFECT,...', or 'linear:C' [N s/m]) at all four corners of the full vehicle "
                    "(a compact pickup; see docs/full-vehicle.md) and write metrics.json, run.npz and vehicle.png. "
                    f"Tests: {tests}. A test's settings are the options below it names; another test's "
                    "setting is refused.")
    p.add_argument("model")
    p.add_argument("--test", choices=maneuvers.names(), default="dlc", help="the test (default dlc)")
    for s in maneuvers.SETTINGS.values():
        by = ", ".join(f"{m.name} (default {m.defaults[s.name]})" for m in maneuvers.MANEUVERS.values()
                       if s.name in m.defaults)
        if s.kind == "flag":
            p.add_argument(s.cli, dest=s.name, action="store_true", default=None,
                           help=f"{s.text()}; of {by or 'no test'}")
        else:
            p.add_argument(s.cli, dest=s.name, type=_TYPES[s.kind], default=None, metavar=s.metavar,
                           help=f"{s.text()}; of {by or 'no test'}")
    p.add_argument("--profile", default=None, metavar="PROFILE",
                   help="the old spelling of --road: thesis (--road rough) or an ISO 8608 class A..H (--road iso:CLASS)")
    p.add_argument("--damping", choices=tuple(VEHICLE_DAMPING), default="low",
                   help="every corner's control law (dampnet.recipes.control_laws): "
                        + ", ".join(f"{k} = {v}" for k, v in VEHICLE_DAMPING.items())
                        + ", each limited to the damper's low..high levels")
    p.add_argument("--dt", type=float, default=1e-3, help="step [s]")
    p.add_argument("--out", default="vehicle_out", help="output directory")
    p.add_argument("--force", action="store_true", help="replace an existing run in --out")
    p.set_defaults(handler=run)
    return p


#: how argparse reads a setting of each kind (dampnet.recipes.maneuvers.Setting.kind)
_TYPES = {"float": float, "int": int, "seed": int, "choice": str, "road": str}


def check_options(args) -> None:
    """Every option within its range (dampnet.sim.limits; the test's settings as
    dampnet.recipes.maneuvers checks them, another test's refused), before anything runs."""
    from dampnet.recipes import maneuvers
    from dampnet.sim import limits

    limits.check_number("--dt", args.dt, limits.STEP_S)
    maneuvers.settings_of(args.test, _given(args))


def _given(args) -> dict:
    """The manoeuvre settings given on the command line (None: not given)."""
    from dampnet.recipes import maneuvers

    given = {name: getattr(args, name, None) for name in maneuvers.SETTINGS}
    old = getattr(args, "profile", None)
    if old is not None:
        if given.get("road") is not None:
            raise ValueError("--profile: the old spelling of --road; give --road only")
        if args.test not in maneuvers.takes("road"):
            raise ValueError(f"--profile: {args.test} does not take a road (it applies to "
                             f"{', '.join(maneuvers.takes('road'))}); drop --profile")
        given["road"] = _old_profile(old)
    return given


def _old_profile(value: str) -> str:
    """--profile's value (thesis, or an ISO 8608 class A..H) as the road --road names."""
    from dampnet.recipes import roads

    v = value.strip()
    if len(v) == 1 and v.upper() in "ABCDEFGH":
        return f"iso:{v.upper()}"
    if v.lower() == "thesis" or roads.is_named(v):
        return v
    raise ValueError(f"--profile {value!r}: expected thesis or an ISO 8608 class A..H (--profile is the old "
                     f"spelling of --road ROAD: {roads.usage()})")


def _maneuver(args):
    """The test's Maneuver (dampnet.recipes.maneuvers: its settings from the options given)."""
    from dampnet.recipes import maneuvers

    return maneuvers.build(args.test, args.dt, _given(args))


def run(args) -> int:
    """Check every option and the output, run the test (dampnet.recipes.maneuvers.run), write the
    run's directory (dampnet.sim.run_dir), print its summary; 0, or 2 with one line on bad input."""
    import os

    from dampnet.model import ModelError
    from dampnet.recipes import maneuvers
    from dampnet.sim import run_dir
    from dampnet.sim.dampers import load_spec
    from dampnet.sim.roads import RoadError
    from dampnet.sim.vehicle import LoopError

    try:
        check_options(args)
        run_dir.check(run_dir.FULL_CAR, args.out, [args.model] if os.path.exists(args.model) else [], args.force)
        spec = load_spec(args.model)
        man = _maneuver(args)
        print(f"running {man.name} ({man.road.shape[0] * man.dt:.1f} s simulated, "
              f"{man.road.shape[0]} steps) with {spec.name}, {args.damping} damping ...", flush=True)
        res = maneuvers.run(spec, man, args.damping)
    except (RoadError, LoopError, ModelError, ValueError, OSError, KeyError) as e:
        print(f"dampnet: error: {e}", file=sys.stderr)
        return 2
    title = f"{spec.name}, {args.damping} damping: {man.name}"
    try:
        run_dir.save_full_car(args.out, res, spec, title, lambda f: maneuvers.plot({spec.name: res}, f, title))
    except OSError as e:
        print(f"dampnet: error: {args.out}: cannot write the run ({e.strerror or e})", file=sys.stderr)
        return 2
    line = maneuvers.get(args.test).summary(res["metrics"])
    print(f"{title}: {line} -> {args.out}")
    if "coverage" in res:
        from dampnet.envelope.coverage import summary_line

        print(summary_line(spec.name, res["coverage"]) + " (the four corners together)")
    return 0
