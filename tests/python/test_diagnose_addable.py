"""An effect the diagnosis names but these data cannot feed (issue 53: on the real UTFSM data it named
`thermal`, with no temperature channel, and offered `--add thermal`, which `train` then refused):
the candidate carries no add command, names the channel it lacks, and the verdict says what to
record; with the channel, the same effect comes with its command.

The data: the virtual rig without effects (20 tests, 500 Hz) and a model trained on them; then the
force of every test falls by 5 % per kJ dissipated since the test's start (the oil heating within a
test), which that model does not know. Cost: about 17 s (one training of 60 epochs, two diagnoses,
one report).
"""

from __future__ import annotations

import numpy as np
import pytest

from dampnet.diagnosis.run import diagnose, missing_channels
from dampnet.rig import generate
from dampnet.training.pipeline import train_dataset

PLAN = {"name": "heat", "frequencies_hz": [0.5, 1.0, 2.0, 3.0], "amplitudes_m": [0.0254],
        "voltages_v": [0.0, 1.0, 2.25, 3.0, 5.0], "sample_rate_hz": 500.0, "samples": 2000, "min_cycles": 2}
#: the force's fall per kJ dissipated since the start of the test
FALL_PER_KJ = 0.05


def _heated(ds, with_temperature: bool):
    out = ds.subset([t.copy() for t in ds.tests])
    for t in out.tests:
        f, v = t.channels["force"], t.channels["velocity"]
        p = np.abs(f * v)
        e_kj = np.concatenate(([0.0], np.cumsum(0.5 * (p[1:] + p[:-1]) * np.diff(t.time)))) / 1000.0
        t.channels["force"] = f * (1.0 - FALL_PER_KJ * e_kj)
        if with_temperature:
            t.channels["temperature"] = 40.0 + 2.0 * e_kj     # 500 J/K: the rig's thermal effect's
    return out


@pytest.fixture(scope="module")
def model_and_data():
    ds = generate(PLAN, seed=3)
    model, _, _ = train_dataset(ds, decimate=2, max_epochs=60, control_prior=0.0, holdout_voltage=None)
    return model, ds


@pytest.fixture(scope="module")
def without_temperature(model_and_data):
    """(the heated data without a temperature channel, their diagnosis)."""
    model, ds = model_and_data
    heated = _heated(ds, False)
    return heated, diagnose(model, heated, n_surrogates=19)


def test_missing_channels_names_what_an_addition_needs(model_and_data):
    _, ds = model_and_data
    assert missing_channels("thermal", ds, "voltage") == ["temperature"]
    assert missing_channels("thermal", _heated(ds, True), "voltage") == []
    assert missing_channels("valve_lag", ds, "voltage") == []        # the control's lag: the voltage is there
    assert missing_channels("gas_spring", ds, "voltage") == []


def test_thermal_without_a_temperature_channel_is_named_without_an_add_command(without_temperature):
    _, d = without_temperature
    thermal = next(c for c in d["candidates"] if c["effect"] == "thermal")
    assert thermal["significant"] and d["verdict"] == "thermal", [(c["effect"], c["score"]) for c in d["candidates"]]
    assert thermal["add_command"] is None and thermal["missing_channels"] == ["temperature"]
    assert d["finding"]["not_addable"] == {"thermal": ["temperature"]}
    assert "thermal cannot be added from these data: its model input needs a temperature channel" in d["finding"]["sentence"]
    from dampnet.commands.diagnose import summary
    text = summary(d)
    assert "cannot be added: thermal cannot be added" in text and "--add thermal`)" in text
    assert "add it: dampnet train DATA --add thermal" not in text


def test_thermal_with_a_temperature_channel_comes_with_its_command(model_and_data):
    model, ds = model_and_data
    d = diagnose(model, _heated(ds, True), n_surrogates=19)
    thermal = next(c for c in d["candidates"] if c["effect"] == "thermal")
    assert thermal["significant"] and d["verdict"] == "thermal"
    assert thermal["add_command"] == "dampnet train DATA --add thermal" and thermal["missing_channels"] == []
    assert d["finding"]["not_addable"] == {} and "cannot be added" not in d["finding"]["sentence"]


def test_the_report_says_what_to_record_instead_of_a_command(model_and_data, without_temperature, tmp_path):
    """The HTML report's row for thermal without a temperature channel: the same words as the
    summary, no `--add` command. Cost: about 2 s (the report's figures)."""
    from dampnet.diagnosis.context import build_context
    from dampnet.diagnosis.report import write_report

    model, _ = model_and_data
    heated, d = without_temperature
    text = write_report(build_context(model, heated), d, tmp_path / "r").read_text()
    assert "thermal cannot be added from these data: its model input needs a temperature channel" in text
    assert "--add thermal</code>" not in text
