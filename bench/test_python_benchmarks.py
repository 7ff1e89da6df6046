"""Python-level benchmarks with pytest-benchmark (not part of the test suite: testpaths is
`tests`, and the project's addopts disable benchmarks). Run:

    python -m pytest bench/ --benchmark-enable [--benchmark-json FILE]

Targets (recorded in each benchmark's extra_info, never asserted: the machines are shared):
  * `Loop.step` through pybind11: median <= 1 us;
  * `Loop.simulate` over a road: >= 5e6 steps/s, with a linear and with the neural damper;
  * training: one LM epoch of the 3-30-1 network on a fixed small problem (no target; the
    figure to watch when changing dampnet.training).
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pytest_benchmark")

from dampnet import _core  # noqa: E402
from dampnet.latency import python_bench as bp
from dampnet.modeldir import default_model  # noqa: E402

SIM_STEPS = 200_000


@pytest.fixture(scope="module")
def model():
    return default_model()


@pytest.fixture(scope="module")
def loop_models(model):
    return bp._loops(model)  # linear (c = 1500 N s/m), neural_float, neural_double, neural_float_hil; RK4, skyhook


@pytest.mark.parametrize("damper", ["neural_float", "linear"])
def test_loop_step_pybind(benchmark, loop_models, damper):
    """One `Loop.step(z_r, v_r, u)` (returns a StepReport). The road sample is fixed (the car rides a
    slope at constant rate): the kernel's cost does not depend on the input values."""
    loop = _core.Loop(loop_models[damper])
    for k in range(2000):
        loop.step(0.001 * k * 1e-3, 0.001, 0.0)
    benchmark.group = "pybind Loop.step (target: median <= 1 us)"
    benchmark.extra_info.update(target_median_ns=bp.STEP_TARGET_NS, damper=damper)
    benchmark(loop.step, 0.002, 0.001, 0.0)
    median_ns = benchmark.stats.stats.median * 1e9
    benchmark.extra_info.update(median_ns=median_ns, meets_target=median_ns <= bp.STEP_TARGET_NS)


@pytest.mark.parametrize("damper", ["linear", "neural_float", "neural_double", "neural_float_hil",
                                    "neural_float_hil_out"])
def test_simulate_throughput(benchmark, loop_models, damper):
    """`Loop.simulate` over the C++ harness's road (1.3 Hz + 11 Hz, 20 mm), SIM_STEPS steps,
    the whole call including its output arrays (bp.simulate_records): fresh ones, or, for
    "_out", the previous run's arrays passed as out=."""
    lm = loop_models[damper.removesuffix("_out")]
    loop = _core.Loop(lm)
    z, v = bp.harness_road(float(lm.vehicle["dt"]), SIM_STEPS)
    out = loop.simulate(z, v, None, True) if damper.endswith("_out") else None
    benchmark.group = "pybind Loop.simulate (target: >= 5e6 steps/s)"
    benchmark.pedantic(loop.simulate, args=(z, v, None, True, out), rounds=5, iterations=1, warmup_rounds=1)
    sps = SIM_STEPS / benchmark.stats.stats.median
    benchmark.extra_info.update(damper=damper, n_steps=SIM_STEPS, steps_per_s_median=sps)
    if damper in bp.SIMULATE_TARGET_RUNS:
        benchmark.extra_info.update(target_steps_per_s=bp.SIMULATE_TARGET_STEPS_PER_S,
                                    meets_target=sps >= bp.SIMULATE_TARGET_STEPS_PER_S)


@pytest.mark.parametrize("n_tests,samples", [(24, 100), (96, 250)], ids=["2400-samples", "24000-samples"])
def test_lm_epoch(benchmark, n_tests, samples):
    """One Levenberg-Marquardt epoch (Jacobian, J'J, Cholesky trials until the error drops)
    of the 3-30-1 tanh network on synthetic dyno data, from the same initial weights every
    round, torch and numpy's BLAS (its JᵀJ, lm.gram) single-threaded, as fit runs a restart."""
    import torch
    from threadpoolctl import threadpool_limits

    from dampnet.model import mapminmax_settings
    from dampnet.training.lm import LevenbergMarquardt
    from dampnet.training.net import DTYPE, Layout
    from dampnet.training.problem import MlpProblem
    from dampnet.training.synthetic import synthetic_dyno

    X, y = synthetic_dyno(n_tests=n_tests, samples_per_test=samples, seed=0)
    xo, xg = mapminmax_settings(X)
    (yo,), (yg,) = mapminmax_settings(y)
    layout = Layout(3, (30,), "tanh")
    problem = MlpProblem(layout, torch.as_tensor((X - xo) * xg - 1.0, dtype=DTYPE),
                         torch.as_tensor((y - yo) * yg - 1.0, dtype=DTYPE))
    x0 = layout.init(torch.Generator().manual_seed(0))
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        benchmark.group = "training: one LM epoch, 3-30-1"
        with threadpool_limits(1, user_api="blas"):
            rec = benchmark.pedantic(lambda algo: algo.step(),
                                     setup=lambda: ((LevenbergMarquardt(problem, x0.clone()),), {}),
                                     rounds=20, warmup_rounds=2)
    finally:
        torch.set_num_threads(threads)
    assert np.isfinite(rec["train"])
    benchmark.extra_info.update(n_train=len(X), n_params=layout.n_params, torch_threads=1)
