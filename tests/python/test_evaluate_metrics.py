"""Error tables (overall, per test, per frequency), their JSON keys, the evaluate and
compare-algorithms commands, and the PNG plots."""

import json

import numpy as np
import pytest

from dampnet.cli import main
from dampnet.data import DynoTest, write_dataset
from dampnet.rig import generate
from dampnet.evaluation import plots
from dampnet.evaluation.lookup import fit_lookup
from dampnet.evaluation.metrics import error_stats, evaluate_predictions, format_table


def sine_test(tid, f_hz, volts, force, n=200):
    t = np.linspace(0, 1, n)
    return DynoTest(test_id=tid, time=t, frequency_hz=f_hz, amplitude_m=0.0254, control_nominal=volts,
                    channels={"force": np.asarray(force, dtype=float), "velocity": np.cos(t),
                              "displacement": np.sin(t), "voltage": np.full(n, volts)})


def test_error_stats_by_hand():
    y = np.array([0.0, 10.0, -10.0, 20.0])
    p = y + np.array([1.0, -1.0, 3.0, -1.0])
    s = error_stats(p, y)
    assert s["rmse_n"] == pytest.approx(np.sqrt((1 + 1 + 9 + 1) / 4))
    assert s["nrmse"] == pytest.approx(s["rmse_n"] / 30.0)  # range 20 - (-10)
    assert s["max_abs_error_n"] == 3.0
    assert s["mean_abs_error_n"] == 1.5
    assert s["mean_pct_error"] == pytest.approx(100 * 1.5 / 10.0)  # mean |F| = 40 / 4
    assert s["n_samples"] == 4 and s["force_range_n"] == 30.0


def test_tables_group_by_frequency_and_pool_samples():
    rng = np.random.default_rng(1)
    tests, preds = [], []
    for i, (f, u) in enumerate([(1.0, 0.0), (1.0, 5.0), (3.0, 0.0), (3.0, 5.0), (3.0, 5.0)]):
        y = 100 * np.sin(np.linspace(0, 6, 200)) * (1 + u)
        tests.append(sine_test(f"T{i}", f, u, y))
        preds.append(y + rng.normal(0, 1 + i, 200))
    rep = evaluate_predictions(tests, preds)
    assert set(rep) == {"overall", "per_frequency", "per_frequency_control", "per_test"}
    assert [r["frequency_hz"] for r in rep["per_frequency"]] == [1.0, 3.0]
    assert [r["n_tests"] for r in rep["per_frequency"]] == [2, 3]
    assert rep["per_frequency"][1]["controls"] == [0.0, 5.0]
    assert [(r["frequency_hz"], r["control"], r["n_tests"]) for r in rep["per_frequency_control"]] == [
        (1.0, 0.0, 1), (1.0, 5.0, 1), (3.0, 0.0, 1), (3.0, 5.0, 2)]
    # a group's numbers are those of its pooled samples, not averages of tests
    pooled = error_stats(np.concatenate(preds[2:]), np.concatenate([t.channels["force"] for t in tests[2:]]))
    for k in ("rmse_n", "nrmse", "max_abs_error_n", "mean_pct_error"):
        assert rep["per_frequency"][1][k] == pytest.approx(pooled[k])
    assert rep["overall"]["max_abs_error_n"] == max(r["max_abs_error_n"] for r in rep["per_test"])
    assert [r["test_id"] for r in rep["per_test"]] == [t.test_id for t in tests]
    assert "overall" in format_table(rep) and "lbf" in format_table(rep, lbf=True)


def test_mismatched_predictions_are_refused():
    t = sine_test("T1", 1.0, 0.0, np.ones(200))
    with pytest.raises(ValueError, match="T1"):
        evaluate_predictions([t], [np.ones(199)])


def is_png(path):
    return path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 5000


def test_plots_are_pngs(tmp_path):
    ds = generate("quick", seed=0)
    table = fit_lookup(ds)
    t = ds.tests[4]
    pred = {"lookup table": table.predict_test(t)}
    paths = [plots.error_histogram({"a": np.random.default_rng(0).normal(size=1000)}, tmp_path / "h.png"),
             plots.test_figure(t, pred, tmp_path / "t.png"),
             plots.lookup_figure(table, tmp_path / "l.png")]
    rep = evaluate_predictions(ds.tests, [table.predict_test(x) for x in ds.tests])
    paths.append(plots.error_heatmap(rep, tmp_path / "m.png", "mean_pct_error"))
    assert all(is_png(p) for p in paths)


@pytest.fixture(scope="module")
def model_and_data(tmp_path_factory):
    d = tmp_path_factory.mktemp("ev")
    plan = {"name": "ev", "frequencies_hz": [0.5, 3.0], "amplitudes_m": [0.0254],
            "voltages_v": [0.0, 2.25, 5.0], "samples": 2500}
    write_dataset(generate(plan, seed=2), d / "data")
    assert main(["train", str(d / "data"), "--out", str(d / "m"), "--quiet", "--decimate", "25",
                 "--max-epochs", "40", "--valve", "off"]) == 0
    return d


def test_evaluate_cli_json_has_stable_keys_and_plots(model_and_data, capsys):
    d = model_and_data
    rc = main(["evaluate", str(d / "m"), str(d / "data"), "--json", str(d / "all.json"),
               "--plots", str(d / "plots")])
    out = capsys.readouterr().out
    assert rc == 0 and "lookup table" in out
    rep = json.loads((d / "all.json").read_text())
    for k in ("overall", "per_frequency", "per_test", "lookup", "model", "data", "noise_floor", "regions"):
        assert k in rep
    for k in ("nrmse", "rmse_n", "max_abs_error_n", "mean_pct_error"):
        assert isinstance(rep["overall"][k], float) and isinstance(rep["lookup"]["overall"][k], float)
    assert rep["overall"]["n_tests"] == 6 and len(rep["per_test"]) == 6
    assert rep["lookup"]["source"] == "fitted on the model's training tests"
    # the rig's sines never stand still: no error at rest is claimed; the envelope's share is measured
    reg = rep["regions"]
    assert reg["at_rest"] is None and "at rest: not measured here (no sample stands still" in out
    assert reg["outside_envelope"]["measure"] == "ranges and joint envelope" and "outside the training envelope" in out
    assert reg["envelope_note"].startswith("joint envelope")
    names = sorted(p.name for p in (d / "plots").iterdir())
    assert "error_histogram.png" in names and "error_heatmap_nrmse.png" in names
    assert sum(n.startswith("test_") for n in names) == 2  # one control, one per frequency
    assert all(is_png(p) for p in (d / "plots").iterdir())


def test_evaluate_holdout_restricts_to_the_recorded_tests(model_and_data, capsys):
    d = model_and_data
    assert main(["evaluate", str(d / "m"), str(d / "data"), "--holdout", "--json", "-", "--no-lookup"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert [r["control"] for r in rep["per_test"]] == [2.25, 2.25]
    held = json.loads((d / "m" / "model.json").read_text())["meta"]["data"]["holdout_tests"]
    assert [r["test_id"] for r in rep["per_test"]] == held
    # the same numbers train wrote into metrics.json for the hold-out
    metrics = json.loads((d / "m" / "metrics.json").read_text())
    assert rep["overall"]["nrmse"] == pytest.approx(metrics["holdout"]["overall"]["nrmse"], rel=1e-12)
    # train wrote the hold-out's regions as evaluate finds them: 2.25 V, between the trained levels, is
    # outside the joint envelope throughout; the rig's sines never stand still
    reg = metrics["holdout_regions"]
    assert reg["at_rest"] is None and reg["outside_envelope"] == rep["regions"]["outside_envelope"]
    assert reg["outside_envelope"]["share_time"] == 1.0


def test_evaluate_errors(model_and_data, tmp_path, capsys):
    d = model_and_data
    assert main(["evaluate", str(tmp_path / "none"), str(d / "data")]) == 2
    assert main(["evaluate", str(d / "m"), str(d / "data"), "--plots", str(tmp_path / "p"),
                 "--plot-tests", "T999"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all(line.startswith("dampnet: error:") for line in err)


def test_compare_algorithms_table(model_and_data, tmp_path, capsys):
    d = model_and_data
    rc = main(["compare-algorithms", str(d / "data"), "--algorithms", "lm,scg", "--decimate", "50",
               "--max-epochs", "30", "--quiet", "--json", str(tmp_path / "t3.json")])
    assert rc == 0
    res = json.loads((tmp_path / "t3.json").read_text())
    assert [r["algorithm"] for r in res["rows"]] == ["lm", "scg"]
    for r in res["rows"]:
        assert 0 < r["nrmse_test"] < 0.2 and r["time_s"] > 0 and "nrmse_holdout" in r
    assert "lookup_holdout_nrmse" in res
    assert main(["compare-algorithms", str(d / "data"), "--algorithms", "lm,sgd"]) == 2
