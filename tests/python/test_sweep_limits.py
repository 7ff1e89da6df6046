"""`dampnet sweep` refuses up front, in one line naming the field, what used to fail late (issue 29):
an output directory inside an input dataset (every cell failed with InputChanged), non-finite or
out-of-range numbers of a random distribution (OverflowError tracebacks), samples drawn outside
their parameter's range, and specs too large to list (10^6 cells never finished submitting;
n = 10^9 samples ran out of memory). No cluster is started: these are refused before one."""

from __future__ import annotations

import pytest

import needs

for _module in ("dask.distributed", "pandas", "pyarrow"):
    needs.need_module(_module)

from dampnet.cli import main  # noqa: E402
from dampnet.sweep import SpecError, parse_spec  # noqa: E402
from dampnet.sweep.grid import MAX_CELLS, MAX_CELLS_CEILING, expand  # noqa: E402
from test_sweep import one_line_error  # noqa: E402  (exit 2, one line, the fragments in it)


def test_an_output_inside_an_input_dataset_is_refused(tmp_path, capsys):
    data = tmp_path / "data"
    data.mkdir()
    (data / "manifest.csv").write_text("test_id,file\n")
    spec = tmp_path / "s.toml"
    spec.write_text(f"[training]\ndatasets = ['{data}']\n")
    for extra in ([], ["--force"], ["--resume"]):
        one_line_error(capsys, ["sweep", str(spec), "--out", str(data / "sweep"), *extra],
                       f"{data / 'sweep'}: is inside an input directory of this command ({data})",
                       "name a directory outside it")
    assert sorted(p.name for p in data.iterdir()) == ["manifest.csv"]
    # a directory that is no dataset (it would be hashed whole, e.g. "/") is refused as one
    spec.write_text(f"[training]\ndatasets = ['{tmp_path}']\n")
    one_line_error(capsys, ["sweep", str(spec), "--out", str(tmp_path / "o")], "line 2", "training.datasets[0]",
                   "a directory without manifest.csv")


BAD_RANDOM = [
    ("speed = {uniform = [nan, 10]}", "simulation.random.speed: uniform: expected two finite numbers, got [nan, 10]"),
    ("speed = {uniform = [1, inf]}", "simulation.random.speed: uniform: expected two finite numbers, got [1, inf]"),
    ("speed = {loguniform = [1, inf]}", "simulation.random.speed: loguniform: expected two finite numbers"),
    ("speed = {normal = [10, -inf]}", "simulation.random.speed: normal: expected two finite numbers"),
    ("speed = {uniform = [-1e308, 1e308]}", "simulation.random.speed: uniform = [-1e+308, 1e+308]: the range is too wide"),
    ("speed = {uniform = [-5, 5]}", "simulation.random.speed: uniform = [lo, hi]: lo: expected a number in (0, 100] m/s, got -5"),
    ("speeds = {normal = [-3, 1]}", "simulation.random.speeds: normal = [mean, sd]: mean: expected a number in (0, 100] m/s"),
    ("road_seed = {integers = [-3, 4]}", "simulation.random.road_seed: integers = [lo, hi]: lo: expected an integer >= 0"),
    ("speed = {normal = [10, 5]}", "simulation.random.speed: sample 24 of the normal distribution is out of the "
                                   "parameter's range (expected a number in (0, 100] m/s, got -3.5"),
]


@pytest.mark.parametrize("table, line, fragment", [
    ("simulation", "speeds = [1000]", "simulation.speeds[0]: expected a number in (0, 100] m/s, got 1000"),
    ("fullcar", "speeds_kmh = [0]", "fullcar.speeds_kmh[0]: expected a number in (0, 360] km/h, got 0"),
    ("fullcar", "dt = 0.02", "fullcar.dt: expected a number in [1e-06, 0.01] s, got 0.02"),
])
def test_speeds_and_steps_have_the_commands_ranges(tmp_path, capsys, table, line, fragment):
    """A spec's speeds and step take the ranges `dampnet simulate` / `vehicle` check
    (dampnet.sim.limits), not a copy: what a command refuses, a sweep refuses."""
    spec = tmp_path / "s.toml"
    spec.write_text(f"[{table}]\n{line}\n")
    one_line_error(capsys, ["sweep", str(spec), "--out", str(tmp_path / "o")], f"{spec}: line 2: {fragment}")


@pytest.mark.parametrize("line, fragment", BAD_RANDOM)
def test_bad_random_numbers_are_one_line_errors_naming_the_field(tmp_path, capsys, line, fragment):
    spec = tmp_path / "s.toml"
    spec.write_text(f"[simulation]\nroads = ['iso:A']\n[simulation.random]\nn = 50\nseed = 1\n{line}\n")
    one_line_error(capsys, ["sweep", str(spec), "--out", str(tmp_path / "o")], f"{spec}: line 6: {fragment}")
    assert not (tmp_path / "o").exists()


def test_a_vehicle_draw_names_its_sub_table(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text("[simulation]\nroads = ['impulse']\n[simulation.random]\nn = 3\nseed = 0\n"
                    "[simulation.random.vehicle]\nm_s = {uniform = [200, inf]}\n")
    one_line_error(capsys, ["sweep", str(spec), "--out", str(tmp_path / "o")],
                   "line 7: simulation.random.vehicle.m_s: uniform: expected two finite numbers")


def test_specs_beyond_the_cell_limit_are_refused_before_any_cell_is_listed(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text("[simulation]\nroads = ['iso:A']\n[simulation.random]\nn = 1000000000\nseed = 1\n"
                    "speed = {uniform = [1, 2]}\n")
    one_line_error(capsys, ["sweep", str(spec), "--out", str(tmp_path / "o")],
                   f"{spec}: line 4: simulation.random.n: 1,000,000,000 random samples, more than the limit of "
                   f"{MAX_CELLS:,} cells", "--max-cells N raises it")
    seeds = list(range(1000))
    spec.write_text(f"[simulation]\nroads = ['rough']\nroad_seeds = {seeds}\nspeeds = {[0.1 * k for k in range(1, 1001)]}\n")
    one_line_error(capsys, ["sweep", str(spec), "--out", str(tmp_path / "o")],
                   "the spec makes up to 1,000,000 cells (simulation 1,000,000 (1000 road_seed x 1000 speed))",
                   f"more than the limit of {MAX_CELLS:,} cells")
    assert not (tmp_path / "o").exists()
    # the limit is an option, itself bounded
    spec.write_text("[simulation]\nroads = ['rough']\nroad_seeds = [0, 1]\nspeeds = [5.0, 10.0]\n")
    one_line_error(capsys, ["sweep", str(spec), "--out", str(tmp_path / "o"), "--max-cells", "3"],
                   "up to 4 cells", "more than the limit of 3 cells")
    for bad in ("0", str(MAX_CELLS_CEILING + 1)):
        one_line_error(capsys, ["sweep", str(spec), "--out", str(tmp_path / "o"), "--max-cells", bad],
                       f"--max-cells: expected an integer in [1, {MAX_CELLS_CEILING:,}], got {bad}")
    sp = parse_spec(spec.read_text(), source="s.toml")
    assert len(expand(sp, max_cells=4)) == 4
    with pytest.raises(SpecError, match="more than the limit of 3 cells"):
        expand(sp, max_cells=3)


def test_the_help_states_the_limits_the_code_uses(capsys):
    from dampnet.sweep.runner import NO_WORKER_NOTICE_S, WORKER_TIMEOUT_S

    with pytest.raises(SystemExit):
        main(["sweep", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert f"default {MAX_CELLS}, at most {MAX_CELLS_CEILING}" in text
    assert f"(default {WORKER_TIMEOUT_S:g};" in text and f"after {NO_WORKER_NOTICE_S:g} s" in text


@pytest.mark.parametrize("line, fragment", [
    ("max_epochs = 0", "line 3: training.max_epochs: max_epochs (--max-epochs, the epoch limit): expected a whole "
                       "number in [1, 1000000], got 0"),
    ("seeds = [1, -1]", "line 3: training.seeds[1]: seed (--seed"),
    ("hidden = [30, 385]", "line 3: training.hidden[1]: hidden (--hidden): expected one or two layer sizes, whole "
                           "numbers: layer 1 in [1, 384]"),
    ("decimate = 0", "line 3: training.decimate: decimate (--decimate"),
    ("max_fail = 9999999999", "line 3: training.max_fail: max_fail"),
    ("holdout_voltage = 1e300", "line 3: training.holdout_voltage: holdout_voltage (--holdout-voltage"),
])
def test_training_options_are_checked_as_dampnet_train_checks_them_before_any_cell(tmp_path, capsys, line, fragment):
    """The ranges are dampnet.training.settings' (the one place a training's inputs are checked):
    refused when the spec is read, not in every cell."""
    spec = tmp_path / "s.toml"
    spec.write_text(f"[training]\ndatasets = ['rig:quick']\n{line}\n")
    one_line_error(capsys, ["sweep", str(spec), "--out", str(tmp_path / "o")], f"{spec}: {fragment}")
    assert not (tmp_path / "o").exists()


def test_a_setting_given_as_text_and_as_numbers_makes_a_text_column(tmp_path):
    """Issue 49, item 14: restarts = [1, "auto", 2] ran every cell, then Parquet refused the mixed
    column and the sweep died with no table and its state "running". The column is text, each cell
    as written; the Parquet and CSV tables hold it. Milliseconds."""
    import pandas as pd

    from dampnet.sweep.grid import Cell
    from dampnet.sweep.table import frame, write_csv, write_parquet

    cells = [Cell("training", i, {"restarts": r, "seed": i}, key=f"k{i}") for i, r in enumerate([1, "auto", 2])]
    records = {c.key: {"status": "ok", "metrics": {"holdout_nrmse": 0.01 * (c.index + 1)}} for c in cells}
    df = frame(cells, records)
    assert list(df["restarts"]) == ["1", "auto", "2"] and str(df["seed"].dtype) == "Int64"
    write_parquet(df, tmp_path / "t.parquet")
    write_csv(df, tmp_path / "t.csv")
    assert list(pd.read_parquet(tmp_path / "t.parquet")["restarts"]) == ["1", "auto", "2"]


def test_a_failure_writing_the_results_leaves_the_cells_and_an_honest_state(tmp_path, monkeypatch):
    """If writing the table fails, the cells' records stay and sweep.json says "failed" and why."""
    import json

    from dampnet.sweep import runner
    from dampnet.sweep.store import Store

    store = Store(tmp_path / "sw")
    store.root.mkdir(parents=True)
    store.set_state(state="running")

    def boom(*a, **k):
        raise OSError("disk full")

    monkeypatch.setattr(runner, "write_results", boom)
    (store.root / "cells").mkdir(exist_ok=True)
    (store.root / "cells" / "k0.json").write_text("{}")
    with pytest.raises(OSError, match="disk full"):
        runner.publish_results(store, None, None, {})
    state = json.loads((store.root / "sweep.json").read_text())
    assert state["state"] == "failed" and "writing the results: OSError: disk full" in state["error"], state
    assert (store.root / "cells" / "k0.json").is_file()
