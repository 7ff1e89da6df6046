"""Shared fixtures: the repository root, and the C/C++ builds that several tests use."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

import needs

sys.path.insert(0, str(Path(__file__).resolve().parent))

from cbuild import ROOT, cmake_build  # noqa: E402

# the firmware lab (bench/firmware_lab.py: cross builds, QEMU runs), which several tests drive
sys.path.insert(0, str(ROOT / "bench"))


def pytest_configure(config):
    """One latency-harness build per library for the whole run, shared by its processes and by the
    commands it starts (`dampnet bench`, the demo, the installed wheel): dampnet.latency.harness
    keys it by its compile command and rebuilds it when an input is newer."""
    import os

    os.environ.setdefault("DAMPNET_BENCH_HARNESS_DIR", str(ROOT / "build" / "bench-harness"))
    # One compute thread per process (numpy's OpenBLAS, OpenMP, torch): the run is one process per
    # core (xdist -n auto), and each process's own pool of a thread per core beside them made the
    # cores contend: `pytest -n 2 tests/python/test_diagnose_hidden.py tests/python/test_diagnose_leftover.py`
    # took 112-118 s without and 100-110 s with, both orders (2026-12-03). Set here, before the workers start, so
    # they and every command they run inherit it; a test that wants more threads asks for them
    # (threadpoolctl, torch.set_num_threads).
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    # Bytecode written as modules are first imported, by this process and every Python the suite
    # starts (workers, the commands it runs, restart, sweep and dask workers): these machines set
    # PYTHONDONTWRITEBYTECODE=1, under which each of them compiled every module it imported
    # (0.3 s of CPU a process importing the training path, 1 s one importing all of dampnet).
    # python/env.sh unsets it too; this covers a suite started without it.
    os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
    sys.dont_write_bytecode = False
    # The FMUs the tests export are compiled at -O0: 1.25 s a compile against 2.6 s at the default
    # -O2, about 40 compiles a run; the installed wheel's commands and the demo build with the
    # defaults, as users do (wheel_env drops this).
    from dampnet.export.fmu.build import FLAGS_ENV

    os.environ.setdefault(FLAGS_ENV, "-O0")


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return ROOT


@pytest.fixture(scope="session")
def asan_build() -> Path:
    """The standalone project with its C/C++ tests, under AddressSanitizer + UBSan, at -Og (issue 51
    measured the build's CPU time 315 s at -O2 -g and 97 s at -O1 -g1, every C/C++ test passing under
    both; -Og, 2026-12-03: 75 s against 90 s at -O1, the tests' run 31 s against 28 s: the kernel
    tests' many fixed-size networks compile faster without -O1's inlining). The static library only
    (DAMPNET_BUILD_SHARED=OFF: the shared one is the same sources compiled a second time; the plain
    build's consumer runs it)."""
    return cmake_build("asan", "DAMPNET_BUILD_TESTS=ON", "DAMPNET_SANITIZE=ON", "DAMPNET_BUILD_SHARED=OFF",
                       "CMAKE_BUILD_TYPE=RelWithDebInfo", "CMAKE_C_FLAGS_RELWITHDEBINFO=-Og -g1 -DNDEBUG",
                       "CMAKE_CXX_FLAGS_RELWITHDEBINFO=-Og -g1 -DNDEBUG")


#: the plain Release build's options, shared by plain_build and installed_prefix; a unity build (each
#: target's sources compiled as one: the two libraries' 30 s of CPU become 18)
PLAIN = ("DAMPNET_BUILD_TESTS=ON", "CMAKE_BUILD_TYPE=Release", "CMAKE_UNITY_BUILD=ON")


@pytest.fixture(scope="session")
def installed_prefix() -> Path:
    """The standalone project's library (Release) built and installed into a prefix. It is the
    plain build's (the same folder and options: DAMPNET_BUILD_TESTS only adds tests/cpp, which
    installs nothing), so the library is compiled once for both (about 20 s of CPU less than a
    build of its own)."""
    return cmake_build("plain", *PLAIN, target=["dampnet_static", "dampnet_shared"], install=True) / "prefix"


@pytest.fixture(scope="session")
def plain_build() -> Path:
    """The standalone project with tests, plain kernel (for comparison with Eigen)."""
    return cmake_build("plain", *PLAIN, target="dn_print_outputs")


@pytest.fixture(scope="session")
def eigen_build() -> Path:
    """The standalone project with tests, dense layers through Eigen (libeigen3-dev)."""
    needs.need_file("/usr/include/eigen3/Eigen/Core", "libeigen3-dev", "Eigen's headers")
    return cmake_build("eigen", "DAMPNET_BUILD_TESTS=ON", "DAMPNET_USE_EIGEN=ON",
                       "CMAKE_BUILD_TYPE=Release", target="dn_print_outputs")


@pytest.fixture
def one_torch_thread():
    """torch on one thread for the test (timings and reductions independent of the machine)."""
    import torch

    old = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(old)


@pytest.fixture(scope="session")
def quick_envelope_model(tmp_path_factory):
    """A quick-plan model (LM, 30 epochs, seed 0) with its training envelope, shared by the
    coverage tests: {root, model, split, env}; root/model is its directory with envelope.npz,
    root/model_old the same model without (as written before envelopes), root/data the data."""
    from dampnet.data import write_dataset
    from dampnet.envelope import envelope_of
    from dampnet.modeldir import save_model_dir
    from dampnet.rig import generate
    from dampnet.training.pipeline import train_dataset

    root = tmp_path_factory.mktemp("quick_envelope_model")
    ds = generate("quick", seed=0)
    model, _, split = train_dataset(ds, algorithm="lm", max_epochs=30, seed=0)
    env = envelope_of(model, split)
    save_model_dir(model, {}, root / "model", envelope=env)
    save_model_dir(model, {}, root / "model_old")
    write_dataset(ds, root / "data")
    return dict(root=root, model=model, split=split, env=env)
