"""Callback dampers in dampnet._core: what their Python function may do (issue 14, item 2)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from dampnet import _core


def car(fn, n=50):
    model = _core.LoopModel(_core.Damper.callback(fn), {"damper_eval": "per_step"}, {})
    return _core.Loop(model), np.zeros(n), np.zeros(n)


@pytest.mark.parametrize("returned, shown", [("abc", "str 'abc'"), (None, "NoneType None"),
                                             ([1.0], "list [1.0]"), (1j, "complex 1j")])
def test_a_callback_returning_no_number_raises_a_type_error_saying_so(returned, shown):
    loop, z, zd = car(lambda inp: returned)
    for call in (lambda: loop.simulate(z, zd), lambda: loop.step(0.0, 0.0), loop.forward):
        with pytest.raises(TypeError, match=re.escape(f"returned {shown}") + ".*expected the force"):
            call()


def test_a_callback_exception_is_raised_as_itself_with_its_traceback():
    def fn(inp):
        raise LookupError("from the damper")

    loop, z, zd = car(fn)
    with pytest.raises(LookupError, match="from the damper") as e:
        loop.simulate(z, zd)
    assert any(tb.name == "fn" for tb in e.traceback)
    d = _core.Damper.callback(fn)
    with pytest.raises(LookupError, match="from the damper"):
        d.forces(0.0, np.zeros(3), 0.0, 0.0, 0.0, 20.0)


def test_simulate_calls_a_stateful_callback_once_per_sample():
    # simulate asked the damper for its feature count with an extra evaluation first: a
    # stateful callback (the rig's truth damper) advanced one step more than the run
    calls = []
    loop, z, zd = car(lambda inp: calls.append(inp.t) or 0.0, n=40)
    loop.simulate(z, zd)
    assert len(calls) == 40
    assert calls == sorted(calls) and calls[0] == 0.0
