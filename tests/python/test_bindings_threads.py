"""The threading contract of dampnet._core (issue 14, item 3).

Models are shareable (Mlp, Damper, LoopModel are immutable once built); a Loop is one
mutable loop state and refuses a second call while one is under way (RuntimeError), so
threads sharing a Loop get either the right result or that error, never a wrong result.
"""

from __future__ import annotations

import threading

import numpy as np
import pytest

from dampnet import _core
from dampnet.sim.quarter_car.loop import QuarterCar, damper_from_model
from loop_helpers import random_model

BUSY = "already in use"


def road(n, seed=0, dt=1e-3):
    t = np.arange(n) * dt
    w = 2 * np.pi * (1.3 + 0.2 * seed)
    return 0.015 * np.sin(w * t), 0.015 * w * np.cos(w * t)


def run_threads(n, target):
    errors = []

    def wrapped(i):
        try:
            target(i)
        except BaseException as e:  # reported by the test, not lost in the thread
            errors.append(e)

    threads = [threading.Thread(target=wrapped, args=(i,)) for i in range(n)]
    for th in threads:
        th.start()
    for th in threads:
        th.join(timeout=120)
    assert not any(th.is_alive() for th in threads), "a thread hung"
    if errors:
        raise errors[0]


def test_threads_sharing_one_loop_get_the_right_result_or_the_busy_error():
    # Before the busy flag, four threads in simulate on one Loop (GIL released) stepped one
    # state together: times not monotonic, forces off, no error.
    model = _core.LoopModel(_core.Damper.linear(1500.0), {}, {"kind": "skyhook_onoff"})
    z, zd = road(100_000)
    want = _core.Loop(model).simulate(z, zd)
    shared = _core.Loop(model)
    start = threading.Barrier(4)
    outcome = {"right": 0, "refused": 0, "wrong": 0}
    lock = threading.Lock()

    def work(i):
        start.wait()
        for _ in range(5):
            try:
                got = shared.simulate(z, zd)
            except RuntimeError as e:
                assert BUSY in str(e) and "own Loop" in str(e), str(e)
                kind = "refused"
            else:
                same = (np.array_equal(got["state"], want["state"]) and
                        np.array_equal(got["force"], want["force"]))
                kind = "right" if same else "wrong"
            with lock:
                outcome[kind] += 1

    run_threads(4, work)
    assert outcome["wrong"] == 0, outcome
    assert outcome["right"] >= 1, outcome
    # never left busy: the loop still runs, and from where it was left
    np.testing.assert_array_equal(shared.simulate(z, zd)["state"], want["state"])


def test_separate_loops_on_one_shared_model_equal_serial_runs():
    # One neural model (acceleration feature, implicit solve) and its MLP shared by four
    # threads, each with its own Loop and road: bit-identical to the serial runs. (The random
    # network feeds energy in: its car leaves the physical bounds after 2.8 s, DN_E_DIVERGED.)
    model = random_model(["velocity", "acceleration", "displacement"], seed=3)
    car = QuarterCar(damper_from_model(model), {}, {"kind": "skyhook_onoff"})
    roads = [road(2_500, seed=i) for i in range(4)]
    serial = [car.spawn().simulate(z, zd) for z, zd in roads]
    got = [None] * 4
    start = threading.Barrier(4)

    def work(i):
        mine = car.spawn()
        start.wait()
        for _ in range(3):
            got[i] = mine.simulate(*roads[i])

    run_threads(4, work)
    for i in range(4):
        for key in ("state", "force", "features", "status"):
            np.testing.assert_array_equal(got[i][key], serial[i][key], err_msg=f"thread {i} {key}")


def blocking_callback_model():
    """A callback damper that, on its first call, waits until the test says go."""
    entered, go = threading.Event(), threading.Event()
    calls = {"n": 0}

    def force(inp):
        calls["n"] += 1
        if calls["n"] == 1:
            entered.set()
            assert go.wait(60), "the test never released the callback"
        return 1500.0 * inp.v

    model = _core.LoopModel(_core.Damper.callback(force), {"damper_eval": "per_step"}, {})
    return model, entered, go


def test_a_call_during_simulate_is_refused_and_the_run_is_right():
    model, entered, go = blocking_callback_model()
    z, zd = road(2000)
    loop = _core.Loop(model)
    result = {}
    runner = threading.Thread(target=lambda: result.update(r=loop.simulate(z, zd)))
    runner.start()
    try:
        assert entered.wait(60)
        # simulate is now inside the callback (the GIL released in Event.wait): every use of
        # the same Loop from this thread is refused, naming the contract
        for name, use in [("simulate", lambda: loop.simulate(z, zd)), ("step", lambda: loop.step(0, 0)),
                          ("step_force", lambda: loop.step_force(0, 0)), ("forward", loop.forward),
                          ("reset", loop.reset), ("state", lambda: loop.state),
                          ("damper_evals", lambda: loop.damper_evals)]:
            with pytest.raises(RuntimeError, match=BUSY) as e:
                use()
            assert f"Loop.{name}" in str(e.value) and "own Loop" in str(e.value)
        with pytest.raises(RuntimeError, match=BUSY):
            loop.state = np.zeros(len(_core.STATE_NAMES))
        # another Loop on the same model is free to run meanwhile
        other = _core.Loop(model).simulate(z, zd)
    finally:
        go.set()
        runner.join(60)
    np.testing.assert_array_equal(result["r"]["state"], other["state"])


def test_the_busy_flag_is_cleared_after_every_error():
    state = {"mode": "ok"}
    holder = {}

    def force(inp):
        if state["mode"] == "raise":
            raise ZeroDivisionError("from the callback")
        if state["mode"] == "reenter":  # the damper steps the loop that is evaluating it
            holder["loop"].step_force(0.0, 0.0)
        return 1500.0 * inp.v

    model = _core.LoopModel(_core.Damper.callback(force), {"damper_eval": "per_step"}, {})
    loop = holder["loop"] = _core.Loop(model)
    z, zd = road(500)
    want = _core.Loop(model).simulate(z, zd)
    bad_road = z.copy()
    bad_road[100] = np.nan
    bad_out = dict(want, force=np.zeros(3))
    errors = [(lambda: loop.simulate(bad_road, zd), ValueError, "NONFINITE_INPUT"),
              (lambda: loop.simulate(z, zd, out=bad_out), ValueError, "out"),
              (lambda: loop.step(np.nan, 0.0), ValueError, "NONFINITE_INPUT"),
              (lambda: setattr(loop, "state", np.full(13, np.inf)), ValueError, "NONFINITE"),
              (lambda: loop.simulate(z, zd, u=np.zeros(3)), ValueError, "u must be")]
    for mode in ("raise", "reenter"):
        for call in (lambda: loop.simulate(z, zd), lambda: loop.step(0.0, 0.0), loop.forward):
            errors.append((call, ZeroDivisionError if mode == "raise" else RuntimeError,
                           "from the callback" if mode == "raise" else BUSY, mode))
    for call, exc, match, *mode in errors:
        state["mode"] = mode[0] if mode else "ok"
        with pytest.raises(exc, match=match):
            call()
        state["mode"] = "ok"
        np.testing.assert_array_equal(loop.simulate(z, zd)["state"], want["state"])


def test_threads_sharing_a_callback_damper_get_their_own_errors():
    # A callback's exception belongs to the run that called it. It was kept on the (shared)
    # damper, so a loop in another thread could raise it, or stop on its NaN.
    def force(inp):
        if threading.current_thread().name == "bad":
            raise KeyError("bad thread")
        return 1500.0 * inp.v

    model = _core.LoopModel(_core.Damper.callback(force), {"damper_eval": "per_step"}, {})
    z, zd = road(3000)
    want = _core.Loop(model).simulate(z, zd)
    stop = threading.Event()
    seen = {"bad": 0, "good": 0}

    def bad():
        loop = _core.Loop(model)
        while not stop.is_set():
            with pytest.raises(KeyError, match="bad thread"):
                loop.simulate(z, zd)
            seen["bad"] += 1

    def good():
        loop = _core.Loop(model)
        try:
            for _ in range(15):
                np.testing.assert_array_equal(loop.simulate(z, zd)["state"], want["state"])
                seen["good"] += 1
        finally:
            stop.set()

    errors = []

    def recorded(fn):
        def run():
            try:
                fn()
            except BaseException as e:  # reported by the test, not lost in the thread
                errors.append(e)
                stop.set()
        return run

    threads = [threading.Thread(target=recorded(bad), name="bad"),
               threading.Thread(target=recorded(good), name="good")]
    for th in threads:
        th.start()
    for th in threads:
        th.join(120)
    if errors:
        raise errors[0]
    assert seen["good"] == 15 and seen["bad"] >= 1, seen


def test_a_damper_is_not_changed_while_it_is_evaluated():
    holder = {}

    def force(inp):
        holder["damper"].add_term("position_poly", np.zeros(4))
        return 0.0

    d = holder["damper"] = _core.Damper.callback(force)
    with pytest.raises(RuntimeError, match="being evaluated"):
        d.forces(0.0, np.linspace(-1, 1, 5), 0.0, 0.0, 0.0, 20.0)
    d.add_term("position_poly", np.zeros(4))  # set-up outside an evaluation is fine
