"""Shape checks for what dampnet reads from files (model.json, meta.json, manifest cells).

Plain explicit checks rather than a validation library: the files have a dozen
fields of a few kinds (number, numeric array of a given rank, string, list of
strings, object), and every message must name the file and field in the
project's own error class (`DataError` for data, `ModelError` for models).
A checker takes that class as `error` so one module serves both.

Messages never echo more than `MAX_ECHO` characters of a value (`show`) and
never numpy reprs such as ``np.float64(1.0)``.
"""

from __future__ import annotations

import json
import math
import numbers
import os
import stat
from pathlib import Path
from typing import Any

import numpy as np

#: characters of a cell or value echoed in an error message
MAX_ECHO = 200
#: nesting depth allowed in a JSON file (model.json's deepest field, w1, has depth 3)
MAX_JSON_DEPTH = 32
#: the largest text file read (a dyno test's CSV of hours at kHz is under it; /dev/zero is not a file)
MAX_TEXT_BYTES = 1 << 30


def show(value: Any, limit: int = MAX_ECHO) -> str:
    """A short, plain repr of `value` for an error message (numbers as Python floats/ints)."""
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        value = value.item()
    if isinstance(value, str):
        text = repr(value[:limit])
        return text if len(value) <= limit else f"{text}... ({len(value)} characters)"
    if isinstance(value, (dict, list, tuple)):
        kind = type(value).__name__
        return f"a JSON {'object' if kind == 'dict' else 'list'} of {len(value)} items"
    text = repr(value)
    return text if len(text) <= limit else text[:limit] + "..."


def read_text(path: Path, error: type[Exception], what: str = "UTF-8 text", max_bytes: int = MAX_TEXT_BYTES) -> str:
    """The text of `path` (UTF-8, a leading BOM dropped); `error` naming the file otherwise.

    Only a regular file of at most `max_bytes` is read (issue 49: a channel map given as
    /dev/zero read until memory ran out, a FIFO blocked for ever): the file is opened without
    blocking and looked at before a byte is read."""
    fd = None
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):
            raise error(f"{path}: is a directory: expected a file")
        if not stat.S_ISREG(st.st_mode):
            raise error(f"{path}: is not a regular file (a device, FIFO or socket): expected a file")
        if st.st_size > max_bytes:
            raise error(f"{path}: {st.st_size:,} bytes, over the {max_bytes:,} this reader takes: expected {what}")
        with os.fdopen(fd, "rb") as f:
            fd = None
            data = f.read(max_bytes + 1)
        if len(data) > max_bytes:  # grew while being read
            raise error(f"{path}: over the {max_bytes:,} bytes this reader takes: expected {what}")
    except FileNotFoundError:
        raise error(f"{path}: file not found") from None
    except IsADirectoryError:
        raise error(f"{path}: is a directory: expected a file") from None
    except OSError as e:
        raise error(f"{path}: cannot be read ({e.strerror})") from None
    finally:
        if fd is not None:
            os.close(fd)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise error(f"{path}: byte {e.start}: not {what} ({e.reason})") from None


def load_json(path: Path, error: type[Exception]) -> Any:
    """The parsed JSON of `path`, nested at most MAX_JSON_DEPTH deep; `error` otherwise."""
    text = read_text(path, error, "UTF-8 JSON")
    if _max_depth(text) > MAX_JSON_DEPTH:
        raise error(f"{path}: nested deeper than {MAX_JSON_DEPTH} levels: expected a dampnet JSON file")
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise error(f"{path}: line {e.lineno}: not valid JSON ({e.msg})") from None
    except (ValueError, RecursionError) as e:  # e.g. an integer of more than 4300 digits
        raise error(f"{path}: not valid JSON ({show(str(e))})") from None


def parse_toml(text: str, source: str, error: type[Exception], what: str = "valid TOML") -> dict:
    """The parsed TOML `text` (from `source`, named in errors); `error` for text that is not
    TOML or nests too deep to read. tomllib, or on Python 3.10 the package tomli (the same
    parser; the sweep and lab extras install it)."""
    try:
        import tomllib
    except ModuleNotFoundError:
        try:
            import tomli as tomllib  # type: ignore[no-redef]
        except ImportError:
            raise error(f"{source}: reading TOML on Python < 3.11 needs the package tomli: pip install "
                        "'dampnet[lab]' (or 'dampnet[sweep]', which install it)") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise error(f"{source}: not {what} ({show(str(e))})") from None
    except RecursionError:
        raise error(f"{source}: arrays or tables nested too deeply: expected {what}") from None


def _max_depth(text: str) -> int:
    """Bracket depth of JSON text, ignoring brackets inside strings (an upper bound is enough)."""
    depth = deepest = 0
    in_str = escaped = False
    for ch in text:
        if in_str:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_str = False
        elif ch == '"':
            in_str = True
        elif ch in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif ch in "]}":
            depth -= 1
    return deepest


def expect_object(value: Any, where: str, error: type[Exception]) -> dict:
    if not isinstance(value, dict):
        raise error(f"{where}: expected a JSON object, got {_kind(value)}")
    return value


def expect_number(value: Any, where: str, error: type[Exception]) -> float:
    """A finite real number (JSON int or float, not a bool)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise error(f"{where}: expected a number, got {_kind(value)}")
    v = _to_float(value)
    if not math.isfinite(v):
        raise error(f"{where}: expected a finite number, got {show(v)}")
    return v


def expect_string(value: Any, where: str, error: type[Exception]) -> str:
    if not isinstance(value, str):
        raise error(f"{where}: expected a string, got {_kind(value)}")
    return value


def expect_strings(value: Any, where: str, error: type[Exception]) -> list[str]:
    if not isinstance(value, list):
        raise error(f"{where}: expected a list of strings, got {_kind(value)}")
    for i, s in enumerate(value):
        expect_string(s, f"{where}[{i}]", error)
    return list(value)


def expect_array(value: Any, ndim: int, where: str, error: type[Exception]) -> np.ndarray:
    """A float64 array of rank `ndim` from nested JSON lists of numbers (rectangular)."""
    shape_name = "a list of numbers" if ndim == 1 else "a list of equal-length lists of numbers"
    if not isinstance(value, list):
        raise error(f"{where}: expected {shape_name}, got {_kind(value)}")
    if ndim == 1:
        for i, v in enumerate(value):
            if isinstance(v, bool) or not isinstance(v, numbers.Real):
                raise error(f"{where}[{i}]: expected a number, got {_kind(v)}")
        return np.array([_to_float(v) for v in value], dtype=np.float64)
    rows = [expect_array(r, ndim - 1, f"{where}[{i}]", error) for i, r in enumerate(value)]
    if len({r.shape for r in rows}) > 1:
        raise error(f"{where}: expected {shape_name}, got rows of different lengths")
    if not rows:
        return np.zeros((0,) * ndim)
    return np.stack(rows)


def expect_number_map(value: Any, where: str, error: type[Exception]) -> dict[str, float]:
    """A JSON object of finite numbers."""
    obj = expect_object(value, where, error)
    return {k: expect_number(v, f"{where}[{show(k)}]", error) for k, v in obj.items()}


def _to_float(value: numbers.Real) -> float:
    """float(value), with an integer too large for a float as inf (not OverflowError)."""
    try:
        return float(value)
    except OverflowError:
        return math.inf if value > 0 else -math.inf


def _kind(value: Any) -> str:
    """What a JSON value is, for 'expected X, got Y' (with the value when it is short)."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return f"a boolean ({'true' if value else 'false'})"
    if isinstance(value, numbers.Real):
        return f"a number ({show(value)})"
    if isinstance(value, str):
        return f"a string ({show(value)})"
    if isinstance(value, list):
        return f"a list of {len(value)} items"
    if isinstance(value, dict):
        return f"an object of {len(value)} fields"
    return type(value).__name__
