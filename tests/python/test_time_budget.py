"""The suite's time budget (tests/time_budget.py): a test over it fails the run unless marked
slow with a reason, and a bare slow marker is refused. Three small pytest runs in subprocesses
(about 4 s idle, 12 s on a loaded machine), with budgets of a fraction of a second."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

pytest_plugins = ["pytester"]

TESTS = Path(__file__).resolve().parents[1]

SLEEPY = """
import time
import pytest

def test_quick():
    pass

def test_sleepy():
    time.sleep(0.6)

@pytest.fixture(scope="module")
def sleepy_fixture():
    time.sleep(0.6)

def test_slow_setup(sleepy_fixture):
    pass

@pytest.mark.slow(reason="sleeps on purpose")
def test_marked():
    time.sleep(0.6)
"""


@pytest.fixture
def run(pytester, monkeypatch):
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")]))

    def go(source: str, *args: str):
        pytester.makepyfile(test_inner=source)
        return pytester.runpytest_subprocess("-p", "time_budget", "-p", "no:cacheprovider", "-p", "no:xdist",
                                             "-o", "addopts=", *args)
    return go


def test_a_test_over_the_budget_fails_the_run_and_is_named(run):
    res = run(SLEEPY, "--test-budget", "0.3")
    assert res.ret == pytest.ExitCode.TESTS_FAILED
    out = res.stdout.str()
    assert "4 passed" in out  # every test passed: the budget alone fails the run
    assert "test_inner.py::test_sleepy" in out and "test_inner.py::test_slow_setup" in out  # setup counts
    listed = out[out.index("budget (tests/time_budget.py)"):]
    assert "test_marked" not in listed and "test_quick" not in listed


def test_within_the_budget_or_with_it_off_the_run_passes(run):
    assert run(SLEEPY, "--test-budget", "5").ret == pytest.ExitCode.OK
    assert run(SLEEPY, "--test-budget", "0").ret == pytest.ExitCode.OK


def test_a_slow_marker_without_a_reason_is_refused(run):
    res = run("import pytest\n\n@pytest.mark.slow\ndef test_x():\n    pass\n")
    assert res.ret == pytest.ExitCode.USAGE_ERROR
    assert "needs reason=" in res.stderr.str()
