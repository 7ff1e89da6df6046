"""schema.parse_toml without a TOML parser (Python < 3.11 without tomli): the caller's error with the
extra to install, not an ImportError traceback."""

import sys

import pytest

from dampnet.data import DataError
from dampnet.schema import parse_toml


def test_parse_toml_without_a_parser_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "tomllib", None)    # as on Python 3.10
    monkeypatch.setitem(sys.modules, "tomli", None)      # and tomli not installed
    with pytest.raises(DataError, match=r"m\.toml: .*needs the package tomli: pip install 'dampnet\[lab\]'"):
        parse_toml("a = 1\n", "m.toml", DataError)


def test_parse_toml_reads_toml():
    assert parse_toml("[channels]\nforce = 'F'\n", "m.toml", DataError) == {"channels": {"force": "F"}}
