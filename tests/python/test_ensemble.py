"""dampnet.training.ensemble.average_networks: K one-hidden-layer networks as one, whose output is their
mean: checked against the members' own outputs in numpy (dampnet.reference) and in the C++
runtime, with physics terms, and refused (naming the field) for members that cannot add up."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dampnet import _core
from dampnet.training.ensemble import average_networks
from dampnet.model import ModelError
from dampnet.predict import predict_force
from dampnet.sim.quarter_car.loop import damper_from_model
from loop_helpers import numpy_forward, random_model

FEATURES = ["velocity", "acceleration", "voltage"]
TERMS = [{"kind": "bump_stop", "params": [0.01, 2e5, 1.5]}]


def test_the_average_is_one_network_with_the_members_mean_output():
    members = [random_model(FEATURES, hidden=h, seed=s, terms=TERMS) for h, s in ((12, 1), (20, 2), (9, 3))]
    avg = average_networks(members)
    assert avg.hidden == (41,) and avg.meta["ensemble"]["members"] == 3
    assert avg.meta["ensemble"]["member_ids"] == [m.model_id() for m in members]
    rng = np.random.default_rng(0)
    X = rng.uniform([-0.6, -12, -0.5], [0.6, 12, 5.5], size=(500, 3))  # beyond the ranges too (saturation)
    mean = np.mean([numpy_forward(m, X) for m in members], axis=0)
    np.testing.assert_allclose(numpy_forward(avg, X), mean, rtol=1e-12, atol=1e-9)
    # a hybrid model: the terms once, not K times
    xd = rng.uniform(-0.02, 0.02, 500)
    np.testing.assert_allclose(predict_force(avg, X, xd), np.mean([predict_force(m, X, xd) for m in members], axis=0),
                               rtol=1e-12, atol=1e-9)
    # the C++ runtime (double) runs it as it runs any network
    args = (xd, X[:, 0], X[:, 1], X[:, 2], X[:, 2], np.full(500, 20.0))  # x, v, a, u, u_lag, temperature
    runtime = damper_from_model(avg).forces(*args)[0]
    each = np.mean([damper_from_model(m).forces(*args)[0] for m in members], axis=0)
    np.testing.assert_allclose(runtime, each, rtol=1e-9, atol=1e-6)
    assert average_networks(members[:1]).hidden == (12,)


def test_members_that_cannot_add_up_are_refused():
    a, b = random_model(FEATURES, seed=1), random_model(FEATURES, seed=2)
    with pytest.raises(ModelError, match="no models"):
        average_networks([])
    with pytest.raises(ModelError, match="model 1's in_gain differs"):
        average_networks([a, dataclasses.replace(b, in_gain=b.in_gain * 1.01)])
    with pytest.raises(ModelError, match="model 1's features differs"):
        average_networks([a, random_model(["velocity", "voltage", "acceleration"], seed=2)])
    with pytest.raises(ModelError, match="model 1's terms differs"):
        average_networks([a, random_model(FEATURES, seed=2, terms=TERMS)])
    with pytest.raises(ModelError, match="average: 13 networks of 30, 30, 30, .* hidden neurons make a layer of 390; "
                                         f"dampnet's models hold at most {_core.MAX_HIDDEN}"):
        average_networks([random_model(FEATURES, hidden=30, seed=s) for s in range(13)])
    two = dataclasses.replace(b, w2=np.eye(12), b2=np.zeros(12))
    with pytest.raises(ModelError, match="model 1 has two hidden layers"):
        average_networks([a, two])
