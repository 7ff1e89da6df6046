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

import pytest

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

    def pytest_runtest_logreport(self, report):
        entry = self.totals.setdefault(report.nodeid, [0.0, "slow" in report.keywords])
        entry[0] += report.duration

    def over(self) -> list[tuple[str, float]]:
        budget = self.config.getoption("--test-budget")
        if not budget or budget <= 0:
            return []
        return sorted(((nodeid, t) for nodeid, (t, slow) in self.totals.items() if t > budget and not slow),
                      key=lambda x: -x[1])

    def pytest_terminal_summary(self, terminalreporter):
        over = self.over()
        if over:
            budget = self.config.getoption("--test-budget")
            terminalreporter.section(f"tests over the {budget:g} s budget (tests/time_budget.py)", red=True)
            for nodeid, t in over:
                terminalreporter.line(f"{t:8.1f} s  {nodeid}")
            terminalreporter.line("make each smaller (a shared trained model, the quick plan, fewer epochs), or "
                                  "mark it @pytest.mark.slow(reason=...) saying why it cannot be")

    @pytest.hookimpl(trylast=True)
    def pytest_sessionfinish(self, session):
        if self.over() and session.exitstatus == pytest.ExitCode.OK:
            session.exitstatus = pytest.ExitCode.TESTS_FAILED
