"""No Python call into dampnet._core crashes the interpreter (issue 14, item 2).

Each check runs in a subprocess: a segmentation fault there is a failed test with the
call that caused it, not a dead pytest.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

HERE = Path(__file__).resolve().parent


def run_python(code_or_args, cwd, timeout=300):
    """Python in a subprocess, in cwd (hypothesis may keep a .hypothesis cache there)."""
    args = code_or_args if isinstance(code_or_args, list) else ["-c", textwrap.dedent(code_or_args)]
    env = dict(os.environ, PYTHONFAULTHANDLER="1")
    return subprocess.run([sys.executable, *args], capture_output=True, text=True,
                          timeout=timeout, cwd=cwd, env=env)


def crash_report(proc) -> str:
    calls = [ln for ln in proc.stderr.splitlines() if ln.startswith("CALL ")]
    others = [ln for ln in proc.stderr.splitlines() if not ln.startswith("CALL ")]
    return (f"exit status {proc.returncode} (negative: killed by that signal)\n"
            f"last call: {calls[-1] if calls else '-'}\n" + "\n".join(others[-25:]))


def test_none_for_a_model_or_damper_raises_instead_of_crashing(tmp_path):
    # The calls of the issue, and the unbound methods with None for self (found by the fuzz
    # test below: pybind11 passed None to a member function as a null `this`).
    proc = run_python("""
        import numpy as np
        from dampnet import _core
        from dampnet.sim.quarter_car.loop import QuarterCar
        calls = {
            "QuarterCar(None)": lambda: QuarterCar(None),
            "Loop(None)": lambda: _core.Loop(None),
            "LoopModel(None, {}, {})": lambda: _core.LoopModel(None, {}, {}),
            "Damper.neural(None, ...)": lambda: _core.Damper.neural(None, ["velocity"]),
            "Loop.reset(None)": lambda: _core.Loop.reset(None),
            "Loop.state.fget(None)": lambda: _core.Loop.state.fget(None),
            "Loop.damper_evals.fget(None)": lambda: _core.Loop.damper_evals.fget(None),
            "Mlp.n_inputs.fget(None)": lambda: _core.Mlp.n_inputs.fget(None),
            # instances made by __new__ without __init__ reached methods as raw memory
            "uninitialised Loop.simulate": lambda: _core.Loop.__new__(_core.Loop).simulate(
                np.zeros(3), np.zeros(3)),
            "uninitialised Loop.state": lambda: _core.Loop.__new__(_core.Loop).state,
            "uninitialised Damper.forces": lambda: _core.Damper.__new__(_core.Damper).forces(
                0.0, 0.0, 0.0, 0.0, 0.0, 20.0),
            "uninitialised Damper.inverse": lambda: _core.Damper.__new__(_core.Damper).inverse(
                0.0, 0.0, 0.0, 0.0, 0.0, 20.0),
            "uninitialised Damper.control_range": lambda: _core.Damper.__new__(_core.Damper).control_range(),
            "uninitialised LoopModel.vehicle": lambda: _core.LoopModel.__new__(_core.LoopModel).vehicle,
            "Damper.neural(uninitialised Mlp)": lambda: _core.Damper.neural(
                _core.Mlp.__new__(_core.Mlp), ["velocity"]),
            "Loop(uninitialised LoopModel)": lambda: _core.Loop(_core.LoopModel.__new__(_core.LoopModel)),
        }
        for name, fn in calls.items():
            try:
                fn()
                print(name, "returned")
            except Exception as e:
                print(name, type(e).__name__)
        """, tmp_path)
    assert proc.returncode == 0, crash_report(proc)
    lines = proc.stdout.splitlines()
    assert len(lines) == 16, proc.stdout
    for line in lines:
        assert line.endswith("TypeError"), line


def test_every_core_callable_with_arbitrary_arguments(tmp_path):
    # bindings_fuzz_driver.py: every public callable of _core found by introspection, 10
    # derandomized hypothesis examples each (~900 calls, ~4 s of CPU).
    proc = run_python([str(HERE / "bindings_fuzz_driver.py"), "10"], tmp_path)
    assert proc.returncode == 0, crash_report(proc)
    assert "no crash" in proc.stdout


def test_init_again_on_an_initialised_object_is_refused(tmp_path):
    # Issue 29: pybind11 ignores a second __init__ (the object kept its old value, the call
    # returned None); now TypeError naming the class, and the object is unchanged.
    proc = run_python("""
        import numpy as np
        from dampnet import _core
        lin = [_core.Damper.linear(1500.0)] * 4
        fcm = _core.FullCarModel(lin)
        lm = _core.LoopModel(lin[0], {}, {})
        env_args = (np.array([-1.0, 0.0]), np.array([1.0, 5.0]),
                    np.full((1, _core.ENVELOPE_PAIR_WORDS), 0xFFFFFFFF, np.uint32))
        objects = {
            "FullCarModel": (fcm, ([_core.Damper.linear(10.0)] * 4, {"m_s": 900.0})),
            "FullCar": (_core.FullCar(fcm), (fcm,)),
            "Envelope": (_core.Envelope(*env_args), (np.zeros(3), np.ones(3), np.zeros((3, _core.ENVELOPE_PAIR_WORDS), np.uint32))),
            "LoopModel": (lm, (lin[0], {"m_s": 900.0}, {})),
            "Loop": (_core.Loop(lm), (lm,)),
        }
        for name, (obj, args) in objects.items():
            try:
                obj.__init__(*args)
                print(name, "returned")
            except TypeError as e:
                print(name, e)
        print("m_s", fcm.params["m_s"], lm.vehicle["m_s"])
        fresh = _core.FullCar.__new__(_core.FullCar)
        fresh.__init__(fcm)   # the first __init__ of an object made by __new__ still works
        print("fresh", fresh.state.shape)
        """, tmp_path)
    assert proc.returncode == 0, crash_report(proc)
    lines = proc.stdout.splitlines()
    for name in ("FullCarModel", "FullCar", "Envelope", "LoopModel", "Loop"):
        assert f"{name} {name}.__init__: this {name} is already initialised; make a new {name} instead" in lines
    assert "m_s 2600.0 700.0" in lines     # unchanged
    assert "fresh (53,)" in lines
