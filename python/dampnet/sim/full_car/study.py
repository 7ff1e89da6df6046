"""The thesis's full-vehicle comparison (chapter 5.2, Figures 58-60) for dampnet: each damper
model (neural, lookup table, the rig's truth damper) in the same vehicle at its low and high
damping setting and under skyhook, in each test; the headline metrics side by side and each
model's difference from the truth damper."""

from __future__ import annotations

from typing import Any, Callable, Mapping

from dampnet.sim.full_car.maneuvers import Maneuver
from dampnet.sim.full_car.runs import run
from dampnet.sim.dampers import DamperSpec


def run_study(specs: list[DamperSpec], tests: dict[str, Maneuver], damping: tuple[str, ...],
              progress: Callable[[str], None] | None = None, keep_runs: bool = False, *,
              recipes: Mapping[str, Any], controller: Callable[[DamperSpec, str], Any]) -> dict:
    """{'results': {test: {damping: {model: metrics}}}, 'errors': ... vs the model named
    'truth' when there is one (relative, per headline metric), 'coverage': {test: {damping:
    {model: dampnet.envelope.coverage result}}} for neural models, 'headline_metrics': {test: the metrics the
    table shows, the first one first}, 'runs' (with keep_runs)}.

    recipes: each test's entry of dampnet.recipes.maneuvers (its .metrics and .headline);
    controller(spec, damping): every corner's controller (dampnet.recipes.control_laws.
    vehicle_controller); `recipes.maneuvers.run_study` passes both."""
    results: dict = {}
    coverage: dict = {}
    runs: dict = {}
    for test, man in tests.items():
        for d in damping:
            for spec in specs:
                if progress:
                    progress(f"{test} {d}: {spec.name}")
                r = run(spec, man, d, metrics=recipes[test].metrics, controller=controller(spec, d))
                results.setdefault(test, {}).setdefault(d, {})[spec.name] = r["metrics"]
                if "coverage" in r:
                    coverage.setdefault(test, {}).setdefault(d, {})[spec.name] = r["coverage"]
                if keep_runs:
                    runs.setdefault(test, {}).setdefault(d, {})[spec.name] = r
    headline = {t: tuple(recipes[t].headline) for t in tests}
    out = {"results": results, "errors": relative_errors(results, headline), "coverage": coverage,
           "tests": {t: m.meta.get("test") for t, m in tests.items()}, "headline_metrics": headline}
    if keep_runs:
        out["runs"] = runs
    return out


def relative_errors(results: dict, headline: dict, reference: str = "truth") -> dict:
    """(model - truth) / truth of each headline metric (headline: test -> its metrics; counts,
    such as cones hit: the difference)."""
    errs: dict = {}
    for test, by_d in results.items():
        for d, by_model in by_d.items():
            ref = by_model.get(reference)
            if ref is None:
                continue
            for name, m in by_model.items():
                if name == reference:
                    continue
                row = {}
                for k in headline.get(test, ()):
                    if isinstance(m[k], int) and not isinstance(m[k], bool):
                        row[k] = m[k] - ref[k]
                    elif ref.get(k):
                        row[k] = (m[k] - ref[k]) / abs(ref[k])
                errs.setdefault(test, {}).setdefault(d, {})[name] = row
    return errs


def text_table(study: dict) -> str:
    """The results as text: per test and damping, one row per model."""
    lines = []
    for test, by_d in study["results"].items():
        keys = study["headline_metrics"].get(test, ())
        lines.append(f"{test}: " + ", ".join(keys))
        for d, by_model in by_d.items():
            for name, m in by_model.items():
                vals = "  ".join(f"{m[k]:9.4g}" if not isinstance(m[k], int) else f"{m[k]:9d}" for k in keys)
                lines.append(f"  {d:8s} {name:10s} {vals}")
    return "\n".join(lines)
