"""Issue 53, UTFSM: can a control-scaled, position-and-direction candidate ("mr_hysteresis") name what
the displacement gives on UTFSM while a control-independent rubber-mount loop stays "structure left"?

An MR damper's pre-yield hysteresis grows with the control (the yield stress grows with the current);
a rubber top mount's does not. bench/experiments/position_by_direction.py found that gas_spring's
Legendre columns times the direction of motion s = tanh(v / 0.05 v_max) are named on UTFSM (11.8 %,
z 20.9) but also name the rig's mount_hysteresis (58 %), a wrong name. Here the candidate is scored
beside the shipped catalogue (gas_spring unchanged) in these variants, P = Legendre P1..P3 of the
normalised position (degree >= 1: friction's direction term stays friction's), u = control / max|control|:

    plain     P s                          (position_by_direction's extra columns, for reference)
    u         P s u
    both      [P s, P s u]
    u_perp    P s u minus its pooled least-squares fit on P s (what only a control-scaled loop explains)

Datasets: UTFSM's default model (bench/real_data.py's split, its training tests) and the rig cases of
tests/python/test_diagnose_hidden.py (one effect each, the model without it), plus "mr" and "mr10" (the
rig's mount loop with its yield force scaled by the control, 30 + 250 u / 5 V N, yield travel 4 and
10 mm: a synthetic MR pre-yield loop).

    python bench/experiments/mr_hysteresis_candidate.py                   # UTFSM + rig seeds 1 3
    python bench/experiments/mr_hysteresis_candidate.py --rig-seeds       # UTFSM only
    python bench/experiments/mr_hysteresis_candidate.py --no-utfsm --variants u_perp
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench"))
sys.path.insert(0, str(ROOT / "tests" / "python"))

RIG_CASES = ("none", "gas_spring", "bump_stop", "thermal", "valve_lag", "friction", "coulomb",
             "mount_hysteresis", "mr", "mr10")
VARIANTS = ("plain", "u", "both", "u_perp")
ID = "mr_hysteresis_probe"


def _parts(ctx):
    from dampnet.diagnosis import catalogue as K

    c, h = K._x_frame(ctx)
    zv, _ = K._vel_norm(ctx)
    u = ctx.at_rows(ctx.control_name)
    us = max(float(np.max(np.abs(np.concatenate(u)))), 1e-12)
    plain = [K.gas_columns_of(x, c, h)[:, :3] * np.tanh(z / 0.05)[:, None]
             for x, z in zip(ctx.at_rows("displacement"), zv)]
    scaled = [p * (ui / us)[:, None] for p, ui in zip(plain, u)]
    return plain, scaled


def columns_of(variant):
    def columns(ctx, theta):
        plain, scaled = _parts(ctx)
        if variant == "plain":
            return plain
        if variant == "u":
            return scaled
        if variant == "both":
            return [np.hstack([p, q]) for p, q in zip(plain, scaled)]
        P, Q = np.vstack(plain), np.vstack(scaled)
        A = np.linalg.lstsq(P, Q, rcond=None)[0]
        return [q - p @ A for p, q in zip(plain, scaled)]
    return columns


def register(variant):
    from dampnet.diagnosis import catalogue as K
    from dampnet.effects import _POSITION, EffectInfo, register_effect

    register_effect(EffectInfo(id=ID, title="probe", physics="probe", rig="absent", diagnosed_by=ID, adds=_POSITION))
    K.register_candidate(K.Candidate(id=ID, needs="displacement, control", signature="probe",
                                     columns=columns_of(variant), testable=K._gas_testable))


def unregister():
    from dampnet.diagnosis import catalogue as K
    from dampnet.effects import CATALOGUE

    K.CANDIDATES.pop(ID, None)
    CATALOGUE.pop(ID, None)


def scores(model, ds, n_surrogates, variant):
    """variant "shipped": the catalogue as it is (with mr_hysteresis, as "MR"); "before": without it
    (the catalogue before this candidate); a probe variant: without it, the probe in its place."""
    from dampnet.diagnosis import catalogue as K
    from dampnet.diagnosis.run import diagnose

    built_in = K.CANDIDATES.get("mr_hysteresis")
    try:
        if variant != "shipped":
            K.CANDIDATES.pop("mr_hysteresis", None)
        if variant not in ("shipped", "before"):
            register(variant)
        d = diagnose(model, ds, n_surrogates=n_surrogates, seed=0)
    finally:
        unregister()
        if built_in is not None:
            K.CANDIDATES["mr_hysteresis"] = built_in
    f = d["finding"]
    named = ", ".join(f["effects"]).replace(ID, "MR").replace("mr_hysteresis", "MR") or "-"
    top = ", ".join(f"{c['effect'].replace(ID, 'MR').replace('mr_hysteresis', 'MR')} {100 * c['score']:.1f} % z {c['z']:.1f}"
                    for c in d["candidates"][:3] if c["testable"])
    mr = next((c for c in d["candidates"] if c["effect"] in (ID, "mr_hysteresis")), None)
    mr_s = (f"{100 * mr['score']:.1f} % z {mr['z']:.1f}" + (f" given {'+'.join(mr['given'])}" if mr.get("given") else "")
            if mr and mr["testable"] else "-")
    return f"| {variant} | {f['kind']} | {named} | {mr_s} | {top} |"


@dataclass
class _MrLoop:
    """The rig's mount loop (Bouc-Wen, 4 mm) with its yield force scaled by the control: F_y(u) =
    F_y0 + F_y1 u / u_max, as an MR damper's pre-yield loop (Spencer 1997's alpha = alpha_a + alpha_b u)."""

    f0_n: float = 30.0
    f1_n: float = 250.0
    u_max_v: float = 5.0
    yield_travel_m: float = 0.004

    def make(self):
        from dampnet.rig.effects import MountHysteresis

        outer = self

        @dataclass
        class MrPreYield(MountHysteresis):
            name = "mr_preyield_test"

            def force(self, ctx):
                base = super().force(ctx) / self.yield_force_n
                return base * (outer.f0_n + outer.f1_n * np.asarray(ctx.voltage) / outer.u_max_v)

        return MrPreYield(yield_travel_m=self.yield_travel_m)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rig-seeds", type=int, nargs="*", default=[1, 3])
    ap.add_argument("--cases", nargs="*", default=list(RIG_CASES))
    ap.add_argument("--variants", nargs="*", default=list(VARIANTS),
                    help="probe variants scored besides 'before' (the catalogue without mr_hysteresis) and "
                         "'shipped' (with it)")
    ap.add_argument("--no-utfsm", action="store_true")
    args = ap.parse_args(argv)
    variants = ["before", "shipped"] + list(args.variants)
    head = "| variant | finding | named | MR candidate | top three |\n|---|---|---|---|---|"
    if not args.no_utfsm:
        from real_data import default_on_split

        t0 = time.time()
        _, first, train_ds = default_on_split("utfsm")
        print(f"\nutfsm (default model, {time.time() - t0:.0f} s)\n{head}", flush=True)
        for v in variants:
            print(scores(first.model, train_ds, 49, v), flush=True)

    from dampnet.rig import generate
    from dampnet.training.pipeline import train_dataset
    from test_diagnose_hidden import N_SUR, PLAN, TRAIN, _PlainCoulomb

    for seed in args.rig_seeds:
        for case in args.cases:
            effects = ([] if case == "none" else [_PlainCoulomb()] if case == "coulomb"
                       else [_MrLoop().make()] if case == "mr"
                       else [_MrLoop(yield_travel_m=0.010).make()] if case == "mr10" else [case])
            rig = generate(PLAN, effects=effects, seed=seed)
            model, _, _ = train_dataset(rig, **TRAIN)
            print(f"\nrig {case} seed {seed}\n{head}", flush=True)
            for v in variants:
                print(scores(model, rig, N_SUR, v), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
