"""`Loop.step` returns a StepReport (cheaper than the dict it used to return): the same
values as attributes and under the dict's keys, and a read-only Mapping, so code written
for the dict keeps working. And the runtime states which SIMD path its kernel uses."""

from __future__ import annotations

import collections.abc
from pathlib import Path

import numpy as np
import pytest

from dampnet import _core
from dampnet.sim.quarter_car.loop import damper_from_model
from dampnet.model import MlpModel

KEYS = ["force", "u", "x", "v", "a", "acc_s", "acc_us", "features", "clamped_mask", "status"]


def _stepped(repo_root, n=300):
    model = MlpModel.load(repo_root / "export" / "dn_model_default.json")
    lm = _core.LoopModel(damper_from_model(model, single=True), {}, {"kind": "skyhook_onoff"})
    loop = _core.Loop(lm)
    t = np.arange(n) * 1e-3
    z = 0.02 * np.sin(2 * np.pi * 1.3 * t)
    v = 0.02 * 2 * np.pi * 1.3 * np.cos(2 * np.pi * 1.3 * t)
    reports = [loop.step(zk, vk) for zk, vk in zip(z, v)]
    return lm, reports, z, v


def test_step_report_is_the_former_dict(repo_root):
    lm, reports, z, v = _stepped(repo_root)
    r = reports[-1]
    assert isinstance(r, collections.abc.Mapping)
    assert list(r.keys()) == KEYS and list(r) == KEYS and len(r) == len(KEYS)
    d = dict(r)
    assert list(d) == KEYS and [k for k, _ in r.items()] == KEYS and len(r.values()) == len(KEYS)
    plain = r.to_dict()
    for k in KEYS:
        if k == "features":
            np.testing.assert_array_equal(r[k], plain[k])
            np.testing.assert_array_equal(r.features, plain[k])
            assert r.features.shape == (3,)
        else:
            assert r[k] == plain[k] == getattr(r, k) == r.get(k), k
    assert "force" in r and "nope" not in r and 3 not in r
    assert r.get("nope") is None and r.get("nope", 7) == 7
    with pytest.raises(KeyError):
        r["nope"]
    with pytest.raises(KeyError):
        r[3]
    assert type(r) is _core.StepReport
    with pytest.raises(TypeError):
        _core.StepReport()  # only Loop.step makes them
    with pytest.raises(AttributeError):
        r.force = 1.0  # read-only
    assert np.ptp([q.force for q in reports]) > 10.0  # the road did excite the damper
    assert "StepReport(force=" in repr(r)


def test_step_report_force_equals_step_force_on_a_fresh_loop(repo_root):
    """The report is the step's: replaying the road on another loop gives the same values,
    and the force is step_force's. Reports outlive their loop and stay independent."""
    lm, reports, z, v = _stepped(repo_root, 50)
    other = _core.Loop(lm)
    for r, zk, vk in zip(reports, z, v):
        assert other.step_force(zk, vk) == r.force
    del other, lm
    assert len({r.force for r in reports}) > 10 and all(np.isfinite(r.force) for r in reports)


def _cpu_flags() -> set[str]:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("flags"):
                return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


def test_build_info_states_the_kernel_simd_path():
    info = _core.BUILD_INFO
    assert info["kernel_isa"] in ("avx512", "avx2+fma", "sse", "scalar", "eigen")
    # the backend is the one the build's kernel flags name (CMake: -DDN_KERNEL_BACKEND=...,
    # cpp/include/dampnet/kernel/backend.hpp); none named: the header's default
    names = {"avx512": "avx512", "avx2": "avx2+fma", "sse": "sse", "scalar": "scalar", "eigen": "eigen"}
    named = [f.split("=", 1)[1] for f in info["isa_flags"].split() if f.startswith("-DDN_KERNEL_BACKEND=")]
    if named:
        assert info["kernel_isa"] == names[named[-1]]
    if info["kernel_isa"] in ("avx512", "avx2+fma"):
        assert ("-mavx2" in info["flags"] and "-mfma" in info["flags"]) or "-march=native" in info["flags"]
    # DAMPNET_AVX2=AUTO (the default) enables the AVX2 backend on a machine that runs it, and
    # the AVX-512 backend only when DAMPNET_AVX512 asked for it (OFF by default).
    if {"avx2", "fma"} <= _cpu_flags() and "-mavx2" in info["isa_flags"]:
        assert info["kernel_isa"] in ("avx2+fma", "avx512")
    assert info["kernel_isa"] != "avx512" or "-mavx512f" in info["isa_flags"] or "-march=native" in info["isa_flags"]
