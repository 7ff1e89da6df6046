"""`dampnet iri PROFILE.csv`: International Roughness Index (ASTM E1926) of a road profile."""

from __future__ import annotations

import argparse
import json

from dampnet.commands.common import error


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register the `iri` subcommand; its handler is `run`."""
    p = subparsers.add_parser(
        "iri", help="IRI (m/km) of a road profile (ASTM E1926)",
        description="International Roughness Index of a longitudinal profile: the Golden Car at "
                    "80 km/h, 250 mm moving average, 11 m initialisation, exact discretisation. "
                    "PROFILE is a CSV with columns distance_m,elevation_m (metres).")
    p.add_argument("profile", help="CSV file with columns distance_m,elevation_m")
    p.add_argument("--segment", type=float, default=None, metavar="M",
                   help="also report the IRI of each M-metre segment")
    p.add_argument("--json", default=None, metavar="FILE", help="write {overall, segments, ...} as JSON")
    p.set_defaults(handler=run)
    return p


def run(args) -> int:
    from dampnet.outputs import OutputError, check_output_file
    from dampnet.sim.roads import RoadError, iri, read_profile_csv

    try:
        if args.json:
            check_output_file(args.json, [args.profile])
        road = read_profile_csv(args.profile)
        res = iri(road, segment_m=args.segment)
    except (RoadError, OutputError) as e:
        return error(str(e))
    print(f"{args.profile}: {res.length_m:.2f} m at {res.dx_m * 1000:.1f} mm spacing"
          f"{' (resampled to uniform spacing)' if res.resampled else ''}; IRI {res.overall:.3f} m/km")
    for a, b, v in res.segments:
        print(f"  {a:10.2f} - {b:10.2f} m  {v:8.3f} m/km")
    if args.json:
        from dampnet.outputs import atomic_write_text

        try:
            atomic_write_text(args.json, json.dumps(res.to_dict(), indent=2) + "\n", overwrite=True)
        except OSError as e:
            return error(f"cannot write {args.json}: {e.strerror or e}")
    return 0
