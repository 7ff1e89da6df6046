"""The CI-sized run of the atheris harness over the Python readers (fuzz/python/): the fixed
seed corpus in the repository plus a few thousand mutations with a fixed seed, no exception
other than the project's own errors, no input slower than 10 s. The long run (>= 1e7
executions where the machine allows) is recorded in fuzz/python/README.md."""

from __future__ import annotations

from pathlib import Path

from atheris_run import atheris_ci_run


REPO = Path(__file__).resolve().parents[2]
HARNESS = REPO / "fuzz" / "python" / "fuzz_readers.py"
CORPUS = REPO / "fuzz" / "python" / "corpus"


def test_seed_corpus_covers_every_reader():
    targets = {p.read_bytes()[0] % 5 for p in CORPUS.iterdir()}
    assert targets == {0, 1, 2, 3, 4}


def test_atheris_ci_run_over_the_readers(tmp_path):
    atheris_ci_run(HARNESS, CORPUS, tmp_path, runs=4000, max_len=4096)


# -- the envelope reader (fuzz/python/fuzz_envelope.py) -------------------------------------------

ENVELOPE_HARNESS = REPO / "fuzz" / "python" / "fuzz_envelope.py"
ENVELOPE_CORPUS = REPO / "fuzz" / "python" / "corpus_envelope"


def test_envelope_seed_corpus_covers_every_target():
    assert {p.read_bytes()[0] % 3 for p in ENVELOPE_CORPUS.iterdir()} == {0, 1, 2}


def test_atheris_ci_run_over_the_envelope_reader(tmp_path):
    """npz bytes, json bytes and fuzzed arrays: an envelope that every user of one accepts, or the
    reader's one-line EnvelopeError; load_envelope never raises."""
    atheris_ci_run(ENVELOPE_HARNESS, ENVELOPE_CORPUS, tmp_path, runs=3000, max_len=8192)


# -- the lab-file readers (fuzz/python/fuzz_lab.py: TDMS, MDF, RPC III, the channel map) ----------

LAB_HARNESS = REPO / "fuzz" / "python" / "fuzz_lab.py"
LAB_CORPUS = REPO / "fuzz" / "python" / "corpus_lab"


def test_lab_seed_corpus_covers_every_target():
    assert {p.read_bytes()[0] % 4 for p in LAB_CORPUS.iterdir()} == {0, 1, 2, 3}


def test_atheris_ci_run_over_the_lab_readers(tmp_path):
    """Mutated TDMS, MDF4 and RPC III files and channel maps: checked tests or one-line DataErrors
    (each library reads in a child process, about 50 inputs a second)."""
    atheris_ci_run(LAB_HARNESS, LAB_CORPUS, tmp_path, runs=300, max_len=16384)
