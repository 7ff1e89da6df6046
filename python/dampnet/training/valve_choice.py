"""Physics first: whether a free valve term goes under the network (issue 54 item 2).

The request's `valve` option (dampnet.training.settings.OPTIONS):
  "off"  (the Python default) the terms as requested; a valve among them stays.
  "on"   a free valve term ({"kind": "valve"}: bleed + blow-off per direction, dampnet.terms) is
         added to the terms unless one is there; it is fitted first by nonlinear least squares and
         the network learns what it leaves (dampnet.training.pipeline, step 4).
  "auto" (`dampnet train`'s and the demo's default) the model is trained both ways, same seed,
         same split, same restarts, and the hybrid is kept when its validation NRMSE (the error on
         the rows the fit held back to stop on, over the training force's range; for an average of
         restarts, the mean over its members) is lower than the network's alone by MIN_GAIN at
         least. model.meta["valve"] records both errors and the choice; `dampnet train` prints
         `sentence(record)`.

Why both ways and not a rule: on the rig's thesis plan (shim-stack valves with blow-off knees) the
hybrid's validation NRMSE is two thirds of the network's and its held-out error 2.2x the load
cell's noise against 3.1-3.7x (bench/RESULTS.md, "The valve term in the default training"), but a
damper without a blow-off valve (an MR damper) may be better without it; only the data can say.
It costs a second training.

Why a margin (MIN_GAIN) and not any gain: a term is not free. It costs the real-time step (the
Cortex-M4F quarter-car step 11 % more instructions and 6.5 KB of flash, bench/RESULTS.md) and it
changes where the model guesses: on UTFSM's MR damper the hybrid validated 1.7 % better and held out
3.8 % better, but its force at rest was 127 N off (the network alone's 92 N), and the diagnosis loop
after it ended at 40.5 N held out against 38.0 N from the network alone. On the rig's valves with
knees the hybrid validated 8-34 % better (seeds 0-2, one training and the default's restarts).
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from dampnet.features import FEATURES

#: the request's values: what `valve` may be
VALVE_CHOICES = ("auto", "on", "off")
#: a free valve term: its parameters fitted with each training
FREE_VALVE = {"kind": "valve"}
#: the least relative fall of the validation NRMSE that keeps the hybrid (module docstring)
MIN_GAIN = 0.05

#: "auto" tries the valve term only on training tests at this many control levels at least. Its
#: control gain s(u) = (1 + g_num u) / (1 + g_den u) bends between the levels as its two
#: parameters please when nothing between them holds it, and the validation rows (at the trained
#: levels) cannot see that: on the rig's quick plan (0 and 5 V trained, 2.25 V held out, seeds
#: 0-9) "auto" kept the hybrid for 7 seeds and the held-out NRMSE rose from 0.0315 to 0.0364
#: (median; bench/few_tests.py, bench/RESULTS.md "The valve term in the default training").
MIN_LEVELS = 3


def has_valve(terms: Sequence[dict]) -> bool:
    """Whether `terms` hold a valve term (free or with its parameters)."""
    return any(dict(t).get("kind") == FREE_VALVE["kind"] for t in terms or ())


def with_valve(terms: Sequence[dict]) -> list[dict]:
    """`terms` with a free valve term added unless they hold one."""
    terms = [dict(t) for t in terms or ()]
    return terms if has_valve(terms) else [*terms, dict(FREE_VALVE)]


def why_not_auto(terms: Sequence[dict], tests: Sequence, warm_start: bool) -> str | None:
    """Why "auto" cannot try the valve term on these training tests, or None when it can."""
    if has_valve(terms):
        return "the requested terms hold a valve term already"
    if warm_start:
        return "a warm start (init) trains one network"
    lacking = [t.test_id for t in tests if "displacement" not in t.channels]
    if lacking:
        return (f"the physics terms need a displacement channel, which test {lacking[0]}"
                + (f" and {len(lacking) - 1} more" if len(lacking) > 1 else "") + " lacks")
    return None


def too_few_levels(tests: Sequence) -> str | None:
    """Why "auto" does not try the valve term on these training tests (fewer than MIN_LEVELS
    nominal control levels), or None. Tests without a nominal control (a replay, random content)
    spread the control themselves: no level count is made then."""
    if not tests or any(t.control_nominal is None for t in tests):
        return None
    levels = sorted({float(t.control_nominal) for t in tests})
    if len(levels) >= MIN_LEVELS:
        return None
    unit = FEATURES[tests[0].control_name].unit
    return (f"the training tests hold {len(levels)} control level{'s' if len(levels) != 1 else ''} "
            f"({', '.join(f'{u:g}' for u in levels)} {unit}): the valve term's control gain needs {MIN_LEVELS} "
            "at least, one between the others")


def validation_nrmse(model, info) -> float:
    """The error the choice compares: the model's validation NRMSE (info.metrics["val"], the
    hybrid's force for a hybrid); for an average of restarts (no rows held back of its own) the
    mean of its members' (model.meta["restarts"]); NaN when the fit held nothing back."""
    val = info.metrics.get("val")
    if val is not None:
        return float(val)
    r = model.meta.get("restarts") or {}
    members = [run["val_nrmse"] for run in r.get("runs", []) if run["restart"] in r.get("averaged", [])]
    return float(np.mean(members)) if members else float("nan")


def record(without: float | None, with_: float | None, used: bool, why: str | None = None,
           times: dict[str, float] | None = None, failed: str | None = None) -> dict[str, Any]:
    """model.meta["valve"] for an "auto" choice: the two validation errors, which was kept, why
    it could not be tried (`why`) or why the hybrid's fit failed (`failed`), the two trainings'
    times [s]."""
    out: dict[str, Any] = {"choice": "auto", "used": bool(used)}
    if why is not None:
        out["not_tried"] = why
    if failed is not None:
        out["failed"] = failed
    if without is not None or with_ is not None:
        out["validation_nrmse"] = {"without": None if without is None else round(float(without), 7),
                                   "with": None if with_ is None else round(float(with_), 7)}
    if times:
        out["time_s"] = {k: round(float(v), 2) for k, v in times.items()}
    return out


def keep_hybrid(without: float, with_: float) -> bool:
    """The hybrid is kept when its validation error is lower than the network's alone by MIN_GAIN
    at least (a NaN never wins)."""
    return bool(np.isfinite(with_) and (not np.isfinite(without) or with_ <= (1.0 - MIN_GAIN) * without))


def sentence(rec: dict[str, Any] | None) -> str | None:
    """The choice in one line for `dampnet train` and the demo, or None when there was none."""
    if not rec or rec.get("choice") != "auto":
        return None
    if "not_tried" in rec:
        return f"valve term: not tried ({rec['not_tried']})"
    v = rec.get("validation_nrmse") or {}
    w, wo = v.get("with"), v.get("without")
    if w is None:
        return f"valve term: not used (its fit failed: {rec.get('failed', 'no model')})"
    verb = "used" if rec["used"] else "not used"
    return (f"valve term: {verb}, validation NRMSE {w:.4f} with it against {wo:.4f} without (kept when "
            f"{100 * MIN_GAIN:g} % lower at least; --valve on or off trains one way only)")
