"""The CI-sized run of the atheris harness over the damper spec strings (MODEL of `dampnet
simulate` / `vehicle`: fuzz/python/fuzz_damper_specs.py): its fixed seed corpus plus a few
thousand mutations with a fixed seed; only a damper with finite forces or the project's own
one-line errors (LoopError, ModelError), no other exception, no input slower than 10 s."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from atheris_run import atheris_ci_run

REPO = Path(__file__).resolve().parents[2]
HARNESS = REPO / "fuzz" / "python" / "fuzz_damper_specs.py"
CORPUS = REPO / "fuzz" / "python" / "corpus_damper_specs"
sys.path.insert(0, str(HARNESS.parent))


def test_the_corpus_strings_each_give_a_damper_or_a_one_line_error(tmp_path, monkeypatch):
    import fuzz_damper_specs as h

    monkeypatch.setenv("DAMPNET_FUZZ_WORK", str(tmp_path / "w"))
    (tmp_path / "w").mkdir()
    monkeypatch.chdir(h.make_workdir())
    for p in sorted(CORPUS.iterdir()):
        h.test_one_input(p.read_bytes())
    # the string is an error naming the field, not a damper that runs away
    from dampnet.sim.vehicle import LoopError

    with pytest.raises(LoopError, match=r"'linear:-1000': expected linear:C with C the damping coefficient"):
        h.load_spec("linear:-1000")
    with pytest.raises(LoopError, match=r"MODEL 'linear:1\\n2': expected a model directory"):
        h.load_spec("linear:1\n2")   # a control character: no path, no field; said in one line


def test_atheris_ci_run_over_the_damper_specs(tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    atheris_ci_run(HARNESS, CORPUS, tmp_path, runs=3000, max_len=256, env={"DAMPNET_FUZZ_WORK": str(work)})
