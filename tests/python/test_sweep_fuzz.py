"""The CI-sized run of the atheris harness over the sweep-spec reader (fuzz/python/fuzz_sweep_spec.py):
its seed specs plus a couple of thousand mutations with a fixed seed give cells or a one-line
SpecError, never another exception, and no input is slower than 10 s. Also the reader's own
refusals the fuzzing is about: TOML nested too deeply (a RecursionError in tomllib) and a
value or key too long to repeat whole."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import needs
from atheris_run import atheris_ci_run

needs.need_module("atheris")

from dampnet.sweep import SpecError, parse_spec  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
HARNESS = REPO / "fuzz" / "python" / "fuzz_sweep_spec.py"


def test_atheris_ci_run_over_the_sweep_spec_reader(tmp_path):
    seeds = tmp_path / "seeds"
    subprocess.run([sys.executable, str(HARNESS), "--write-seeds", str(seeds)], check=True, timeout=60)
    assert len(list(seeds.iterdir())) >= 7
    atheris_ci_run(HARNESS, seeds, tmp_path, runs=2000, max_len=2048)


@pytest.mark.parametrize("text, fragment", [
    ("a = " + "[" * 5000 + "]" * 5000, "nested too deeply"),
    ("[simulation]\nroads = ['impulse']\nspeeds = ['" + "v" * 5000 + "']\n",
     "simulation.speeds[0]: expected a number, got 'vvvv"),
    ("[simulation]\nroads = ['impulse']\n" + "k" * 5000 + " = 1\n", "simulation.kkkk"),
])
def test_the_reader_refuses_in_one_short_line(text, fragment):
    with pytest.raises(SpecError) as e:
        parse_spec(text, source="s.toml")
    msg = str(e.value)
    assert fragment in msg and "\n" not in msg and len(msg) < 1000, msg[:300]
