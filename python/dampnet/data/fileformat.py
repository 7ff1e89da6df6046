"""The dampnet dataset directory: manifest.csv plus one CSV per test (read and write).

  manifest.csv: test_id,file,frequency_hz,amplitude_m,voltage_v   (or current_a)
                [,run_order | ,started: the order the tests were run in, dampnet.data.runorder]
  <file>.csv:   time_s,displacement_m,velocity_m_s,force_n,voltage_v[,temperature_c,...]

SI units; displacement and velocity positive in extension, force positive when
the damper resists extension. frequency_hz/amplitude_m may be 0 or empty for
tests that are not sines. Any further test columns are kept as channels named
as in the file (known SI columns such as temperature_c map to their channel).
"""

from __future__ import annotations

import csv
import io
import os
from pathlib import Path

import numpy as np

from dampnet.data.table import read_table, safe_name
from dampnet.schema import (expect_number_map, expect_object, expect_string, expect_strings, load_json,
                            read_text, show)
from dampnet.data.types import (COLUMN_CHANNELS, CONTROL_NAMES, FILE_COLUMNS, RIG_GENERATOR, DataError, Dataset,
                                DynoTest)
from dampnet.data.validate import check_test

MANIFEST = "manifest.csv"
META_FILE = "meta.json"
MANIFEST_COLUMNS = ("test_id", "file", "frequency_hz", "amplitude_m")

#: printf formats per known column: resolution of the written file
#: (time 0.1 us, displacement 0.1 um, velocity 1 um/s, force 1 mN, control 0.1 mV / 0.1 uA, 1 mdegC).
COLUMN_FORMATS = {
    "time_s": "%.7f", "displacement_m": "%.7f", "velocity_m_s": "%.6f", "force_n": "%.3f",
    "voltage_v": "%.4f", "current_a": "%.7f", "temperature_c": "%.3f", "acceleration_m_s2": "%.5f",
}
DEFAULT_FORMAT = "%.10g"


def is_dataset_dir(path: Path) -> bool:
    return Path(path).is_dir() and (Path(path) / MANIFEST).is_file()


def _opt_float(cell: str, where: str, col: str) -> float | None:
    cell = cell.strip()
    if cell == "":
        return None
    try:
        v = float(cell)
    except ValueError:
        raise DataError(f"{where}, column {col!r}: expected a number or empty, got {show(cell)}") from None
    if not np.isfinite(v):
        raise DataError(f"{where}, column {col!r}: expected a finite number, got {show(cell)}")
    return v


def _manifest_rows(mpath: Path) -> list[tuple[int, list[str]]]:
    """(line number, cells) of each row of manifest.csv; DataError for text that is not CSV."""
    text = read_text(mpath, DataError, "UTF-8 CSV")
    reader = csv.reader(io.StringIO(text, newline=""))
    rows, start = [], 1  # the line a row starts on (a quoted cell may span lines)
    try:
        for row in reader:
            rows.append((start, row))
            start = reader.line_num + 1
    except csv.Error as e:  # e.g. a field longer than csv.field_size_limit(), a NUL byte
        raise DataError(f"{mpath}: line {start}: not readable as CSV ({show(str(e))})") from None
    return rows


def test_file_path(root: Path, name: str, where: str) -> Path:
    """The test file `name` of the manifest, resolved inside the dataset directory `root`.

    Absolute names, names that leave `root` ('../x') and symlinks pointing out of it are
    refused: a manifest must not make dampnet read (and echo) files elsewhere. The file
    itself is not opened here, so no message can carry its contents.
    """
    if not name:
        raise DataError(f"{where}, column 'file': expected a file name, got an empty cell")
    if "\x00" in name:
        raise DataError(f"{where}, column 'file': expected a file name, got one with a NUL byte")
    if Path(name).is_absolute():
        raise DataError(f"{where}, column 'file': absolute path {show(name)} refused: expected a file "
                        f"name relative to the dataset directory {root}")
    try:
        base = root.resolve()
        target = (root / name).resolve()
        inside = target.is_relative_to(base) and target != base
        exists = inside and target.is_file()
    except (OSError, RuntimeError, ValueError):  # a symlink loop, a name too long
        raise DataError(f"{where}, column 'file': {show(name)} cannot be resolved: expected a file "
                        f"in {root}") from None
    if not inside:
        raise DataError(f"{where}, column 'file': {show(name)} resolves outside the dataset directory "
                        f"{root}: refused, expected a file inside it")
    if not exists:
        raise DataError(f"{where}, column 'file': file {show(name)} not found in {root}")
    return target


def _extra(r: dict, where: str, ccol: str) -> dict:
    """The manifest's further columns of one row (into the test's meta); the run order's columns
    (dampnet.data.runorder: run_order a number, started a time stamp) checked and run_order parsed."""
    from dampnet.data.runorder import RUN_ORDER_COLUMN, STARTED_COLUMN, parse_started

    out = {k: v for k, v in r.items() if k not in (*MANIFEST_COLUMNS, ccol)}
    if RUN_ORDER_COLUMN in out:
        out[RUN_ORDER_COLUMN] = _opt_float(out[RUN_ORDER_COLUMN], where, RUN_ORDER_COLUMN)
    if out.get(STARTED_COLUMN, "").strip():
        try:
            parse_started(out[STARTED_COLUMN])
        except ValueError as e:
            raise DataError(f"{where}, column {STARTED_COLUMN!r}: {e}") from None
    return out


def read_manifest(root: Path) -> list[dict]:
    """Rows of manifest.csv as dicts; DataError naming the line of the first bad row."""
    mpath = root / MANIFEST
    rows = _manifest_rows(mpath)
    if not rows:
        raise DataError(f"{mpath}: empty: expected a header {','.join(MANIFEST_COLUMNS)},voltage_v")
    header = [h.strip() for h in rows[0][1]]
    missing = [c for c in MANIFEST_COLUMNS if c not in header]
    if missing:
        raise DataError(f"{mpath}: line 1: missing column(s) {', '.join(missing)}: expected "
                        f"{','.join(MANIFEST_COLUMNS)},voltage_v (or current_a)")
    if len(set(header)) != len(header):
        dup = next(h for h in header if header.count(h) > 1)
        raise DataError(f"{mpath}: line 1: duplicated column {show(dup)}")
    controls = [c for c in ("voltage_v", "current_a") if c in header]
    if len(controls) != 1:
        raise DataError(f"{mpath}: line 1: expected exactly one of the columns voltage_v or current_a, "
                        f"got {' and '.join(controls) or 'neither'}")
    ccol = controls[0]
    out, seen = [], set()
    for i, row in rows[1:]:
        if not any(c.strip() for c in row):
            continue
        where = f"{mpath}: line {i}"
        if len(row) != len(header):
            raise DataError(f"{where}: expected {len(header)} columns, got {len(row)}")
        r = dict(zip(header, (c.strip() for c in row)))
        if not r["test_id"]:
            raise DataError(f"{where}, column 'test_id': expected a test id, got an empty cell")
        if r["test_id"] in seen:
            raise DataError(f"{where}, column 'test_id': duplicated test id {show(r['test_id'])}")
        seen.add(r["test_id"])
        fpath = test_file_path(root, r["file"], where)
        out.append({
            "test_id": r["test_id"], "file": fpath,
            "frequency_hz": _opt_float(r["frequency_hz"], where, "frequency_hz"),
            "amplitude_m": _opt_float(r["amplitude_m"], where, "amplitude_m"),
            "control_name": "voltage" if ccol == "voltage_v" else "current",
            "control_nominal": _opt_float(r[ccol], where, ccol),
            "extra": _extra(r, where, ccol),
        })
    if not out:
        raise DataError(f"{mpath}: no tests: expected one row per test after the header")
    return out


def read_meta(path: Path) -> dict:
    """meta.json of a dataset: a JSON object; the fields dampnet uses checked for shape."""
    meta = expect_object(load_json(path, DataError), str(path), DataError)
    if "generator" in meta:
        expect_string(meta["generator"], f"{path}: field 'generator'", DataError)
    for key in ("noise", "resolution"):
        if key in meta:
            expect_number_map(meta[key], f"{path}: field {key!r}", DataError)
    if meta.get("generator") == RIG_GENERATOR and "force_n" not in meta.get("noise", {}):
        raise DataError(f"{path}: field 'noise': expected the rig's force_n [N]")
    if "effects" in meta and not isinstance(meta["effects"], (dict, list)):
        raise DataError(f"{path}: field 'effects': expected an object or a list of effect names, "
                        f"got {show(meta['effects'])}")
    if "effects" in meta:
        expect_strings(list(meta["effects"]), f"{path}: field 'effects'", DataError)
    if "plan" in meta:
        plan = expect_object(meta["plan"], f"{path}: field 'plan'", DataError)
        if "name" in plan:
            expect_string(plan["name"], f"{path}: field 'plan.name'", DataError)
    return meta


def read_test_file(path: Path, test_id: str, control_name: str) -> DynoTest:
    """One test CSV in the dataset format (SI columns named as in FILE_COLUMNS)."""
    names, data, lines = read_table(path)
    if "time_s" not in names:
        raise DataError(f"{path}: line 1: missing column 'time_s': expected columns "
                        f"time_s,displacement_m,velocity_m_s,force_n,{FILE_COLUMNS[control_name]}")
    if len(set(names)) != len(names):
        dup = [n for n in names if names.count(n) > 1][0]
        raise DataError(f"{path}: line 1: duplicated column {show(dup)}")
    need = ["displacement_m", "velocity_m_s", "force_n", FILE_COLUMNS[control_name]]
    missing = [c for c in need if c not in names]
    if missing:
        raise DataError(f"{path}: line 1: missing column(s) {', '.join(missing)}: expected "
                        f"time_s,{','.join(need)}")
    other_control = FILE_COLUMNS["current" if control_name == "voltage" else "voltage"]
    channels, colnames = {}, {}
    for j, n in enumerate(names):
        if n == "time_s":
            continue
        if n == other_control:
            raise DataError(f"{path}: line 1, column {n!r}: the manifest says the control is "
                            f"{FILE_COLUMNS[control_name]}, expected that column instead")
        ch = COLUMN_CHANNELS.get(n, n)
        if not safe_name(n):
            raise DataError(f"{path}: line 1, column {show(n)}: expected a column name of letters, digits, "
                            "'_', '.', '-'")
        channels[ch] = data[:, j].copy()
        colnames[ch] = n
    colnames["time"] = "time_s"
    test = DynoTest(test_id=test_id, time=data[:, names.index("time_s")].copy(), channels=channels,
                    control_name=control_name)
    return check_test(test, str(path), lines=lines, column_names=colnames)


def read_dataset_dir(root: str | os.PathLike) -> Dataset:
    """Load a dataset directory (manifest.csv + test CSVs); DataError on any problem."""
    root = Path(root)
    tests = []
    for r in read_manifest(root):
        t = read_test_file(r["file"], r["test_id"], r["control_name"])
        t.frequency_hz = r["frequency_hz"]
        t.amplitude_m = r["amplitude_m"]
        t.control_nominal = r["control_nominal"]
        t.meta.update(r["extra"])
        tests.append(t)
    mfile = root / META_FILE
    meta = read_meta(mfile) if mfile.exists() else {}
    return Dataset(tests=tests, source=str(root), meta=meta)


def _column_for(channel: str) -> str:
    return FILE_COLUMNS.get(channel, channel)


def format_test(test: DynoTest) -> str:
    """The CSV text of one test in the dataset format."""
    order = ["displacement", "velocity", "force", test.control_name]
    order += [c for c in test.channels if c not in order]
    cols = ["time_s"] + [_column_for(c) for c in order]
    data = np.column_stack([test.time] + [test.channels[c] for c in order])
    buf = io.StringIO()
    buf.write(",".join(cols) + "\n")
    np.savetxt(buf, data, fmt=[COLUMN_FORMATS.get(c, DEFAULT_FORMAT) for c in cols], delimiter=",")
    return buf.getvalue()


def _num(v: float | None) -> str:
    return "" if v is None else repr(float(v))


def write_dataset(ds: Dataset, out_dir: str | os.PathLike, overwrite: bool = False,
                  progress: bool = False, inputs=(), extras=None) -> Path:
    """Write `ds` as a dataset directory, atomically; refuse to replace an existing one.

    The directory is built in a staging directory beside `out_dir` and swapped into
    place (`dampnet.outputs`), so a reader never sees a half-written dataset and a
    kill leaves the old or the new one. With `overwrite`, only a dataset dampnet wrote
    (manifest.csv + meta.json naming a dampnet generator) that is not one of `inputs`,
    `.` or a parent is replaced. Values are written at the resolutions of
    COLUMN_FORMATS. `meta` goes to meta.json. `extras` ({file name: writer(path)}) are further
    files written into the same staged directory (e.g. the RPC III copies of replay tests).
    """
    from dampnet.outputs import check_output_dir, json_text, staged_dir

    out = check_output_dir(out_dir, "dataset", inputs, overwrite)
    if not ds.tests:
        raise DataError("write_dataset: the dataset has no tests: expected at least one")
    controls = {t.control_name for t in ds.tests}
    if len(controls) != 1 or not controls <= set(CONTROL_NAMES):
        raise DataError(f"write_dataset: expected one control kind (voltage or current) for all tests, got {sorted(controls)}")
    ccol = FILE_COLUMNS[controls.pop()]
    ids = [t.test_id for t in ds.tests]
    for tid in ids:
        if not safe_name(tid):
            raise DataError(f"write_dataset: test id {show(tid)}: expected letters, digits, '_', '.', '-'")
    if len(set(ids)) != len(ids):
        raise DataError("write_dataset: duplicated test ids")
    # the run order, when every test states it (dampnet.data.runorder), is kept
    from dampnet.data.runorder import RUN_ORDER_COLUMN, STARTED_COLUMN

    stated = [k for k in (RUN_ORDER_COLUMN, STARTED_COLUMN)
              if all(t.meta.get(k) not in (None, "") for t in ds.tests)]
    rows = [",".join(("test_id", "file", "frequency_hz", "amplitude_m", ccol, *stated))]
    for t in ds.tests:
        check_test(t, f"test {t.test_id}")
        order = [(f"{int(float(t.meta[k]))}" if float(t.meta[k]).is_integer() else _num(t.meta[k]))
                 if k == RUN_ORDER_COLUMN else str(t.meta[k]) for k in stated]
        rows.append(",".join((t.test_id, f"{t.test_id}.csv", _num(t.frequency_hz), _num(t.amplitude_m),
                              _num(t.control_nominal), *order)))
    with staged_dir(out) as tmp:
        _write_tests(ds.tests, tmp, progress)
        (tmp / MANIFEST).write_text("\n".join(rows) + "\n")
        (tmp / META_FILE).write_text(json_text(ds.meta, default=str))
        for name, write in (extras or {}).items():
            write(tmp / name)
    return out


def _write_one(args) -> None:
    test, path = args
    Path(path).write_text(format_test(test))


def _write_tests(tests, tmp: Path, progress: bool) -> None:
    """Format and write the test files (with a progress bar if asked)."""
    it = tests
    if progress:
        from tqdm import tqdm
        it = tqdm(it, desc="write", unit="test")
    for t in it:
        _write_one((t, tmp / f"{t.test_id}.csv"))
