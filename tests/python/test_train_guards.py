"""Issue 14, item 9 (training side): data of an absurd scale or a fit that diverges end in a
one-line error and exit 2, never exit 0 with null metrics in metrics.json."""

from __future__ import annotations

import numpy as np
import pytest

from dampnet.cli import main
from dampnet.data import DataError, write_dataset
from dampnet.rig import generate
from dampnet.model import ModelError
from dampnet.training.pipeline import MAX_TRAINING_MAGNITUDE, train_dataset

PLAN = {"name": "tiny", "frequencies_hz": [0.5, 1.5], "amplitudes_m": [0.0254],
        "voltages_v": [0.0, 2.25, 5.0], "samples": 600}


@pytest.fixture(scope="module")
def tiny():
    return generate(PLAN, seed=5)


@pytest.mark.parametrize("channel, scale", [("force", 1e300), ("velocity", 1e200), ("force", 1e20)])
def test_absurd_scale_is_a_one_line_error_not_null_metrics(tiny, tmp_path, capsys, channel, scale):
    ds = tiny.subset([t.copy() for t in tiny.tests])
    for t in ds.tests:
        t.channels[channel] = t.channels[channel] * scale
    data = tmp_path / "data"
    write_dataset(ds, data)
    out = tmp_path / "m"
    rc = main(["train", str(data), "--out", str(out), "--quiet", "--max-epochs", "5"])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1, err
    assert f"training data: {channel} reaches" in err and "expected values below 1e+15" in err
    assert not out.exists()


def test_data_at_the_limit_train(tiny):
    ds = tiny.subset([t.copy() for t in tiny.tests])
    peak = max(float(np.max(np.abs(t.channels["force"]))) for t in ds.tests)
    for t in ds.tests:
        t.channels["force"] = t.channels["force"] * (0.5 * MAX_TRAINING_MAGNITUDE / peak)
    model, info, _ = train_dataset(ds, max_epochs=5)
    assert all(np.isfinite(v) for v in info.metrics.values())


def test_a_diverged_fit_is_a_model_error(tiny, monkeypatch):
    import dampnet.training.pipeline as pipeline

    real_fit = pipeline.fit_checked

    def diverging_fit(*a, **k):
        model, info = real_fit(*a, **k)
        info.metrics["test"] = float("nan")
        return model, info

    monkeypatch.setattr(pipeline, "fit_checked", diverging_fit)
    with pytest.raises(ModelError, match=r"training gave non-finite NRMSE \(test\)"):
        train_dataset(tiny, max_epochs=3)


def test_data_error_is_raised_for_infinite_values_too(tiny):
    ds = tiny.subset([t.copy() for t in tiny.tests])
    for t in ds.tests:  # inf: the readers refuse it; train_dataset called directly must too
        t.channels["force"][:] = np.inf
    with pytest.raises(DataError, match="force reaches inf"):
        train_dataset(ds, max_epochs=3)
