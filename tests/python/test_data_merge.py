"""Several datasets as one (dampnet.data.merge_datasets, `dampnet train DATA DATA ...`): a campaign
plus the tests dampnet plan-tests proposed, trained together."""

from __future__ import annotations

import pytest

from dampnet.cli import main
from dampnet.data import DataError, merge_datasets, write_dataset
from dampnet.model import MlpModel
from dampnet.rig import generate

EXTRA = {"name": "extra", "tests": [{"frequency_hz": 12.0, "amplitude_m": 0.01, "control": 5.0, "test_id": "P01"},
                                    {"frequency_hz": 15.0, "amplitude_m": 0.01, "control": 0.0, "test_id": "P02"}],
         "samples": 2500}


@pytest.fixture(scope="module")
def two():
    return generate("quick", seed=0), generate(EXTRA, seed=1)


def test_merge_keeps_every_test_and_the_rig_provenance(two):
    a, b = two
    m = merge_datasets([a, b])
    assert m.test_ids == a.test_ids + b.test_ids and len(m) == len(a) + len(b)
    assert m.meta["noise"] == a.meta["noise"]  # the same rig noise: the noise floor still applies
    assert m.meta["merged"] == [{"source": a.source, "tests": len(a)}, {"source": b.source, "tests": len(b)}]
    assert merge_datasets([a]) is a


def test_merge_refuses_duplicate_ids_and_mixed_controls(two):
    a, b = two
    with pytest.raises(DataError, match=r"test 'T001' is in both .* test ids must be unique"):
        merge_datasets([a, a])
    c = b.subset([t.copy() for t in b.tests])
    c.source = "current-data"
    for t in c.tests:
        t.test_id = "C" + t.test_id
        t.channels["current"] = t.channels.pop("voltage")
        t.control_name = "current"
    with pytest.raises(DataError, match=r"current-data: test CP01 is controlled by current"):
        merge_datasets([a, c])


def test_train_on_two_datasets(two, tmp_path, capsys):
    a, b = two
    write_dataset(a, tmp_path / "a")
    write_dataset(b, tmp_path / "b")
    rc = main(["train", str(tmp_path / "a"), str(tmp_path / "b"), "--out", str(tmp_path / "m"), "--quiet",
               "--restarts", "1", "--max-epochs", "10", "--decimate", "20", "--valve", "off"])
    assert rc == 0, capsys.readouterr().err
    data = MlpModel.load(tmp_path / "m").meta["data"]
    assert {"P01", "P02"} <= set(data["train_tests"])          # the planned tests are trained on
    assert set(data["holdout_tests"]) == {t.test_id for t in a.tests if t.control_nominal == 2.25}
    capsys.readouterr()
    assert main(["train", str(tmp_path / "a"), str(tmp_path / "a"), "--out", str(tmp_path / "n"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("dampnet: error: ") and "test ids must be unique" in err and err.count("\n") == 1
    assert not (tmp_path / "n").exists()
