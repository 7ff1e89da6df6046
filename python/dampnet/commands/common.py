"""What several commands share: the one-line error, JSON options, loading a dataset by name."""

from __future__ import annotations

import json
import sys

#: names `load_data` resolves to the bundled real measurements (dampnet.data.real)
REAL_DATASETS = ("utfsm", "labcontrol", "utfsm_mr_damper_mts", "labcontrol_mr_damper")


def error(msg: str) -> int:
    """Print the CLI's bad-input line (`dampnet: error: ...`) and return its exit status, 2."""
    print(f"dampnet: error: {msg}", file=sys.stderr)
    return 2


def json_arg(text: str | None, name: str, kind: type):
    """The JSON value of option --`name` (None if not given); ValueError unless it is a `kind`."""
    if text is None:
        return None
    try:
        v = json.loads(text)
    except json.JSONDecodeError as e:
        raise ValueError(f"--{name}: not valid JSON ({e.msg} at column {e.colno})") from None
    if not isinstance(v, kind):
        raise ValueError(f"--{name}: expected a JSON {kind.__name__}")
    return v


def read_json_file(path: str, what: str) -> dict:
    """A JSON object from file `path`; ValueError naming the file, the line and what was expected."""
    try:
        with open(path, encoding="utf-8") as f:
            v = json.load(f)
    except json.JSONDecodeError as e:
        raise ValueError(f"{path}: not valid JSON ({e.msg} at line {e.lineno}, column {e.colno}); "
                         f"expected {what}") from None
    except OSError as e:
        raise ValueError(f"{path}: cannot read {what} ({e.strerror or e})") from None
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a UTF-8 text file; expected {what}") from None
    if not isinstance(v, dict):
        raise ValueError(f"{path}: expected {what} (a JSON object), got a JSON {type(v).__name__}")
    return v


#: what DATA may be, for the commands' help texts
DATA_HELP = ("a dataset directory, a CSV/text or .mat file, or lab files (TDMS .tdms, MDF .mf4/.mdf, RPC III "
             ".rsp/.drv, or a folder of them, with a channel map: dampnet-channels.toml beside them or --channel-map)")


def add_channel_map_option(p) -> None:
    """--channel-map TOML: which channel of a lab file is which (dampnet.data.lab.channelmap)."""
    p.add_argument("--channel-map", default=None, metavar="TOML",
                   help="for lab files (TDMS, MDF, RPC III): the channel map saying which channel is displacement, "
                        "velocity, force, control, temperature, their units where the file has none and the sign "
                        "conventions (default: dampnet-channels.toml beside the data; docs/data-formats.md)")


def load_data(path: str, channel_map: str | None = None):
    """A dataset from a path (directory, CSV/text, .mat or lab file, a folder of lab files) or a
    bundled real dataset's name; `channel_map` a TOML file for lab files (None: the one beside them)."""
    from dampnet.data import load_dataset
    from dampnet.data.real import load_real

    if path in REAL_DATASETS:
        return load_real(path)
    return load_dataset(path, **({"channel_map": channel_map} if channel_map is not None else {}))


def load_all(paths: list[str], channel_map: str | None = None):
    """The datasets of several DATA arguments merged into one. `channel_map` goes to those that take
    one (lab files, folders of lab files: dampnet.data.takes_channel_map), not to dataset directories,
    text files or bundled datasets trained on beside them; DataError if none of them takes it."""
    from dampnet.data import DataError, merge_datasets, takes_channel_map

    if channel_map is None:
        return merge_datasets([load_data(p) for p in paths])
    takes = [p not in REAL_DATASETS and takes_channel_map(p) for p in paths]
    if not any(takes):
        raise DataError(f"--channel-map {channel_map}: applies to lab files (TDMS, MDF, RPC III) or folders of "
                        f"them, and no DATA argument is one ({', '.join(paths)})")
    return merge_datasets([load_data(p, channel_map if t else None) for p, t in zip(paths, takes)])


def add_data_fix_options(p) -> None:
    """The data fixes of dampnet.data.artefacts a command can apply to its data after loading."""
    p.add_argument("--align-force-s", type=float, default=None, metavar="SECONDS",
                   help="move the force channel SECONDS earlier against the motion channels (undo a force "
                        "recorded late: the time_offset artefact `dampnet diagnose` estimates); the data "
                        "files are not changed")
    p.add_argument("--run-order-drift-pct", type=float, default=None, metavar="PERCENT",
                   help="the force drifts by PERCENT %% from the first test to the last in the data's (run) order "
                        "(the run_order_drift artefact `dampnet diagnose` estimates): each test's force is "
                        "rescaled to the first test's condition; the data files are not changed")


def apply_data_fixes(ds, args):
    """`ds` with the data fixes the options ask for (a new Dataset; files untouched)."""
    from dampnet.data.artefacts import align_force, remove_run_order_drift

    if getattr(args, "align_force_s", None):
        ds = align_force(ds, args.align_force_s)
    if getattr(args, "run_order_drift_pct", None):
        ds = remove_run_order_drift(ds, args.run_order_drift_pct)
    return ds
