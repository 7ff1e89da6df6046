"""The thesis's full-vehicle comparison (chapter 5.2, Figures 58-60) for dampnet: each damper
model (neural, lookup table, the rig's truth damper) in the same vehicle at its low and high
damping setting and under skyhook, in each test; the headline metrics side by side and each
model's difference from the truth damper."""

from __future__ import annotations

from typing import Callable

from dampnet.sim.full_car.maneuvers import Maneuver
from dampnet.sim.full_car.runs import DAMPING, run
from dampnet.sim.dampers import DamperSpec

#: the metric of each test that the table shows first, and the others it shows
HEADLINE = {"bsst": ("acc_rms_m_s2", "acc_peak_m_s2"),
            "dlc": ("a_y_peak_m_s2", "roll_peak_deg", "roll_rate_peak_deg_s", "yaw_rate_peak_deg_s",
                    "side_slip_peak_deg", "cones_hit"),
            "road": ("acc_rms_m_s2", "acc_wk_rms_m_s2", "roll_rate_rms_deg_s")}


def run_study(specs: list[DamperSpec], tests: dict[str, Maneuver], damping=DAMPING,
              progress: Callable[[str], None] | None = None, keep_runs: bool = False) -> dict:
    """{'results': {test: {damping: {model: metrics}}}, 'errors': ... vs the model named
    'truth' when there is one (relative, per headline metric), 'coverage': {test: {damping:
    {model: dampnet.envelope.coverage result}}} for neural models, 'runs' (with keep_runs)}."""
    results: dict = {}
    coverage: dict = {}
    runs: dict = {}
    for test, man in tests.items():
        for d in damping:
            for spec in specs:
                if progress:
                    progress(f"{test} {d}: {spec.name}")
                r = run(spec, man, d)
                results.setdefault(test, {}).setdefault(d, {})[spec.name] = r["metrics"]
                if "coverage" in r:
                    coverage.setdefault(test, {}).setdefault(d, {})[spec.name] = r["coverage"]
                if keep_runs:
                    runs.setdefault(test, {}).setdefault(d, {})[spec.name] = r
    out = {"results": results, "errors": relative_errors(results), "coverage": coverage,
           "tests": {t: m.meta.get("test") for t, m in tests.items()}}
    if keep_runs:
        out["runs"] = runs
    return out


def relative_errors(results: dict, reference: str = "truth") -> dict:
    """(model - truth) / truth of each headline metric (cones: the difference in count)."""
    errs: dict = {}
    for test, by_d in results.items():
        kind = test.split("_")[0]
        for d, by_model in by_d.items():
            ref = by_model.get(reference)
            if ref is None:
                continue
            for name, m in by_model.items():
                if name == reference:
                    continue
                row = {}
                for k in HEADLINE.get(kind, ()):
                    if k == "cones_hit":
                        row[k] = m[k] - ref[k]
                    elif ref.get(k):
                        row[k] = (m[k] - ref[k]) / abs(ref[k])
                errs.setdefault(test, {}).setdefault(d, {})[name] = row
    return errs


def text_table(study: dict) -> str:
    """The results as text: per test and damping, one row per model."""
    lines = []
    for test, by_d in study["results"].items():
        keys = HEADLINE.get(test.split("_")[0], ())
        lines.append(f"{test}: " + ", ".join(keys))
        for d, by_model in by_d.items():
            for name, m in by_model.items():
                vals = "  ".join(f"{m[k]:9.4g}" if not isinstance(m[k], int) else f"{m[k]:9d}" for k in keys)
                lines.append(f"  {d:8s} {name:10s} {vals}")
    return "\n".join(lines)
