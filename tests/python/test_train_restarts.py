"""Issue 18, robust training: `dampnet train --restarts N` / train_dataset(restarts=N).

The selection keeps the restart that interpolates the held-out level well on a case that fails
today; model.json records every restart; restarts=1 is the training as it was; the kept model is
the plain fit of its seed; parallel and serial runs keep the same model; bad values are one-line
errors. Heavy measurements (seeds 0-9, several plans): bench/experiments/restarts_seed_spread.py.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from dampnet.cli import main
from dampnet.data import DataError, write_dataset
from dampnet.evaluation.metrics import evaluate_predictions
from dampnet.features import feature_matrix
from dampnet.model import MlpModel
from dampnet.predict import predict_force
from dampnet.rig import generate
from dampnet.training import fit
from dampnet.training.metrics import nrmse
from dampnet.training.pipeline import fit_prepared, prepare_training, train_dataset
from dampnet.training.restarts import restart_seeds

# The 5-frequency x 8-voltage plan of issue 18 (tests/python/test_diagnose_hidden.py's), with
# the training settings: seed 3 fits the training levels as well as any seed but puts
# 2.25 V in a wiggle between 1.5 and 3 V (held-out NRMSE 0.117 against 0.005-0.03).
SPARSE_PLAN = {"name": "sparse-5x8", "frequencies_hz": [0.25, 0.5, 1.0, 2.0, 3.0], "amplitudes_m": [0.0254],
               "voltages_v": [0.0, 0.5, 1.0, 1.5, 2.25, 3.0, 4.0, 5.0], "sample_rate_hz": 1000.0,
               "samples": 2000, "min_cycles": 2}
# Without the control prior (the default since issue 33), which removes the wiggle by itself, and
# with the rest points at the thesis's 0 N (the default before the estimated force at rest, which
# moves seed 3's wiggle: 0.041 there), the case this test was built on.
SPARSE_TRAIN = {"decimate": 4, "max_epochs": 120, "control_prior": 0.0, "rest_target": "zero"}
# Small and quick for the bookkeeping tests: 3 voltages, 2 of them for training.
TINY = {"decimate": 50, "max_epochs": 40}


def _holdout(model, split) -> float:
    tests = split.holdout.tests
    return evaluate_predictions(tests, [predict_force(model, t) for t in tests])["overall"]["nrmse"]


@pytest.fixture(scope="module")
def quick():
    return generate("quick", seed=0)


@pytest.fixture(scope="module")
def quick_dir(quick, tmp_path_factory):
    d = tmp_path_factory.mktemp("data") / "quick"
    write_dataset(quick, d)
    return d


@pytest.mark.slow(reason="the sparse plan with 2 restarts (the first the failing seed's full training) and the "
                         "selection, and the same seed with the control prior: the case needs the failing seed's "
                         "full training (30-40 s on 2 loaded cores)")
def test_selection_keeps_the_restart_that_interpolates_the_held_out_level():
    """Seed 3 fails today on the sparse plan; with 2 restarts the second (a good interpolator)
    is kept, found from the training levels alone, and its held-out error is a fraction.
    Today's training is restart 0 of the run with restarts (the plain fit of seed 3: restart 0's
    seed is the seed asked for, and a restart is the plain fit of its seed, bit for bit, as
    test_parallel_and_serial_restarts_keep_the_same_model checks), so it is not trained twice."""
    ds = generate(SPARSE_PLAN, seed=1)
    kept, info, split2 = train_dataset(ds, seed=3, restarts=2, workers=2, **SPARSE_TRAIN)
    r = kept.meta["restarts"]
    assert r["runs"][0]["seed"] == 3 and len(info.restart_models) == 2
    today = info.restart_models[0]
    assert today.meta["seed"] == 3
    bad = _holdout(today, split2)
    assert bad > 0.05  # the failure this case is built on (measured 0.117)
    prior, _, split1 = train_dataset(ds, seed=3, **{**SPARSE_TRAIN, "control_prior": 1.0})
    assert _holdout(prior, split1) < 0.1 * bad  # the control prior alone (measured 0.0075)
    assert r["kept"] == 1 and r["kept_seed"] == restart_seeds(3, 2)[1]
    good = _holdout(kept, split2)
    assert good < 0.3 * bad and good < 0.03  # measured 0.013
    # the score saw the wiggle: restart 0 strays several times more between levels, most in 1.5-3 V
    s0, s1 = r["runs"][0], r["runs"][1]
    assert s0["score"] > 3 * s1["score"]
    assert max(s0["gaps"], key=s0["gaps"].get) == "1.5-3"
    assert split2.holdout_ids == split1.holdout_ids  # the hold-out never entered the selection


@pytest.mark.slow(reason="three restarts trained to the end on the sparse plan, scored two ways: the measured case "
                         "needs them whole (45-57 s on 2 loaded cores)")
def test_combined_score_keeps_the_restart_that_fits_the_levels_with_the_control_prior():
    """With the control prior (the default) every restart follows the smooth curve between the
    levels, and what tells them apart is how well they fit the levels: on the sparse plan, seed 4,
    three restarts, the restart with the lowest interpolation score fits worse and is worse held
    out; the combined score keeps the one that fits best (measured: held back 0.0049 against
    0.0056-0.0062, held out 0.0067 against 0.0077). The case was found with the thesis's 20 ms
    moving-average acceleration, the default then, and keeps it: the selection, not the derivative,
    is under test (with the zero-phase derivative, seed 4's smoothest restart is also the best fit)."""
    from dampnet.training.pipeline import restarts_holdout

    ds = generate(SPARSE_PLAN, seed=1)
    model, info, split = train_dataset(ds, seed=4, restarts=3, workers=2, decimate=4, max_epochs=120,
                                       acceleration_window=0.02)
    r = restarts_holdout(model.meta["restarts"], info.restart_models, split.holdout.tests)
    runs = r["runs"]
    assert r["score"] == "combined" and r["kept"] == int(np.argmin([x["held_back"] for x in runs]))
    smoothest = int(np.argmin([x["interpolation"] for x in runs]))
    assert smoothest != r["kept"]
    assert runs[r["kept"]]["holdout_nrmse"] < 0.9 * runs[smoothest]["holdout_nrmse"]


def test_model_json_records_every_restart(quick_dir, tmp_path):
    out = tmp_path / "m"
    rc = main(["train", str(quick_dir), "--out", str(out), "--quiet", "--seed", "7", "--restarts", "3",
               "--decimate", "50", "--max-epochs", "40"])
    assert rc == 0
    model = MlpModel.load(out)
    r = model.meta["restarts"]
    assert r["n"] == 3 and r["seed"] == 7 and r["score"] == "combined"
    assert [x["seed"] for x in r["runs"]] == restart_seeds(7, 3) and r["runs"][0]["seed"] == 7
    assert len(set(x["seed"] for x in r["runs"])) == 3
    assert [x["restart"] for x in r["runs"]] == [0, 1, 2]
    scores = [x["score"] for x in r["runs"]]
    assert all(np.isfinite(scores)) and all(s > 0 for s in scores)
    assert [x["kept"] for x in r["runs"]].count(True) == 1
    assert r["runs"][r["kept"]]["kept"] and r["kept"] == int(np.argmin(scores))
    assert r["kept_seed"] == r["runs"][r["kept"]]["seed"] == model.meta["seed"]
    assert r["levels"] == [0.0, 5.0] and list(r["runs"][0]["gaps"]) == ["0-5"]
    assert r["score_min"] == min(scores) and r["score_max"] == max(scores)
    metrics = json.loads((out / "metrics.json").read_text())
    mr = metrics["training"]["restarts"]
    # metrics.json adds each restart's hold-out NRMSE (for the user, after the fact): the kept
    # restart's is the model's own hold-out figure
    assert {k: v for k, v in mr.items() if not k.startswith("holdout")} == {**r, "runs": mr["runs"]}
    assert [{k: v for k, v in x.items() if k != "holdout_nrmse"} for x in mr["runs"]] == r["runs"]
    kept_h = mr["runs"][r["kept"]]["holdout_nrmse"]
    assert kept_h == pytest.approx(metrics["holdout"]["overall"]["nrmse"], abs=1e-7)
    hs = [x["holdout_nrmse"] for x in mr["runs"]]
    assert mr["holdout_nrmse_min"] == min(hs) and mr["holdout_nrmse_max"] == max(hs) and len(set(hs)) == 3


def test_combined_score_is_the_held_back_error_and_the_interpolation(quick):
    """The default score of each restart is the root-sum-square of its error on the rows its fit
    held back (validation and test rows) over the force range, and its interpolation score; the
    held-back error is recomputed here from a refit of the kept seed alone, and the interpolation
    score ranks the same fits when asked for alone."""
    model, _, _ = train_dataset(quick, seed=4, restarts=3, workers=1, **TINY)
    r = model.meta["restarts"]
    assert r["score"] == "combined"
    for x in r["runs"]:
        assert 0 < x["held_back"] and 0 < x["interpolation"]
        assert x["score"] == pytest.approx(np.hypot(x["held_back"], x["interpolation"]), abs=2e-7)
    assert r["kept"] == int(np.argmin([x["score"] for x in r["runs"]]))
    prep = prepare_training(quick, **TINY)
    refit, info = fit_prepared(prep, r["kept_seed"], threads=1)
    assert refit.model_id() == model.model_id()
    rows = np.concatenate([info.val_idx, info.test_idx])
    assert len(rows) == len(prep.X) - len(info.train_idx) > 0
    err = predict_force(refit, prep.X[rows]) - prep.force[rows]
    expected = np.sqrt(np.mean(err ** 2)) / (prep.force.max() - prep.force.min())
    assert r["runs"][r["kept"]]["held_back"] == pytest.approx(expected, abs=1e-7)
    alone, _, _ = train_dataset(quick, seed=4, restarts=3, workers=1, restart_score="interpolation", **TINY)
    ra = alone.meta["restarts"]
    assert [x["interpolation"] for x in ra["runs"]] == [x["interpolation"] for x in r["runs"]]
    assert [x["score"] for x in ra["runs"]] == [x["interpolation"] for x in r["runs"]]
    assert ra["kept"] == int(np.argmin([x["interpolation"] for x in r["runs"]]))


def test_restarts_1_is_the_training_as_it_was(quick):
    """restarts=1 is the plain fit: no restart record, and the same weights as fit() on the
    samples the pipeline's docstring describes (hold-out removed, features decimated by 50, the
    control prior on)."""
    model, info, split = train_dataset(quick, seed=2, restarts=1, **TINY)
    assert "restarts" not in model.meta
    train = [t for t in quick.tests if abs(t.control_nominal - 2.25) > 1e-9]
    X = np.concatenate([feature_matrix([t], model.features, None, 0.02)[::50] for t in train])
    y = np.concatenate([t.channels["force"][::50] for t in train])
    ref, _ = fit(X, y, features=model.features, seed=2, max_epochs=40, control_prior=1.0)
    for name in ("w1", "b1", "w_out", "in_offset", "in_gain", "sat_lo", "sat_hi"):
        np.testing.assert_array_equal(getattr(model, name), getattr(ref, name), err_msg=name)
    assert model.b_out == ref.b_out and model.out_gain == ref.out_gain
    default, _, _ = train_dataset(quick, seed=2, **TINY)  # the default is restarts=1
    assert default.model_id() == model.model_id()


def test_parallel_and_serial_restarts_keep_the_same_model(quick):
    par, _, _ = train_dataset(quick, seed=5, restarts=3, workers=2, **TINY)
    ser, _, _ = train_dataset(quick, seed=5, restarts=3, workers=1, **TINY)
    assert par.meta["restarts"]["workers"] == 2 and ser.meta["restarts"]["workers"] == 1
    assert par.model_id() == ser.model_id()
    strip = ("time_s",)
    runs = [[{k: v for k, v in x.items() if k not in strip} for x in m.meta["restarts"]["runs"]] for m in (par, ser)]
    assert runs[0] == runs[1]
    # the kept model is the plain fit of its seed (one thread), bit for bit
    plain, _, _ = train_dataset(quick, seed=par.meta["restarts"]["kept_seed"], threads=1, **TINY)
    assert plain.model_id() == par.model_id()


UNGUARDED_SCRIPT = """
import dampnet
from dampnet.rig import generate

ds = generate("quick", seed=0)
dampnet.train(ds, seed=0, holdout_voltage=2.25, restarts=2, workers=2, decimate=50, max_epochs=5)
print("trained")
"""


def test_a_script_without_a_main_guard_gets_a_clear_error_not_a_hang(tmp_path):
    """Parallel restarts start fresh Pythons that import the calling script; one that trains at its
    top level makes them die starting up. That hung for ever (the parent blocked writing the
    prepared samples to a worker that had died); now the run stops with an error saying what to do,
    and leaves no handoff file behind."""
    script = tmp_path / "unguarded.py"
    script.write_text(UNGUARDED_SCRIPT)
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = {**os.environ, "TMPDIR": str(tmp)}
    try:
        run = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=240,
                             env=env, cwd=tmp_path)
    except subprocess.TimeoutExpired:
        pytest.fail("a script without a main guard hangs dampnet.train's parallel restarts")
    assert run.returncode != 0 and "trained" not in run.stdout
    last = run.stderr.strip().splitlines()[-1]
    assert last.startswith("RuntimeError: restarts: a worker process") and 'if __name__ == "__main__":' in last
    # nothing left to the resource tracker either: the workers stop before making pools of their own
    # (a fresh-clone run once ended with its "leaked semaphore objects" warning after the error)
    assert "leaked" not in run.stderr and "resource_tracker" not in run.stderr, run.stderr[-600:]
    assert not list(tmp.glob("dampnet-restarts-*"))


LONG_PARALLEL_SCRIPT = """
import dampnet
from dampnet.rig import generate

if __name__ == "__main__":
    ds = generate("thesis", seed=0)
    dampnet.train(ds, seed=0, holdout_voltage=2.25, restarts=2, workers=2, max_epochs=1000)
"""


def _state(pid: int) -> str | None:
    """The process's state letter from /proc (Z: a zombie, finished), None when it is gone."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return None


def _has_torch(pid: int) -> bool:
    """Whether process `pid` has torch's library loaded."""
    try:
        return "libtorch_cpu" in Path(f"/proc/{pid}/maps").read_text()
    except OSError:
        return False


def _restart_workers(parent: int) -> list[int]:
    """The running restart workers (spawned Pythons) of process `parent`."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
            cmd = (stat.parent / "cmdline").read_bytes()
        except (OSError, IndexError):
            continue
        if int(fields[1]) == parent and fields[0] != "Z" and b"spawn_main" in cmd:
            found.append(int(stat.parent.name))
    return found


def test_the_workers_stop_when_their_parent_is_killed(tmp_path):
    """A parent killed outright (SIGKILL: the out-of-memory killer, a notebook kernel restarted) cannot
    stop its pool; its restart workers used to fit on for minutes (here each had up to 1,000 epochs
    of the thesis plan, over a minute) and now end within seconds."""
    script = tmp_path / "long.py"
    script.write_text(LONG_PARALLEL_SCRIPT)
    log = tmp_path / "stderr.txt"  # a file, not a pipe nobody reads while the parent runs
    with log.open("w") as err:
        parent = subprocess.Popen([sys.executable, str(script)], cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=err)
    workers: list[int] = []
    try:
        deadline = time.monotonic() + 180
        while len(workers) < 2 and time.monotonic() < deadline and parent.poll() is None:
            time.sleep(0.5)
            workers = _restart_workers(parent.pid)
        assert len(workers) == 2, f"the restart workers did not start: {log.read_text()[-2000:]}"
        # past the workers' start-up (torch loaded: its import is most of it), into their fits
        while not all(_has_torch(w) for w in workers) and time.monotonic() < deadline:
            time.sleep(0.2)
        time.sleep(2)
        assert all(_state(w) not in (None, "Z") for w in workers), "a worker ended before its parent was killed"
        parent.kill()
        parent.wait()
        deadline = time.monotonic() + 30
        while any(_state(w) not in (None, "Z") for w in workers) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert all(_state(w) in (None, "Z") for w in workers), "the workers outlived their killed parent by 30 s"
    finally:
        parent.kill()
        for w in workers:
            with contextlib.suppress(OSError):
                os.kill(w, signal.SIGKILL)


def test_leave_one_level_out_score_records_levels_and_needs_an_interior_level(quick):
    plan = {"name": "four", "frequencies_hz": [1.0, 3.0], "amplitudes_m": [0.0254],
            "voltages_v": [0.0, 1.5, 2.25, 3.0, 5.0], "samples": 2500}
    ds = generate(plan, seed=0)
    model, _, _ = train_dataset(ds, seed=0, restarts=2, workers=1, restart_score="lolo", **TINY)
    r = model.meta["restarts"]
    assert r["score"] == "lolo" and r["withheld_levels"] == [1.5, 3.0]
    for run in r["runs"]:
        assert set(run["levels"]) == {"1.5", "3"}
        assert run["score"] == pytest.approx(np.mean(list(run["levels"].values())), rel=1e-5)
    assert r["kept"] == int(np.argmin([x["score"] for x in r["runs"]]))
    plain, _, _ = train_dataset(ds, seed=r["kept_seed"], threads=1, **TINY)
    assert plain.model_id() == model.model_id()
    with pytest.raises(DataError, match="interior training control level"):
        train_dataset(quick, restarts=2, workers=1, restart_score="lolo", **TINY)


@pytest.mark.parametrize("bad", [0, -1, True, 1.5, "3", None])
def test_bad_restarts_value_is_a_clear_error(quick, bad):
    with pytest.raises(ValueError, match=r"restarts \(--restarts, .*\): expected a whole number in \[1, 1000\]"):
        train_dataset(quick, restarts=bad, **TINY)


@pytest.mark.parametrize("argv, message", [
    (["--restarts", "0"], "restarts (--restarts, trainings from different seeds, the best kept): expected a whole "
                          "number in [1, 1000], got 0"),
    (["--restarts", "-2"], "restarts (--restarts, trainings from different seeds, the best kept): expected a whole "
                           "number in [1, 1000], got -2"),
    (["--restarts", "two"], "--restarts: expected a whole number or auto, got 'two'"),
    (["--workers", "0"], "workers (--workers, processes the restarts run in): expected a whole number in [1, 1024] "
                         "or null (the local cores), got 0"),
])
def test_bad_restarts_option_is_one_line_and_exit_2(quick_dir, tmp_path, capsys, argv, message):
    rc = main(["train", str(quick_dir), "--out", str(tmp_path / "m"), "--quiet", *argv])
    err = capsys.readouterr().err
    assert rc == 2 and err == f"dampnet: error: {message}\n"
    assert not (tmp_path / "m").exists()


def test_auto_trains_once_when_there_is_nothing_to_interpolate(quick_dir, tmp_path, capsys):
    """--restarts auto (the default) on data with one training level trains once and says why."""
    rc = main(["train", str(quick_dir), "--out", str(tmp_path / "m"), "--holdout-tests", "T001,T004,T007",
               "--holdout-voltage", "5", "--decimate", "50", "--max-epochs", "20", "--algorithm", "lm"])
    out = capsys.readouterr().out
    assert rc == 0 and "restarts: 1 (the training tests have 1 control level (2.25)" in out
    assert "restarts" not in MlpModel.load(tmp_path / "m").meta


@pytest.mark.parametrize("decimate", [None, 12])
def test_auto_restarts_keep_rows_times_restarts_within_the_budget(quick, quick_dir, tmp_path, capsys,
                                                                 monkeypatch, decimate):
    """The automatic restarts count the training rows as the pipeline will fit them (its feature
    matrix's rows, hold-out and decimation applied) and run fewer than the default when rows x
    restarts would exceed the budget (the thesis plan: 1), never fewer than --average."""
    from dampnet.training import restarts as rs

    rows = rs.training_rows(quick, 2.25, (), decimate)
    assert rows == len(prepare_training(quick, decimate=decimate).X)
    assert rs.auto_restarts(quick, 2.25, decimate=decimate) == (rs.DEFAULT_RESTARTS, None)
    monkeypatch.setattr(rs, "RESTART_ROWS_BUDGET", 3 * rows + rows // 2)
    n, note = rs.auto_restarts(quick, 2.25, decimate=decimate)
    assert n == 3 and f"{rows:,} training rows" in note
    assert rs.auto_restarts(quick, 2.25, decimate=decimate, average=4)[0] == 4
    monkeypatch.setattr(rs, "RESTART_ROWS_BUDGET", rows // 2)
    assert rs.auto_restarts(quick, 2.25, decimate=decimate)[0] == rs.MIN_AUTO_RESTARTS
    if decimate is None:  # the command says how many it ran and why
        monkeypatch.setattr(rs, "RESTART_ROWS_BUDGET", 2 * rows)
        rc = main(["train", str(quick_dir), "--out", str(tmp_path / "m"), "--max-epochs", "5", "--algorithm", "lm"])
        out = capsys.readouterr().out
        assert rc == 0 and f"restarts: 2 (not {rs.DEFAULT_RESTARTS}: {rows:,} training rows" in out
        assert len(MlpModel.load(tmp_path / "m").meta["restarts"]["runs"]) == 2


def test_the_thesis_plan_trains_twice_at_100_hz():
    """The thesis plan's training rows at 200 Hz (91,518) are over DECIMATE_MAX_ROWS, so the default
    keeps about 100 Hz (every 50th sample at 5 kHz): the rows the pipeline fits, which training_rows
    counts without building them, within the cap, and LM's restart budget gives it two trainings
    (one on each of 2 cores), not the 6 of smaller data."""
    from dampnet.data.preprocess import DECIMATE_MAX_ROWS
    from dampnet.training import restarts as rs

    thesis = generate("thesis", seed=0)
    prep = prepare_training(thesis)
    assert prep.split.decimate == 50
    assert rs.training_rows(thesis, 2.25, (), 25) > DECIMATE_MAX_ROWS  # 200 Hz would be over the cap
    assert len(prep.X) == rs.training_rows(thesis, 2.25) <= DECIMATE_MAX_ROWS
    assert rs.auto_algorithm(len(prep.X))[0] == "lm"
    n, note = rs.auto_restarts(thesis, 2.25)
    assert n == 2 and f"{len(prep.X):,} training rows" in note


def test_auto_algorithm_is_br_on_small_data_and_lm_beyond(quick, quick_dir, tmp_path, capsys, monkeypatch):
    """`dampnet train`'s default algorithm: Bayesian regularisation up to BR_MAX_ROWS training rows
    (one training: its seeds agree), Levenberg-Marquardt beyond (with the automatic restarts); the
    command says which and why, and --settings then needs the algorithm named."""
    import dampnet
    from dampnet.training import restarts as rs

    rows = rs.training_rows(quick, 2.25, ())
    assert rs.auto_algorithm(rows)[0] == "br" and rs.auto_algorithm(rs.BR_MAX_ROWS)[0] == "br"
    assert rs.auto_algorithm(rs.BR_MAX_ROWS + 1)[0] == "lm"
    n, note = rs.auto_restarts(quick, 2.25, algorithm="br")
    assert n == 1 and "Bayesian regularisation" in note
    assert rs.auto_restarts(quick, 2.25, algorithm="br", average=2)[0] == 2  # one BR training per network averaged
    rc = main(["train", str(quick_dir), "--out", str(tmp_path / "br"), "--max-epochs", "5"])
    out = capsys.readouterr().out
    assert rc == 0 and f"algorithm: br ({rows:,} training rows, at most {rs.BR_MAX_ROWS:,}" in out
    assert "restarts: 1 (Bayesian regularisation" in out
    model = MlpModel.load(tmp_path / "br")
    assert model.meta["algorithm"] == "br" and "restarts" not in model.meta
    monkeypatch.setattr(rs, "BR_MAX_ROWS", rows - 1)
    # both autos (the command's defaults) count the training rows once between them
    from dampnet.recipes.training import TrainingRequest, plan

    counted, count_rows = [], rs.training_rows
    monkeypatch.setattr(rs, "training_rows", lambda *a, **k: counted.append(1) or count_rows(*a, **k))
    both = plan(quick, TrainingRequest(algorithm="auto", restarts="auto"))
    assert (both.algorithm, both.restarts, len(counted)) == ("lm", rs.DEFAULT_RESTARTS, 1)
    rc = main(["train", str(quick_dir), "--out", str(tmp_path / "lm"), "--max-epochs", "5", "--restarts", "2"])
    out = capsys.readouterr().out
    assert rc == 0 and f"algorithm: lm ({rows:,} training rows, over {rows - 1:,}" in out
    assert MlpModel.load(tmp_path / "lm").meta["algorithm"] == "lm"
    # the Python API takes "auto" too (its default stays lm, as its restarts stay 1)
    assert dampnet.train(quick, algorithm="auto", max_epochs=3).model.meta["algorithm"] == "lm"
    monkeypatch.undo()
    assert dampnet.train(quick, algorithm="auto", max_epochs=3).model.meta["algorithm"] == "br"
    assert dampnet.train(quick, max_epochs=3).model.meta["algorithm"] == "lm"
    # a hold-out that matches nothing: the pipeline's hint, from the row count "auto" needs
    with pytest.raises(DataError, match="no test at control 9.*choose another --holdout-voltage"):
        dampnet.train(quick, algorithm="auto", holdout_voltage=9.0, max_epochs=3)
    rc = main(["train", str(quick_dir), "--out", str(tmp_path / "bad"), "--settings", '{"mu_max": 1e8}'])
    err = capsys.readouterr().err
    assert rc == 2 and "name it with --algorithm" in err and not (tmp_path / "bad").exists()
    # an unknown algorithm names 'auto' among the valid ones, from the API as from the command
    for bad in ("bogus", 3, ["lm"]):
        with pytest.raises(ValueError, match=r"^algorithm \(--algorithm\): expected auto or one of lm, br, scg, adam"):
            dampnet.train(quick, algorithm=bad)


def test_average_keeps_the_best_restarts_as_one_network(quick_dir, tmp_path, capsys):
    """--average 2: the two lowest-scored restarts averaged into one network twice as wide, whose
    output is their mean (each restart refitted alone: the plain fit of its seed), with the
    training NRMSE measured for the averaged network and the summary saying so."""
    out = tmp_path / "m"
    rc = main(["train", str(quick_dir), "--out", str(out), "--seed", "7", "--restarts", "3", "--average", "2",
               "--hidden", "12", "--decimate", "50", "--max-epochs", "40", "--algorithm", "lm", "--valve", "off"])
    text = capsys.readouterr().out
    assert rc == 0
    model = MlpModel.load(out)
    r = model.meta["restarts"]
    ranked = sorted(range(3), key=lambda k: (r["runs"][k]["score"], k))
    assert r["averaged"] == ranked[:2] and r["averaged_seeds"] == [r["runs"][k]["seed"] for k in ranked[:2]]
    assert model.hidden == (24,) and model.meta["ensemble"]["members"] == 2
    assert f"averaged the best 2 (restarts {ranked[0]}, {ranked[1]}) into one network" in text
    ds = generate("quick", seed=0)
    members = [train_dataset(ds, seed=r["runs"][k]["seed"], hidden=(12,), threads=1, **TINY)[0] for k in ranked[:2]]
    test = ds.tests[4]
    mean = np.mean([predict_force(m, test) for m in members], axis=0)
    np.testing.assert_allclose(predict_force(model, test), mean, rtol=1e-12, atol=1e-9)
    # the training NRMSE in model.json is the averaged network's own, on the training rows
    prep = prepare_training(ds, hidden=(12,), **TINY)
    assert model.meta["metrics"]["all"] == pytest.approx(nrmse(predict_force(model, prep.X), prep.force), abs=1e-6)
    assert model.meta["metrics"]["all"] != members[0].meta["metrics"]["all"]


@pytest.mark.parametrize("kw, message", [
    ({"restarts": 2, "average": 3}, "only 2 restart"),
    ({"restarts": 3, "average": 3, "hidden": (130,)}, "a layer of 390; dampnet's models hold at most 384"),
    ({"restarts": 2, "average": 2, "hidden": (8, 8)}, "only one-hidden-layer networks"),
    ({"restarts": 2, "average": 2, "restart_score": "lolo"}, "use restart_score 'combined' or 'interpolation'"),
    ({"restarts": 2, "average": 0}, r"average \(--average, .*\): expected a whole number in \[1, 1000\], got 0"),
])
def test_bad_average_is_a_clear_error(quick, kw, message):
    with pytest.raises(ValueError, match=message):
        train_dataset(quick, **{**TINY, **kw})


def test_a_sweep_takes_the_automatic_algorithm_and_says_which_it_chose():
    """algorithms = ['auto'] in a sweep spec: the cell trains as `dampnet train` does by default
    (br on the quick plan's rows) and its row's algorithm_used says so; a named one is kept."""
    from dampnet.sweep import SpecError, parse_spec
    from dampnet.sweep.grid import expand
    from dampnet.sweep.inputs import bind
    from dampnet.sweep.metrics import objectives
    from dampnet.sweep.train_cell import run

    spec = parse_spec({"training": {"datasets": "rig:quick", "algorithms": ["auto", "lm"], "decimate": 50,
                                    "max_epochs": 3}})
    cells = expand(spec)
    bind(cells, spec)
    used = {c.params["algorithm"]: run(c.params, dict(c.inputs))["metrics"]["algorithm_used"] for c in cells}
    assert used == {"auto": "br", "lm": "lm"}
    assert "algorithm_used" not in objectives("training")       # text, never an objective
    with pytest.raises(SpecError, match="'foo' is not a training algorithm; valid: auto, lm"):
        parse_spec({"training": {"datasets": "rig:quick", "algorithms": ["foo"]}})


def test_a_sweep_sets_the_rest_target():
    """rest_target in a sweep's [training] (the request option dampnet train's --rest-target sets):
    each cell trains its rest points to its target, recorded in the model; a bad word is refused."""
    from dampnet.sweep import SpecError, parse_spec
    from dampnet.sweep.grid import expand
    from dampnet.sweep.inputs import bind
    from dampnet.sweep.train_cell import run

    spec = parse_spec({"training": {"datasets": "rig:quick", "algorithms": "lm", "decimate": 50, "max_epochs": 2,
                                    "hidden": [4], "rest_target": ["zero", "estimated"]}})
    cells = expand(spec)
    bind(cells, spec)
    rest = {c.params["rest_target"]: run(c.params, dict(c.inputs))["model"]["meta"]["rest_force"] for c in cells}
    assert set(rest) == {"zero", "estimated"}
    assert rest["zero"]["target"] == "zero" and rest["zero"]["target_N"] == 0.0
    # the rig's gas force at rest is about -270 N (test_train_cli checks it against the truth)
    assert rest["estimated"]["target"] == "estimated" and rest["estimated"]["target_N"] < -200.0
    with pytest.raises(SpecError, match="rest_target.*expected one of estimated, zero, none"):
        parse_spec({"training": {"datasets": "rig:quick", "rest_target": "gas"}})


def test_the_demo_report_shows_each_restarts_score_and_its_parts(quick, tmp_path):
    """The demo's restarts section (shown when its trainings ran several restarts: the full demo's
    LM on the thesis plan) lists every restart's score, held-back error, interpolation score and
    held-out NRMSE from the training's metrics, and draws their held-out errors."""
    import dampnet
    from dampnet.demo.report import _fmt, _restarts_section
    from dampnet.demo.run import _restarts_summary

    trained = dampnet.train(quick, seed=1, restarts=2, workers=1, **TINY)
    rec = trained.metrics["training"]["restarts"]
    # the report reads the demo summary's digest of the record, as the demo writes it
    page = _restarts_section({"original": _restarts_summary(trained.metrics), "improved": None},
                             tmp_path / "restarts.png")
    assert "combined" in page and "held-back error" in page and "interpolation score" in page
    for x in rec["runs"]:
        row = "".join(f"<td>{_fmt(c)}</td>" for c in (x["score"], x["held_back"], x["interpolation"],
                                                      x["holdout_nrmse"]))
        assert row in page
    assert (tmp_path / "restarts.png").stat().st_size > 1000 and "data:image/png;base64," in page


def test_stopping_the_pool_waits_for_its_manager_thread():
    """_stop_pool returns once the pool's manager thread has ended: one still closing the pool's
    wake-up pipe when the interpreter exits made Python 3.11 print "Bad file descriptor" after
    "dampnet: terminated" (test_train_signals failed so once in seven suite runs).
    shutdown(wait=False) drops the executor's reference to that thread, so a later
    shutdown(wait=True) did not wait for it. Three rounds of a one-worker pool stopped mid-task.
    Cost: about 1.6 s."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    from dampnet.training.restarts import _stop_pool

    for _ in range(3):
        ex = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"))
        busy = ex.submit(time.sleep, 30)
        deadline = time.monotonic() + 30
        while not busy.running() and time.monotonic() < deadline:
            time.sleep(0.01)
        manager = ex._executor_manager_thread
        assert manager is not None and manager.is_alive()
        _stop_pool(ex)
        assert not manager.is_alive(), "the pool's manager thread outlived _stop_pool"
