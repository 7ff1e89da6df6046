"""`Loop.step_force` is `Loop.step` without the report: the same force, the same state."""

from __future__ import annotations

import numpy as np
import pytest

from dampnet import _core
from dampnet.sim.quarter_car.loop import damper_from_model
from dampnet.model import MlpModel


@pytest.mark.parametrize("config", [{}, {"damper_eval": "per_step", "accel_feature": "linear"}])
def test_step_force_equals_step(repo_root, config):
    model = MlpModel.load(repo_root / "export" / "dn_model_default.json")
    lm = _core.LoopModel(damper_from_model(model, single=True), config, {"kind": "skyhook_onoff"})
    a, b = _core.Loop(lm), _core.Loop(lm)
    t = np.arange(2000) * 1e-3
    z = 0.02 * np.sin(2 * np.pi * 1.3 * t) + 0.004 * np.sin(2 * np.pi * 11.0 * t)
    v = np.gradient(z, t)
    forces = []
    for zk, vk in zip(z, v):
        f = b.step_force(zk, vk)
        assert f == a.step(zk, vk)["force"]
        forces.append(f)
    np.testing.assert_array_equal(a.state, b.state)
    assert np.ptp(forces) > 10.0  # the road did excite the damper
    with pytest.raises(ValueError, match="step"):
        b.step_force(float("nan"), 0.0)
