"""Readers: a dataset directory, a single text file with unit-bearing columns, a MATLAB .mat file.

`load_dataset(path, **options)` picks the reader from what `path` is:

  directory with manifest.csv     the dataset format (`dampnet.data.fileformat`)
  *.mat                           `read_mat`, needs `mapping` (variable -> channel)
  *.tdms, *.mf4/.mdf, *.rsp/.drv  lab files through their own libraries (dampnet.data.lab), with a
  (or a folder of them)           channel map (dampnet-channels.toml beside the data, or channel_map=)
  any other file                  `read_text`: CSV (',', ';', tab) or whitespace text
                                  whose header names carry units (force_lbf, mm/s, kN, ...)

Options common to single files (all SI after conversion):
  voltage=V or current=A    a constant control when the file has no control column
  dt=s                      the sample interval when the file has no time column
  motion_positive='extension'|'compression'  the rig's displacement/velocity sign
  force_positive='extension'|'compression'   'extension' = positive when resisting extension
  frequency_hz, amplitude_m, test_id         describe the test
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from dampnet.data.fileformat import is_dataset_dir, read_dataset_dir
from dampnet.data.matfile import NonNumeric
from dampnet.data.table import read_table
from dampnet.data.testbuild import apply_convention, build_test, velocity_summary  # noqa: F401  (apply_convention: its old home)
from dampnet.data.types import DataError, Dataset, DynoTest
from dampnet.data.units import parse_column
from dampnet.schema import read_text as read_text_file, show


def read_text(path: str | os.PathLike, *, skip_lines: int = 0, columns: list[str] | None = None,
              **options) -> DynoTest:
    """One test from a CSV or whitespace-separated text file with unit-bearing column names.

    `columns` names the columns (with units) of a file without a header row,
    e.g. ['time_s', 'x_mm', 'dx_mm_s', 'force_n']. See the module doc for options.
    """
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: file not found")
    names, data, lines = read_table(path, skip_lines=skip_lines, has_header=columns is None)
    if columns is not None:
        if len(columns) != data.shape[1]:
            raise DataError(f"{path}: columns= names {len(columns)} columns, the file has {data.shape[1]}")
        names = list(columns)
    header_where = f"{path}: line {_header_line(path, skip_lines)}" if columns is None else f"{path}: columns="
    chans, colnames = {}, {}
    for j, name in enumerate(names):
        ch, scale, offset = parse_column(name, where=header_where)
        if ch in chans:
            raise DataError(f"{path}: column {show(name)}: a second {ch} column (after "
                            f"{show(colnames[ch])}): expected one")
        with np.errstate(all="ignore"):  # an overflow becomes inf, which check_test refuses by line
            chans[ch] = data[:, j] * scale + offset
        colnames[ch] = name
    return build_test(str(path), chans, colnames, lines=lines, **options)


def _header_line(path: Path, skip_lines: int) -> int:
    """The file line of the header row (after skip_lines, blank and '#' lines)."""
    text = read_text_file(path, DataError)
    for i, line in enumerate(text.splitlines()[skip_lines:], start=skip_lines + 1):
        if line.strip() and not line.lstrip().startswith("#"):
            return i
    return skip_lines + 1


def _mat_variable(m: dict, ref: str, where: str) -> np.ndarray:
    """`name` or `name:col` (0-based column) of a loadmat dict, as a 1-D float array."""
    name, _, col = ref.partition(":")
    if name not in m:
        have = ", ".join(k for k in m if not k.startswith("__"))
        raise DataError(f"{where}: variable {show(name)} not found: expected one of {show(have)}")
    a = m[name]
    if isinstance(a, NonNumeric) or not np.issubdtype(a.dtype, np.number) or np.iscomplexobj(a):
        raise DataError(f"{where}: variable {show(name)}: expected real numbers, got {a.dtype}")
    a = a.astype(np.float64)
    if col:
        ok = col.isascii() and col.isdigit() and len(col) < 10
        if a.ndim != 2 or not ok or int(col) >= a.shape[1]:
            raise DataError(f"{where}: {show(ref)}: expected a column index below {a.shape[1] if a.ndim == 2 else 1} "
                            f"of the {a.shape} variable {show(name)}")
        return a[:, int(col)]
    if a.ndim == 2 and 1 in a.shape:
        return a.ravel()
    if a.ndim != 1:
        raise DataError(f"{where}: variable {show(name)} has shape {a.shape}: expected a vector, or name:col")
    return a


def read_mat(path: str | os.PathLike, mapping: dict[str, str] | None = None, **options) -> DynoTest:
    """One test from a MATLAB .mat file, `mapping` = {column name with unit: variable ref}.

    Example for the Labcontrol files: {'displacement_mm': 'x_F:0',
    'velocity_mm_s': 'x_F:1', 'force_n': 'x_F:2'}, with dt='Ts' (a variable
    name or a number [s]). Variable refs are 'name' or 'name:column' (0-based).
    """
    from dampnet.data.matfile import load_variables

    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: file not found")
    m = load_variables(path)  # in a child process: scipy's reader can crash on a malformed file
    if not mapping:
        raise DataError(f"{path}: expected mapping= from channel columns (e.g. 'force_n') to variables "
                        f"(e.g. 'x_F:2'); variables: {show(', '.join(k for k in m if not k.startswith('__')))}")
    chans, colnames = {}, {}
    for name, ref in mapping.items():
        ch, scale, offset = parse_column(name, where=f"{path}: mapping")
        with np.errstate(all="ignore"):  # an overflow becomes inf, which check_test refuses by line
            chans[ch] = _mat_variable(m, ref, str(path)) * scale + offset
        colnames[ch] = f"{ref} ({name})"
    lens = {k: len(v) for k, v in chans.items()}
    if len(set(lens.values())) != 1:
        raise DataError(f"{path}: mapped variables differ in length {lens}: expected equal lengths")
    dt = options.pop("dt", None)
    if isinstance(dt, str):
        v = _mat_variable(m, dt, str(path))
        if v.size < 1:
            raise DataError(f"{path}: dt variable {show(dt)} is empty: expected the sample interval [s]")
        dt = float(v[0])
    return build_test(str(path), chans, colnames, header_lines=0, dt=dt, **options)


def takes_channel_map(path: str | os.PathLike) -> bool:
    """Whether load_dataset(path) can take a channel map: a lab file (TDMS, MDF, RPC III) or a folder
    of them (not a dataset directory, a text or .mat file, or a path that does not exist)."""
    from dampnet.data.lab import is_lab_file

    p = Path(path)
    if p.is_dir():
        if is_dataset_dir(p):
            return False
        from dampnet.data.lab.assemble import lab_files

        return bool(lab_files(p))
    return p.is_file() and is_lab_file(p)


def load_dataset(path: str | os.PathLike, channel_map=None, **options) -> Dataset:
    """A Dataset from a dataset directory, a folder of lab files or a single file (format detected).

    Directories need manifest.csv, or hold lab files (TDMS, MDF, RPC III: dampnet.data.lab; a
    manifest is derived, nothing written). Lab files take `channel_map=` (a TOML path, a dict,
    a ChannelMap; default: dampnet-channels.toml beside the data). `.mat` files need
    `mapping=`; other files are text tables. A single file gives its test(s).
    """
    p = Path(path)
    if p.is_dir():
        if not is_dataset_dir(p):
            from dampnet.data.lab import LAB_SUFFIXES, read_lab_folder
            from dampnet.data.lab.assemble import lab_files

            if lab_files(p):
                return read_lab_folder(p, channel_map, **options)
            raise DataError(f"{p}: a directory without manifest.csv: expected a dataset directory "
                            f"(manifest.csv + one CSV per test), or lab files ({', '.join(LAB_SUFFIXES)})")
        if options or channel_map is not None:
            raise DataError(f"{p}: options {sorted(options) + (['channel_map'] if channel_map is not None else [])} "
                            "apply to single files and lab files, not dataset directories")
        return read_dataset_dir(p)
    if not p.exists():
        raise DataError(f"{p}: not found: expected a dataset directory or a data file")
    from dampnet.data.lab import is_lab_file, read_lab_file

    if is_lab_file(p):
        tests = read_lab_file(p, channel_map, **options)
        return Dataset(tests=tests, source=str(p), meta={"reader": "lab", **velocity_summary(tests)})
    if channel_map is not None:
        raise DataError(f"{p}: channel_map applies to lab files (TDMS, MDF, RPC III); for a text file name "
                        "the columns with their units, for a .mat file pass mapping=")
    if p.suffix.lower() == ".mat":
        test = read_mat(p, **options)
    else:
        test = read_text(p, **options)
    return Dataset(tests=[test], source=str(p), meta={"reader": "mat" if p.suffix.lower() == ".mat" else "text",
                                                      **velocity_summary([test])})
