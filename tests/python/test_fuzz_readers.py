"""The CI-sized run of the atheris harness over the Python readers (fuzz/python/): the fixed
seed corpus in the repository plus a few thousand mutations with a fixed seed, no exception
other than the project's own errors, no input slower than 10 s. The long run (>= 1e7
executions where the machine allows) is recorded in fuzz/python/README.md."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path


REPO = Path(__file__).resolve().parents[2]
HARNESS = REPO / "fuzz" / "python" / "fuzz_readers.py"
CORPUS = REPO / "fuzz" / "python" / "corpus"


def test_seed_corpus_covers_every_reader():
    targets = {p.read_bytes()[0] % 5 for p in CORPUS.iterdir()}
    assert targets == {0, 1, 2, 3, 4}


def test_atheris_ci_run_over_the_readers(tmp_path):
    corpus = tmp_path / "corpus"
    shutil.copytree(CORPUS, corpus)  # libFuzzer adds what it finds to the first corpus directory
    proc = subprocess.run(
        [sys.executable, str(HARNESS), str(corpus), "-runs=4000", "-seed=1", "-max_len=4096",
         "-timeout=10", f"-artifact_prefix={tmp_path}/", "-print_final_stats=1"],
        capture_output=True, text=True, timeout=600, cwd=tmp_path)
    tail = "\n".join(proc.stderr.splitlines()[-30:])
    assert proc.returncode == 0, tail
    assert "Done 4000 runs" in proc.stderr, tail
    assert not list(tmp_path.glob("crash-*")) and not list(tmp_path.glob("timeout-*"))


# -- the envelope reader (fuzz/python/fuzz_envelope.py) -------------------------------------------

ENVELOPE_HARNESS = REPO / "fuzz" / "python" / "fuzz_envelope.py"
ENVELOPE_CORPUS = REPO / "fuzz" / "python" / "corpus_envelope"


def test_envelope_seed_corpus_covers_every_target():
    assert {p.read_bytes()[0] % 3 for p in ENVELOPE_CORPUS.iterdir()} == {0, 1, 2}


def test_atheris_ci_run_over_the_envelope_reader(tmp_path):
    """npz bytes, json bytes and fuzzed arrays: an envelope that every user of one accepts, or the
    reader's one-line EnvelopeError; load_envelope never raises."""
    corpus = tmp_path / "corpus"
    shutil.copytree(ENVELOPE_CORPUS, corpus)
    proc = subprocess.run(
        [sys.executable, str(ENVELOPE_HARNESS), str(corpus), "-runs=3000", "-seed=1", "-max_len=8192",
         "-timeout=10", f"-artifact_prefix={tmp_path}/", "-print_final_stats=1"],
        capture_output=True, text=True, timeout=600, cwd=tmp_path)
    tail = "\n".join(proc.stderr.splitlines()[-30:])
    assert proc.returncode == 0, tail
    assert "Done 3000 runs" in proc.stderr, tail
    assert not list(tmp_path.glob("crash-*")) and not list(tmp_path.glob("timeout-*"))
