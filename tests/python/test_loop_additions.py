"""The diagnosis loop adds every effect a diagnosis names, in its order (dampnet.recipes.loop,
issue 53): on Labcontrol's MR damper the first diagnosis named friction, gas_spring and
compressibility; adding only the first and diagnosing again named nothing (29.8 N held out),
adding the three together gave 18.3 N (bench/RESULTS.md, "Real dampers"). The rules, on
diagnoses written out (no training), and `dampnet diagnose`'s command for adding them together.
Cost: < 1 s.
"""

from __future__ import annotations

from types import SimpleNamespace

from dampnet.commands.diagnose import together_command
from dampnet.recipes.loop import LoopStep, next_request
from dampnet.recipes.training import TrainingRequest


def _step(named, added=(), not_addable=None) -> LoopStep:
    d = {"verdict": named[0] if named else None,
         "finding": {"effects": list(named), "not_addable": dict(not_addable or {})}}
    return LoopStep("x", tuple(added), TrainingRequest.of(), None, 0.0, diagnosis=d)


def test_every_named_effect_is_added_in_the_diagnosis_order():
    assert _step(["friction", "gas_spring", "compressibility"]).to_add(3) == (
        ("friction", "gas_spring", "compressibility"), {}, None)
    assert _step(["gas_spring", "friction"]).to_add(3) == (("gas_spring", "friction"), {}, None)


def test_what_is_not_added_and_why():
    # already added: only the new ones; all of them already: stop
    assert _step(["friction", "gas_spring"], added=["friction"]).to_add(3) == (("gas_spring",), {}, None)
    effects, _, stop = _step(["friction"], added=["friction"]).to_add(3)
    assert effects == () and stop == "the diagnosis names friction again, already added"
    # an effect the data cannot carry is left out, saying why; when it is the only one, the loop stops
    assert _step(["friction", "thermal"], not_addable={"thermal": ["temperature"]}).to_add(3) == (
        ("friction",), {"thermal": "the data have no temperature channel"}, None)
    effects, _, stop = _step(["thermal"], not_addable={"thermal": ["temperature"]}).to_add(3)
    assert effects == () and "thermal, whose input needs a temperature channel the data lack" in stop
    # nothing named; and max_steps caps the effects added in all
    assert _step([]).to_add(3) == ((), {}, "the diagnosis names no effect")
    assert _step(["friction", "gas_spring", "compressibility"], added=["valve_lag"]).to_add(2) == (
        ("friction",), {"gas_spring": "max_steps 2", "compressibility": "max_steps 2"}, None)
    effects, _, stop = _step(["friction"], added=["valve_lag", "gas_spring"]).to_add(2)
    assert effects == () and "stops at 2 additions" in stop


def test_the_next_request_adds_them_together_after_what_the_model_has():
    model = SimpleNamespace(features=["velocity", "acceleration", "voltage", "displacement"],
                            feature_params={}, terms=[])
    diagnosis = {"candidates": [{"effect": "friction", "parameters": {"presliding_length_mm": 0.3}}]}
    req = next_request(TrainingRequest.of(), model, diagnosis, ("friction", "compressibility"))
    assert req.add == ("friction", "compressibility") and req.features[-1] == "displacement"
    assert next_request(TrainingRequest.of(), model, diagnosis, ["friction"]).add == ("friction",)


def test_diagnose_prints_the_command_that_adds_them_together():
    def diag(named, commands):
        return {"finding": {"effects": named},
                "candidates": [{"effect": e, "add_command": c} for e, c in commands.items()]}

    cmd = {"friction": "dampnet train D --add friction", "gas_spring": "dampnet train D --add gas_spring",
           "thermal": None}
    assert (together_command(diag(["friction", "gas_spring"], cmd), "d.json")
            == "dampnet train D --add friction --add gas_spring --diagnosis d.json")
    assert together_command(diag(["gas_spring", "friction"], cmd)) == "dampnet train D --add gas_spring --add friction"
    # one effect (or one the data can carry): its own command says it, no second line
    assert together_command(diag(["friction"], cmd)) is None
    assert together_command(diag(["friction", "thermal"], cmd)) is None
