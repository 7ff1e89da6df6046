"""simulate(..., out=previous result): the benchmark's reused-arrays row. Same results as fresh
arrays, written in place into the caller's arrays, and every misuse refused by name."""

import numpy as np
import pytest

from dampnet import _core
from dampnet.sim.quarter_car.loop import QuarterCar


def _car(neural: bool = False) -> QuarterCar:
    if neural:
        from dampnet.latency.python_bench import _loops, default_model
        return QuarterCar(None, model=_loops(default_model())["neural_float_hil"])
    return QuarterCar(_core.Damper.linear(1500.0), {}, {"kind": "skyhook_onoff"})


def _road(n: int, dt: float = 1e-3):
    t = np.arange(n) * dt
    return 0.02 * np.sin(2 * np.pi * 1.3 * t), 0.02 * 2 * np.pi * 1.3 * np.cos(2 * np.pi * 1.3 * t)


@pytest.mark.parametrize("neural", [False, True])
def test_out_equals_fresh_and_is_written_in_place(neural):
    car = _car(neural)
    z, v = _road(500)
    fresh = car.simulate(z, v)
    out = {k: np.full_like(a, 7) for k, a in fresh.items() if k != "t"}
    res = car.simulate(z, v, out=out)
    for k, a in out.items():
        assert res[k] is a  # the caller's arrays, returned
        np.testing.assert_array_equal(a, fresh[k])
    np.testing.assert_array_equal(res["t"], fresh["t"])
    again = car.simulate(z, v, out=res)  # a previous result, "t" and all, is a valid out
    np.testing.assert_array_equal(again["force"], fresh["force"])


def test_out_misuse_is_refused():
    car = _car()
    z, v = _road(50)
    good = car.simulate(z, v)

    def bad(**change):
        o = {k: a for k, a in good.items() if k != "t"}
        o.update(change)
        return o

    with pytest.raises(ValueError, match="no 'status'"):
        car.simulate(z, v, out={k: a for k, a in good.items() if k != "status"})
    with pytest.raises(ValueError, match=r"out\['status'\] has the wrong dtype"):
        car.simulate(z, v, out=bad(status=good["status"].astype(np.int64)))
    with pytest.raises(ValueError, match=r"out\['force'\] must be"):
        car.simulate(z, v, out=bad(force=np.empty(49)))
    with pytest.raises(ValueError, match=r"out\['state'\] must be"):
        car.simulate(z, v, out=bad(state=np.empty((50, 26))[:, ::2]))  # the right shape, not C-contiguous
    unaligned = np.frombuffer(bytearray(50 * 8 + 1), dtype=np.float64, offset=1, count=50)
    with pytest.raises(ValueError, match=r"out\['a'\] must be"):
        car.simulate(z, v, out=bad(a=unaligned))                          # not aligned
    with pytest.raises(ValueError, match="share memory with each other"):
        car.simulate(z, v, out=bad(v=good["x"]))
    ro = np.empty(50)
    ro.flags.writeable = False
    with pytest.raises(ValueError, match=r"out\['x'\] must be"):
        car.simulate(z, v, out=bad(x=ro))
    with pytest.raises(ValueError, match="share memory"):
        car.simulate(good["v"], v, out=good)
    with pytest.raises(TypeError):
        car.simulate(z, v, out=[1, 2])


def test_no_u_means_zero_control_for_the_external_law():
    """simulate without u: the external law's control is 0 (clamped to its limits) for every
    step; before, an empty array stood in for u and was read past its end (garbage or a crash)."""
    from dampnet.sim.quarter_car.loop import QuarterCar

    car = QuarterCar(_core.Damper.linear(1500.0), {}, {"kind": "external", "u_min": -1.0})
    z, v = _road(200_000)
    r = car.simulate(z, v)
    assert np.all(r["status"] >= 0) and np.all(r["control"] == 0.0)
    r2 = car.simulate(z, v, u=np.zeros_like(z))
    np.testing.assert_array_equal(r["state"], r2["state"])


def test_large_results_are_ordinary_arrays():
    """From 4 MiB up the fresh result arrays are huge-page mappings owned by the arrays (see
    fresh_array in module.cpp): the same values, shapes and flags as numpy-allocated ones."""
    car = _car()
    n = 600_000  # every 8-byte column 4.8 MB
    z, v = _road(n)
    big = car.simulate(z, v)
    ref = car.simulate(z, v, out={k: np.empty_like(a) for k, a in big.items() if k != "t"})
    for k, a in big.items():
        assert a.flags.writeable and (a.flags.c_contiguous or k == "t"), k
        assert a.shape == ref[k].shape and a.dtype == ref[k].dtype, k
        np.testing.assert_array_equal(a, ref[k])
    assert big["state"].base is not None  # the mapping's owner
    big["force"][:] = 1.0  # writeable memory of its own
    assert not np.shares_memory(big["force"], big["x"])
    del big, ref
