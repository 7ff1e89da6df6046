"""A pytest plugin that holds every test to a time budget (issue 51: the suite in 15 minutes).

A test whose setup, call and teardown together take longer than the budget fails the run, named
with its time, unless it is marked `@pytest.mark.slow(reason="...")`: a slow test says why it is
slow (what it checks that a smaller run could not), and a marker without a reason is refused at
collection. The budget is DEFAULT_BUDGET_S, or `--test-budget SECONDS` (0: no budget). The modules
holding a slow test are run first, so that a parallel run does not end on one of them.

Why setup counts: a module's trained model is built in its first test's setup, and a fixture that
trains for minutes is exactly what this budget is for. Under pytest-xdist the controller receives
every worker's reports, so the check runs there, once.
"""

from __future__ import annotations

import json
import os
from collections import defaultdict
from pathlib import Path

import pytest

#: where each run writes every test's time (setup + call + teardown [s]) and its worker, for
#: finding what makes the suite slow without another run (`--durations` shows only the slowest)
TIMES_FILE = Path(__file__).resolve().parent.parent / "build" / "test-times.json"

#: seconds a test may take (setup + call + teardown) without a `slow` marker, on the 2-core machine
#: with the suite's two worker processes
DEFAULT_BUDGET_S = 60.0


def pytest_addoption(parser):
    parser.addoption("--test-budget", type=float, default=DEFAULT_BUDGET_S, metavar="SECONDS",
                     help="fail the run when a test without @pytest.mark.slow(reason=...) takes longer "
                          f"than SECONDS, setup and teardown included (default {DEFAULT_BUDGET_S:g}; 0: off)")


def pytest_configure(config):
    config.addinivalue_line("markers", "slow(reason): a test allowed over the time budget (tests/time_budget.py); "
                                       "the reason says why it cannot be smaller")
    if not hasattr(config, "workerinput"):  # an xdist worker's reports reach its controller
        config.pluginmanager.register(_Budget(config), "time_budget_check")


def pytest_collection_modifyitems(config, items):
    bare = sorted({item.nodeid for item in items
                   for m in item.iter_markers("slow") if not str(m.kwargs.get("reason", "")).strip()})
    if bare:
        raise pytest.UsageError("@pytest.mark.slow needs reason=\"...\" (why the test cannot be smaller): "
                                + ", ".join(bare[:10]))
    # The modules that hold a slow test run first (in collection order otherwise): the parallel run
    # hands out whole modules (--dist loadscope), and a long module started last would run alone at
    # the end while the other worker idles. Every process sorts alike, as xdist requires.
    heavy = {item.module.__name__ for item in items if item.get_closest_marker("slow") and item.module}
    items.sort(key=lambda item: (item.module is None or item.module.__name__ not in heavy))


class _Budget:
    def __init__(self, config):
        self.config = config
        self.totals: dict[str, list] = {}  # nodeid -> [seconds, marked slow]
        self.worker: dict[str, str] = {}   # nodeid -> the xdist worker that ran it

    def pytest_runtest_logreport(self, report):
        entry = self.totals.setdefault(report.nodeid, [0.0, "slow" in report.keywords])
        entry[0] += report.duration
        node = getattr(report, "node", None)
        self.worker[report.nodeid] = getattr(getattr(node, "gateway", None), "id", "main")

    def by_module(self) -> list[tuple[str, float]]:
        modules: dict[str, float] = defaultdict(float)
        for nodeid, (t, _) in self.totals.items():
            modules[nodeid.split("::")[0]] += t
        return sorted(modules.items(), key=lambda x: -x[1])

    def over(self) -> list[tuple[str, float]]:
        budget = self.config.getoption("--test-budget")
        if not budget or budget <= 0:
            return []
        return sorted(((nodeid, t) for nodeid, (t, slow) in self.totals.items() if t > budget and not slow),
                      key=lambda x: -x[1])

    def pytest_terminal_summary(self, terminalreporter):
        if len(self.totals) > 50:  # a whole run, not one module: where its time went
            workers: dict[str, float] = defaultdict(float)
            for nodeid, (t, _) in self.totals.items():
                workers[self.worker.get(nodeid, "main")] += t
            terminalreporter.section("the slowest modules (setup + call + teardown) [s]")
            for module, t in self.by_module()[:15]:
                terminalreporter.line(f"{t:8.1f}  {module}")
            terminalreporter.line("per worker: " + ", ".join(f"{w} {t:.0f} s" for w, t in sorted(workers.items()))
                                  + f"; every test's time in {TIMES_FILE}")
            self._write_times()
        over = self.over()
        if over:
            budget = self.config.getoption("--test-budget")
            terminalreporter.section(f"tests over the {budget:g} s budget (tests/time_budget.py)", red=True)
            for nodeid, t in over:
                terminalreporter.line(f"{t:8.1f} s  {nodeid}")
            terminalreporter.line("make each smaller (a shared trained model, the quick plan, fewer epochs), or "
                                  "mark it @pytest.mark.slow(reason=...) saying why it cannot be")

    def _write_times(self) -> None:
        try:
            TIMES_FILE.parent.mkdir(parents=True, exist_ok=True)
            tmp = TIMES_FILE.with_name(f".{TIMES_FILE.name}.{os.getpid()}")
            tmp.write_text(json.dumps({nodeid: {"s": round(t, 3), "slow": slow, "worker": self.worker.get(nodeid)}
                                       for nodeid, (t, slow) in self.totals.items()}, indent=0))
            os.replace(tmp, TIMES_FILE)
        except OSError:  # a read-only tree: the summary above is enough
            pass

    @pytest.hookimpl(trylast=True)
    def pytest_sessionfinish(self, session):
        if self.over() and session.exitstatus == pytest.ExitCode.OK:
            session.exitstatus = pytest.ExitCode.TESTS_FAILED
