"""Issue 29: every numeric option of `dampnet simulate`, `study` and `vehicle` within a stated range,
and a run's size checked before anything is allocated (dampnet.sim.limits, the one place for
both, also behind the Python entry points the commands call: Road.sample, the maneuvers)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from dampnet.sim.full_car import maneuvers
from dampnet.sim import limits
from dampnet.sim.roads import RoadError, thesis_rough_road

SIZE = "MAX_RUN_VALUES"


CASES = [
    # the issue's: each allocated until MemoryError or failed inside numpy
    (["vehicle", "linear:1500", "--speed", "1e-6"], SIZE),
    (["vehicle", "linear:1500", "--speed", "0.05"], SIZE),
    (["vehicle", "linear:1500", "--dt", "1e-7"], "--dt: expected a finite number in [1e-06, 0.01] s, got 1e-07"),
    (["vehicle", "linear:1500", "--dt", "1e-300"], "--dt: expected a finite number in [1e-06, 0.01] s"),
    (["vehicle", "linear:1500", "--test", "road", "--speed", "inf"],
     "--speed: expected a finite number in (0, 360] km/h, got inf"),
    (["vehicle", "linear:1500", "--test", "road", "--speed", "nan"], "--speed: expected a finite number"),
    (["vehicle", "linear:1500", "--test", "road", "--speed", "1e-3"], SIZE),
    (["vehicle", "linear:1500", "--test", "road", "--seed", "-1"], "--seed: expected an integer in [0, "),
    (["simulate", "linear:1500", "--speed", "1e-6"], SIZE),
    (["simulate", "linear:1500", "--dt", "1e-6"], SIZE),
    (["simulate", "linear:1500", "--dt", "nan"], "--dt: expected a finite number"),
    (["simulate", "linear:1500", "--speed", "1e9"], "--speed: expected a finite number in (0, 100] m/s"),
    (["simulate", "linear:1500", "--u", "inf"], "--u: expected a finite number"),
    (["simulate", "truth", "--control", "skyhook_onoff", "--command-tau", "1e300"], "--command-tau"),
    (["study", "linear:1500", "--dt", "1e-7"], "--dt: expected a finite number in [1e-06, 0.01] s"),
    (["study", "linear:1500", "--dt", "1e-6"], SIZE),
]

CHILD = """
import contextlib, io, json, resource, sys
resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))
from dampnet.cli import main
out = []
for args in json.loads(sys.argv[1]):
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        try:
            rc = main(args)
        except BaseException as e:   # MemoryError, a traceback: what the checks prevent
            rc, err = -1, io.StringIO(repr(e))
    out.append([rc, err.getvalue()])
print(json.dumps(out))
"""


def test_bad_sizes_and_numbers_are_refused_in_one_line_before_running(tmp_path):
    """All cases in one subprocess with 4 GB of address space: a check that came after the
    allocation would die of MemoryError, not give the one-line error."""
    runs = [[*args, "--out", str(tmp_path / f"o{i}")] for i, (args, _f) in enumerate(CASES)]
    proc = subprocess.run([sys.executable, "-c", CHILD, json.dumps(runs)], capture_output=True, text=True,
                          timeout=300, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    for (args, fragment), (rc, stderr) in zip(CASES, json.loads(proc.stdout.splitlines()[-1])):
        assert rc == 2, (args, stderr)
        err = stderr.splitlines()[-1]   # (a study prints its progress before)
        assert err.startswith("dampnet: error: ") and "Traceback" not in stderr, (args, stderr)
        assert fragment in err, (args, err)
        if fragment == SIZE:   # the limit stated, and what to change
            assert "1e+08 values" in err and ("--speed" in err or "--dt" in err), err
    assert not list(tmp_path.glob("o*"))


def test_the_python_entry_points_check_the_size_too():
    with pytest.raises(RoadError, match=rf"the lane change .* beyond the limit .*{SIZE}"):
        maneuvers.dlc(1e-3, 1e-6)
    with pytest.raises(RoadError, match=rf"the thesis_rough road .*{SIZE}"):
        maneuvers.rough_road(thesis_rough_road(), 1e-3, 0.05)
    with pytest.raises(RoadError, match="speed: expected a finite number in"):
        maneuvers.rough_road(thesis_rough_road(), 1e-3, float("inf"))
    with pytest.raises(RoadError, match="dt: expected a finite number in"):
        maneuvers.bsst(-1e-3)
    with pytest.raises(RoadError, match=rf"road 'thesis_rough' .* dt = 1e-09 s.*{SIZE}"):
        thesis_rough_road().sample(1e-9, 10.0)


def test_the_size_limit_counts_the_values_a_run_keeps():
    # the road's own steps (duration / dt + 1) at the largest accepted size pass, one more not
    n = limits.MAX_RUN_VALUES // limits.QUARTER_CAR_VALUES
    assert limits.check_run_size(n, limits.QUARTER_CAR_VALUES, "w", "h") == n
    with pytest.raises(ValueError, match=SIZE):
        limits.check_run_size(n + 1, limits.QUARTER_CAR_VALUES, "w", "h")
    with pytest.raises(ValueError, match=SIZE):
        limits.check_run_size(float("inf"), 1, "w", "h")


@pytest.mark.parametrize("argv, words", [
    (["--control", "skyhook_onoff", "--u", "3"], "--u: control law 'skyhook_onoff' does not take it (it applies to passive)"),
    (["--control", "passive_low", "--damping", "high"], "--damping: control law 'passive_low' does not take it"),
    (["--control", "passive", "--command-tau", "0.01"], "--command-tau: control law 'passive' does not take it"),
])
def test_an_option_the_control_law_does_not_read_is_refused(tmp_path, capsys, argv, words):
    """Issue 49, item 13: `simulate --road impulse --control skyhook_onoff --u 3` ran skyhook and
    ignored --u. Refused in one line before the run, naming the laws the option applies to. Milliseconds."""
    from dampnet.cli import main

    out = tmp_path / "run"
    assert main(["simulate", "linear:1500", "--road", "impulse", "--out", str(out), *argv]) == 2
    assert words in capsys.readouterr().err
    assert not out.exists()
