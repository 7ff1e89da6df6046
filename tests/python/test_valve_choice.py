"""valve "auto", `dampnet train`'s default (dampnet.training.valve_choice, issue 54 item 2): the model
trained without and with a free valve term under the network, the lower validation error kept,
and the choice said. Both ways on the rig's quick plan (0, 2.25 and 5 V, the valves' blow-off
knees in the truth damper; nothing held out: three levels): with Bayesian regularisation cut at 40
epochs the network alone has not bent at the knees yet and the hybrid's validation NRMSE is three
quarters of its (0.0056 against 0.0073, seed 0), so the hybrid is kept; with LM at 60 epochs the
network alone is the better (0.0045 against 0.0058), so it is kept, bit for bit the valve "off"
model. Where the term cannot be tried (no displacement channel, two control levels) or fitted (no
samples in compression), the network is trained once or kept, and the record says why.

Cost: about 25 s on one core (two trainings with a valve fit of about 3 s, six without, short).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import dampnet
from dampnet.cli import main
from dampnet.data import write_dataset
from dampnet.recipes.loop import next_request
from dampnet.recipes.training import TrainingRequest
from dampnet.rig import generate
from dampnet.training.valve_choice import keep_hybrid, sentence

# the two cases above: each decides the other way on the same data
KEPT = ("--algorithm", "br", "--max-epochs", "40", "--seed", "0", "--holdout-voltage", "none")
NOT_KEPT = {"algorithm": "lm", "max_epochs": 60, "seed": 0, "holdout_voltage": None}


@pytest.fixture(scope="module")
def quick():
    return generate("quick", seed=0)


def _weights(model) -> list[np.ndarray]:
    return [np.asarray(w, dtype=np.float64) for w in (model.w1, model.b1, model.w_out, model.b_out,
                                                      model.in_offset, model.in_gain, model.out_offset)]


def test_the_command_keeps_the_hybrid_where_it_validates_better_and_says_so(quick, tmp_path, capsys):
    write_dataset(quick, tmp_path / "data")
    assert main(["train", str(tmp_path / "data"), "--out", str(tmp_path / "m"), *KEPT]) == 0
    out = capsys.readouterr().out
    model = json.loads((tmp_path / "m" / "model.json").read_text())
    metrics = json.loads((tmp_path / "m" / "metrics.json").read_text())
    rec = model["meta"]["valve"]
    assert rec["used"] is True and rec["choice"] == "auto"
    v = rec["validation_nrmse"]
    assert v["with"] < 0.8 * v["without"]           # measured 0.0056 against 0.0073
    assert f"valve term: used, validation NRMSE {v['with']:.4f} with it against {v['without']:.4f} without" in out
    assert metrics["training"]["valve"] == rec
    # the kept model is the hybrid: its fitted valve, and the validation error recorded is its own
    (term,) = model["terms"]
    assert term["kind"] == "valve" and len(term["params"]) == 10
    assert v["with"] == pytest.approx(metrics["training"]["nrmse"]["val"], abs=1e-7)
    # and the error without is the network alone's, trained as valve "off" would
    off = dampnet.train(quick, algorithm="br", max_epochs=40, seed=0, valve="off", holdout_voltage=None)
    assert v["without"] == pytest.approx(off.info.metrics["val"], abs=1e-7)
    assert "valve" not in off.model.meta and not off.model.terms


def test_auto_keeps_the_network_where_it_validates_better_bit_for_bit_the_off_model(quick):
    auto = dampnet.train(quick, valve="auto", **NOT_KEPT)
    off = dampnet.train(quick, valve="off", **NOT_KEPT)
    rec = auto.model.meta["valve"]
    assert rec["used"] is False and rec["validation_nrmse"]["with"] > rec["validation_nrmse"]["without"]
    assert not auto.model.terms
    for a, b in zip(_weights(auto.model), _weights(off.model)):
        np.testing.assert_array_equal(a, b)
    assert auto.valve_note.startswith("valve term: not used, validation NRMSE")
    # the loop's next model does not decide again: the terms carry the choice
    nxt = next_request(TrainingRequest.of(valve="auto"), auto.model, None, ())
    assert nxt.valve == "off" and not nxt.terms


def test_without_a_displacement_channel_it_is_not_tried_and_trains_once():
    ds = generate("quick", seed=0)
    for t in ds.tests:
        t.channels.pop("displacement")
    trained = dampnet.train(ds, valve="auto", algorithm="lm", max_epochs=20, seed=0)
    rec = trained.model.meta["valve"]
    assert rec["used"] is False and "displacement" in rec["not_tried"] and "validation_nrmse" not in rec
    assert trained.valve_note.startswith("valve term: not tried (the physics terms need a displacement channel")


def test_a_valve_that_cannot_be_fitted_leaves_the_network_and_says_why():
    ds = generate("quick", seed=0)
    for t in ds.tests:   # no sample in compression: the valve's fit needs both directions
        t.channels["velocity"] = np.abs(t.channels["velocity"])
    trained = dampnet.train(ds, valve="auto", algorithm="lm", max_epochs=20, seed=0, holdout_voltage=None)
    rec = trained.model.meta["valve"]
    assert rec["used"] is False and "extension and in compression" in rec["failed"]
    assert not trained.model.terms
    assert "its fit failed" in trained.valve_note and "compression" in trained.valve_note


def test_on_two_control_levels_it_is_not_tried_and_the_model_is_the_off_model(quick):
    """The quick plan with 2.25 V held out trains on 0 and 5 V: the valve's control gain would bend
    between them unchecked (there, "auto" kept the hybrid for 7 seeds of 10 and the held-out NRMSE
    rose from 0.0315 to 0.0364), so it is not tried: one training, bit for bit valve "off"'s."""
    kw = {"algorithm": "lm", "max_epochs": 20, "seed": 0}
    auto = dampnet.train(quick, valve="auto", **kw)
    off = dampnet.train(quick, valve="off", **kw)
    rec = auto.model.meta["valve"]
    assert rec["used"] is False and "validation_nrmse" not in rec and not auto.model.terms
    assert rec["not_tried"] == ("the training tests hold 2 control levels (0, 5 V): the valve term's control gain "
                                "needs 3 at least, one between the others")
    for a, b in zip(_weights(auto.model), _weights(off.model)):
        np.testing.assert_array_equal(a, b)
    assert auto.valve_note.startswith("valve term: not tried (the training tests hold 2 control levels")


def test_the_loop_keeps_a_kept_valve_free_to_be_fitted_again():
    from dampnet.model import MlpModel

    model = MlpModel.__new__(MlpModel)
    model.features, model.feature_params = ["velocity", "acceleration", "voltage"], {}
    model.terms = [{"kind": "valve", "params": [0.03] + [1.0] * 7}]
    model.meta = {"valve": {"choice": "auto", "used": True}}
    nxt = next_request(TrainingRequest.of(valve="auto"), model, None, ())
    assert nxt.valve == "off" and list(nxt.terms) == [{"kind": "valve"}]
    # a request that said "on" keeps saying it (one valve: with_valve adds none to a valve there)
    model.meta = {}
    assert next_request(TrainingRequest.of(valve="on"), model, None, ()).valve == "on"


@pytest.mark.parametrize("without, with_, kept", [(0.02, 0.01, True), (0.01, 0.02, False), (0.01, 0.01, False),
                                                  (0.0100, 0.0096, False), (0.0100, 0.0095, True),
                                                  (float("nan"), 0.01, True), (0.01, float("nan"), False)])
def test_the_hybrid_is_kept_only_when_its_error_is_lower_by_the_margin(without, with_, kept):
    """MIN_GAIN, 5 %: UTFSM's hybrid validated 1.7 % better but held out worse at rest and after the loop."""
    assert keep_hybrid(without, with_) is kept


def test_no_sentence_without_an_auto_choice():
    assert sentence(None) is None and sentence({"choice": "on"}) is None
