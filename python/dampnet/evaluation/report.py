"""A model's evaluation on a set of tests, beside the lookup-table baseline: what `dampnet evaluate` prints.

  evaluate(model, dataset_or_tests, lookup=None): evaluation() of a Dataset (dampnet.evaluate)
  evaluation(model, tests, lookup=None, envelope=None) -> {"model", "overall", "per_frequency",
      "per_frequency_control", "per_test", "regions" (at rest, outside the envelope:
      dampnet.evaluation.regions), "lookup": {same tables} | absent}
  lookup_for(model_path, ds, holdout_ids) -> (LookupTable, where it came from)
  write_plots(model, tests, report, out_dir, lookup=None, plot_tests=None) -> [paths]
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np

from dampnet.data import Dataset, DataError
from dampnet.evaluation.lookup import LookupTable, fit_lookup
from dampnet.evaluation.metrics import evaluate_predictions
from dampnet.evaluation.regions import region_errors
from dampnet.predict import predict_force
from dampnet.schema import load_json


def evaluation(model, tests: Sequence[Any], lookup: LookupTable | None = None, envelope=None) -> dict[str, Any]:
    """Tables of `model` (an MlpModel, hybrid terms included) on `tests`, its error at rest and
    outside its training envelope (`envelope`: the model's, dampnet.envelope; None: its training
    ranges only; dampnet.evaluation.regions) and the tables of `lookup` if given."""
    tests = list(tests)
    preds = [predict_force(model, t) for t in tests]
    rep = {"model": {"id": model.model_id(), "features": model.features, "terms": model.terms,
                     "algorithm": model.meta.get("algorithm")},
           **evaluate_predictions(tests, preds),
           "regions": region_errors(model, tests, preds, envelope)}
    if lookup is not None:
        rep["lookup"] = evaluate_predictions(tests, [lookup.predict_test(t) for t in tests])
    return rep


def evaluate(model, data, lookup: LookupTable | None = None, envelope=None) -> dict[str, Any]:
    """Error tables of `model` on `data` (a Dataset or a list of DynoTests): overall, per
    frequency, per frequency and control, per test (errors in N, NRMSE as a fraction of the
    force range), the error at rest and outside the training envelope ("regions"); with
    `lookup`, the lookup-table baseline's tables under "lookup"."""
    return evaluation(model, data.tests if isinstance(data, Dataset) else data, lookup, envelope)


def lookup_for(model_path: str | Path, ds: Dataset, holdout_ids: Sequence[str]):
    """The lookup-table baseline to show beside a model: (table, source description).

    The one fitted on the model's training tests (metrics.json next to model.json) if
    there is one; else fitted on the tests of `ds` outside the model's hold-out; else
    (ds holds only hold-out tests) on `ds` itself, which flatters the baseline.
    """
    p = Path(model_path)
    mfile = (p if p.is_dir() else p.parent) / "metrics.json"
    if mfile.is_file():  # optional: a damaged metrics.json falls back to fitting a table
        try:
            d = load_json(mfile, DataError)
            if isinstance(d, dict) and isinstance(d.get("lookup_table"), dict):
                return LookupTable.from_dict(d["lookup_table"]), "fitted on the model's training tests"
        except (KeyError, TypeError, ValueError):
            pass
    held = set(holdout_ids)
    rest = [t for t in ds.tests if t.test_id not in held]
    if rest:
        return fit_lookup(rest), "fitted on the evaluated data's non-hold-out tests"
    return fit_lookup(ds.tests), "fitted on the evaluated tests themselves (optimistic)"


def pick_plot_tests(tests: Sequence[Any], wanted: Sequence[str] | None = None, n: int = 4) -> list[Any]:
    """Tests to draw: the ones named, else up to n spread over frequency (the thesis drew 0.25,
    1, 2 and 3 Hz at 2.25 V), preferring the control value most tests share."""
    tests = list(tests)
    if wanted:
        by_id = {t.test_id: t for t in tests}
        missing = [w for w in wanted if w not in by_id]
        if missing:
            raise DataError(f"--plot-tests: no test(s) {missing} in the evaluated data")
        return [by_id[w] for w in wanted]
    if len(tests) <= n:
        return tests
    ctrls = [t.control_nominal for t in tests]
    common = max(set(ctrls), key=ctrls.count)
    pool = [t for t in tests if t.control_nominal == common] or tests
    pool = sorted(pool, key=lambda t: (t.frequency_hz or 0.0))
    idx = np.unique(np.round(np.linspace(0, len(pool) - 1, min(n, len(pool)))).astype(int))
    return [pool[i] for i in idx]


def write_plots(model, tests: Sequence[Any], report: dict[str, Any], out_dir: str | Path,
                lookup: LookupTable | None = None, plot_tests: Sequence[str] | None = None) -> list[Path]:
    """error_histogram.png, error_heatmap_nrmse.png, test_<id>.png per chosen test, lookup_table.png."""
    from dampnet.evaluation import plots  # matplotlib: only when drawing

    out = Path(out_dir)
    tests = list(tests)
    paths = []
    errs = {"MLP": np.concatenate([predict_force(model, t) - t.channels["force"] for t in tests])}
    if lookup is not None:
        errs["lookup table"] = np.concatenate([lookup.predict_test(t) - t.channels["force"] for t in tests])
    paths.append(plots.error_histogram(errs, out / "error_histogram.png"))
    if len(report["per_test"]) > 1:
        paths.append(plots.error_heatmap(report, out / "error_heatmap_nrmse.png", "nrmse",
                                         "MLP: NRMSE per test (frequency x control)"))
        paths.append(plots.error_heatmap(report, out / "error_heatmap_max_error.png", "max_abs_error_n",
                                         "MLP: maximum |error| per test [N]"))
    for t in pick_plot_tests(tests, plot_tests):
        preds = {"MLP": predict_force(model, t)}
        if lookup is not None:
            preds["lookup table"] = lookup.predict_test(t)
        paths.append(plots.test_figure(t, preds, out / f"test_{t.test_id}.png"))
    if lookup is not None:
        paths.append(plots.lookup_figure(lookup, out / "lookup_table.png"))
    return paths
