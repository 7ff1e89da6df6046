"""Several datasets as one: a campaign plus the tests `dampnet plan-tests` proposed, run later."""

from __future__ import annotations

from typing import Sequence

from dampnet.data.types import DataError, Dataset


def merge_datasets(datasets: Sequence[Dataset]) -> Dataset:
    """The tests of every dataset, in order, as one Dataset.

    Refused (DataError naming both sources): a test id in two datasets, or different control
    channels (voltage vs current). The provenance (`meta`) is the first dataset's when every
    dataset's rig noise settings agree (so the noise floor still applies), else only the list of
    sources; `meta["merged"]` lists the sources and their test counts.
    """
    datasets = list(datasets)
    if not datasets:
        raise DataError("no datasets to merge")
    if len(datasets) == 1:
        return datasets[0]
    seen: dict[str, str] = {}
    control = None
    for ds in datasets:
        for t in ds.tests:
            if t.test_id in seen:
                raise DataError(f"test {t.test_id!r} is in both {seen[t.test_id]} and {ds.source}: test ids must be "
                                "unique across the datasets (rename one, e.g. in its manifest.csv)")
            seen[t.test_id] = ds.source
            if control is None:
                control = (t.control_name, ds.source)
            elif t.control_name != control[0]:
                raise DataError(f"{ds.source}: test {t.test_id} is controlled by {t.control_name}, but {control[1]} "
                                f"by {control[0]}: merge datasets of one control channel")
    first = datasets[0]
    same_rig = all(d.meta.get("generator") == first.meta.get("generator")
                   and d.meta.get("noise") == first.meta.get("noise") for d in datasets)
    meta = dict(first.meta) if same_rig else {}
    meta["merged"] = [{"source": d.source, "tests": len(d.tests)} for d in datasets]
    return Dataset(tests=_run_order_kept(datasets), source=" + ".join(d.source for d in datasets), meta=meta)


def _run_order_kept(datasets) -> list:
    """The tests, their stated run order (dampnet.data.runorder) carried over: `started` time stamps as
    they are; `run_order` numbers, when every dataset states them, continued from one dataset to
    the next (the datasets were run in the order given); a run_order some datasets lack states
    nothing, so it is dropped."""
    from dataclasses import replace

    from dampnet.data.runorder import RUN_ORDER_COLUMN

    tests = [t for d in datasets for t in d.tests]
    if not any(t.meta.get(RUN_ORDER_COLUMN) is not None for t in tests):
        return tests
    if not all(t.meta.get(RUN_ORDER_COLUMN) is not None for t in tests):
        return [replace(t, meta={k: v for k, v in t.meta.items() if k != RUN_ORDER_COLUMN}) for t in tests]
    out, base = [], 0.0
    for d in datasets:
        vals = [float(t.meta[RUN_ORDER_COLUMN]) for t in d.tests]
        lo = min(vals) if vals else 0.0
        out += [replace(t, meta={**t.meta, RUN_ORDER_COLUMN: base + v - lo + 1}) for t, v in zip(d.tests, vals)]
        base += (max(vals) - lo + 1) if vals else 0.0
    return out
