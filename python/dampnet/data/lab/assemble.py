"""A lab file's raw channels + the channel map -> checked DynoTests in SI units; a folder -> a Dataset.

Steps, each with a one-line DataError naming the file and the channel:
  1. pick the mapped channels (by 'group/name' or name; without a map, by their names' words).
     A TDMS file whose groups each hold the mapped channels (LabVIEW's one group per run) gives
     one test per group, named <file stem>_<group>.
  2. units: the file's own (TDMS unit_string, MDF channel unit, RPC UNITS.CHAN_n), else the
     map's [units]; converted to SI (dampnet.data.units).
  3. no NaN or infinite sample in a channel used.
  4. one time base. Channels on the same time base must have equal lengths. Channels on
     different time bases (MDF channel groups at different rates, TDMS channels of different
     wf_increment) are resampled onto the FORCE channel's time stamps, over the span every
     channel covers, by linear interpolation (numpy.interp): the measured force is never
     interpolated, the motion and control channels are (they are smooth where the force is not).
  5. signs (the map's [convention]), control (a channel, or a constant), velocity
     differentiated from displacement when not recorded (a zero-phase 50 Hz low-pass, 4th-order
     differences, 50 ms cut at each end: dampnet.data.derivative; test.meta["velocity"] and the
     dataset's meta["velocity_derived"] say so); then the usual checks (check_test).
The derived manifest: the nominal control is the control channel's median rounded to 10 mV
(1 mA), so tests group by level (and the 2.25 V hold-out finds them), or none when the channel
varies (NOMINAL_SPREAD: a control law's command, stepped levels); a test whose displacement is a sine (dampnet.data.excitation) gets its
frequency and amplitude; any other (a replayed road, random) none: random content.
"""

from __future__ import annotations

import os
import re
from typing import Any
from pathlib import Path

import numpy as np

from dampnet.data.excitation import sine_or_none
from dampnet.data.lab.channelmap import MAP_CHANNELS, MAP_FILE, ChannelMap, resolve_channel_map
from dampnet.data.lab.raw import LAB_SUFFIXES, RawChannel, RawFile, is_lab_file, read_raw
from dampnet.data.testbuild import build_test, velocity_summary
from dampnet.data.types import CONTROL_NAMES, DT_RANGE_S, MIN_SAMPLES, DataError, Dataset, DynoTest
from dampnet.data.units import quantity_of_name, unit_to_si
from dampnet.schema import show

#: where each format keeps a channel's unit (for messages)
UNIT_FIELD = {"tdms": "unit_string property", "mdf": "channel unit", "rpc": "UNITS.CHAN_n header entry"}
#: decimals the nominal control (the median of a control channel) is rounded to: 10 mV, 1 mA
NOMINAL_DECIMALS = {"voltage": 2, "current": 3}
#: a control channel whose 1-99 % range is wider has no nominal level (a control law's command,
#: a stepped campaign): 0.1 V, 10 mA
NOMINAL_SPREAD = {"voltage": 0.1, "current": 0.01}
#: relative tolerance for two time bases to count as the same
SAME_TIME = 1e-9


def _auto_spec(raw: RawFile) -> dict[str, str]:
    """{dampnet channel: file channel name} from the names' words, when there is no map."""
    spec: dict[str, set[str]] = {}
    for c in raw.channels:
        q = quantity_of_name(c.name)
        if q in MAP_CHANNELS:
            spec.setdefault(q, set()).add(c.name)
    out = {}
    for q, names in spec.items():
        if len(names) > 1:
            raise DataError(f"{raw.path}: channels {', '.join(map(show, sorted(names)))} all look like {q}: "
                            f"expected a channel map ({_map_hint(raw)}) naming which one")
        out[q] = names.pop()
    return out


def _map_hint(raw: RawFile) -> str:
    return f"{MAP_FILE} beside the data, or --channel-map FILE"


def _available(raw: RawFile) -> str:
    labels = [c.label for c in raw.channels]
    text = ", ".join(map(show, labels[:20]))
    return text + (f" and {len(labels) - 20} more" if len(labels) > 20 else "")


def _select(raw: RawFile, spec: dict[str, str]) -> list[tuple[str | None, dict[str, RawChannel]]]:
    """[(group or None, {dampnet channel: raw channel})]: one entry per test in the file."""
    found: dict[str, list[RawChannel]] = {}
    for ch, want in spec.items():
        hits = [c for c in raw.channels if c.label == want] or [c for c in raw.channels if c.name == want]
        if not hits:
            raise DataError(f"{raw.path}: channel {show(want)} ({ch}) not found: expected one of {_available(raw)}")
        found[ch] = hits
    if all(len(h) == 1 for h in found.values()):
        return [(None, {ch: h[0] for ch, h in found.items()})]
    # a name in several groups: one test per group that holds every mapped channel (TDMS runs)
    groups = [g for g in raw.groups() if all(any(c.group == g for c in h) for h in found.values())]
    if len(groups) < 2 or any(len(h) > len(groups) for h in found.values()):
        ch, h = next((ch, h) for ch, h in found.items() if len(h) > 1)
        raise DataError(f"{raw.path}: channel {show(spec[ch])} ({ch}) is in groups "
                        f"{', '.join(show(c.group) for c in h)}: expected 'group/name' in the channel map")
    return [(g, {ch: next(c for c in h if c.group == g) for ch, h in found.items()}) for g in groups]


def _si(path: Path, fmt: str, ch: str, c: RawChannel, cmap: ChannelMap | None) -> np.ndarray:
    """The channel's samples in SI, from the file's unit or the map's; checked finite."""
    where = f"{path}: channel {show(c.label)} ({ch})"
    unit = c.unit.strip()
    mapped = (cmap.units.get(ch) if cmap else None)
    if not unit:
        if not mapped:
            raise DataError(f"{where}: no unit in the file ({UNIT_FIELD[fmt]}): expected one, or "
                            f"[units] {ch} = \"...\" in the channel map")
        unit = mapped
    elif mapped and unit_to_si(mapped, ch, f"{cmap.source}: [units] {ch}") != unit_to_si(unit, ch, where):
        raise DataError(f"{where}: the file says unit {show(unit)}, {cmap.source} says {show(mapped)}: "
                        "expected the same (the file's unit is used; drop the map's)")
    scale, offset = unit_to_si(unit, ch, where)
    bad = ~np.isfinite(c.data)
    if bad.any():
        k = int(np.argmax(bad))
        run = int(np.argmin(bad[k:])) if not bad[k:].all() else int(bad[k:].size)
        t = c.times()
        when = f" (t = {t[k]:.6g} s)" if t is not None and k < len(t) else ""
        raise DataError(f"{where}: sample {k}{when}: expected a finite number, got {show(float(c.data[k]))} "
                        f"({run} non-finite samples from there)")
    with np.errstate(all="ignore"):  # an overflow becomes inf, refused by check_test
        return c.data * scale + offset


def _time_base(path: Path, picked: dict[str, RawChannel], cols: dict[str, np.ndarray]
               ) -> tuple[np.ndarray, dict[str, np.ndarray], dict]:
    """(time [s], columns on it, note) — see the module doc, step 4."""
    if "time" in cols:
        t = cols.pop("time")
        for ch, x in cols.items():
            if x.shape != t.shape:
                raise DataError(f"{path}: channel {show(picked[ch].label)} ({ch}) has {x.size} samples, the time "
                                f"channel {show(picked['time'].label)} {t.size}: expected equal lengths")
        return t, cols, {}
    times = {}
    for ch in cols:
        dt = picked[ch].dt
        if picked[ch].time is None and dt is not None and not (
                np.isfinite(dt) and DT_RANGE_S[0] <= dt <= DT_RANGE_S[1] and np.isfinite(picked[ch].t0)):
            raise DataError(f"{path}: channel {show(picked[ch].label)} ({ch}): sample interval {show(float(dt))} s, "
                            f"start {show(float(picked[ch].t0))} s: expected a positive, finite interval from "
                            f"{DT_RANGE_S[0]:g} to {DT_RANGE_S[1]:g} s (TDMS wf_increment, RPC DELTA_T)")
        tc = picked[ch].times()
        if tc is None:
            raise DataError(f"{path}: channel {show(picked[ch].label)} ({ch}): no time base in the file "
                            "(no wf_increment): expected one, or [channels] time = \"...\" in the channel map")
        times[ch] = tc
    ref = times["force"]
    same_rate = all(picked[ch].time is None and picked[ch].dt is not None for ch in cols) and \
        len({round(picked[ch].dt / picked["force"].dt, 9) for ch in cols}) == 1 and \
        len({picked[ch].t0 for ch in cols}) == 1
    if same_rate or all(tc.shape == ref.shape and np.allclose(tc, ref, rtol=SAME_TIME, atol=0) for tc in times.values()):
        for ch, x in cols.items():
            if x.shape != cols["force"].shape:
                raise DataError(f"{path}: channel {show(picked[ch].label)} ({ch}) has {x.size} samples, "
                                f"{show(picked['force'].label)} (force) {cols['force'].size}: expected equal "
                                "lengths (the channels share one sample rate)")
        return ref, cols, {}
    for ch, tc in times.items():
        if tc.size < 2:   # an empty channel group was "time stamp 0 is not after the one before"
            raise DataError(f"{path}: channel {show(picked[ch].label)} ({ch}): {tc.size} samples: expected at "
                            "least 2 on its own time base (a slow channel is interpolated between its samples)")
        d = np.diff(tc)
        if not (d > 0).all():
            k = int(np.argmax(d <= 0)) + 1
            raise DataError(f"{path}: channel {show(picked[ch].label)} ({ch}): time stamp {k} is not after the one "
                            "before: expected strictly increasing time")
    lo = max(tc[0] for tc in times.values())
    hi = min(tc[-1] for tc in times.values())
    keep = (ref >= lo) & (ref <= hi)
    t = ref[keep]
    out = {ch: (x[keep] if ch == "force" else np.interp(t, times[ch], x)) for ch, x in cols.items()}
    rates = {picked[ch].label: float(1.0 / np.median(np.diff(tc))) for ch, tc in times.items()}
    note = {"resampled": {"onto": picked["force"].label, "method": "linear interpolation (numpy.interp)",
                          "span_s": [float(lo), float(hi)], "rates_hz": rates}}
    return t, out, note


def _check_time(path: Path, label: str, t: np.ndarray) -> None:
    d = np.diff(t)
    if (d <= 0).any():
        k = int(np.argmax(d <= 0)) + 1
        raise DataError(f"{path}: channel {show(label)} (time): sample {k}: time {show(float(t[k]))} after "
                        f"{show(float(t[k - 1]))}: expected strictly increasing time")


_UNSAFE = re.compile(r"[^A-Za-z0-9_.\-]+")


def _test_id(path: Path, group: str | None) -> str:
    stem = path.name[: -len(path.suffix)] if path.suffix else path.name
    tid = stem if group is None else f"{stem}_{group}"
    return _UNSAFE.sub("_", tid).strip("_") or "test"


def read_lab_file(path: str | os.PathLike, channel_map=None, **options) -> list[DynoTest]:
    """The tests of one TDMS, MDF or RPC III file (one, or one per TDMS group holding the mapped
    channels). `channel_map`: a ChannelMap, dict, TOML path, or None (MAP_FILE beside the file,
    else the channel names). `options`: as dampnet.data.readers (voltage=, current=,
    motion_positive=, force_positive=, test_id=, frequency_hz=, amplitude_m=) win over the map."""
    path = Path(path)
    cmap = resolve_channel_map(path, channel_map)
    raw = read_raw(path)
    spec = dict(cmap.channels) if cmap and cmap.channels else _auto_spec(raw)
    for need in ("displacement", "force"):
        if need not in spec:
            raise DataError(f"{path}: no {need} channel: expected [channels] {need} = \"...\" in a channel map "
                            f"({_map_hint(raw)}); the file has {_available(raw)}")
    control = dict(cmap.control) if cmap else {}
    if not any(c in spec for c in CONTROL_NAMES) and not control and not any(
            options.get(c) is not None for c in CONTROL_NAMES):
        raise DataError(f"{path}: no control channel: expected [channels] voltage (or current) = \"...\", or "
                        f"[control] voltage = a constant [V], in a channel map ({_map_hint(raw)}); "
                        f"the file has {_available(raw)}")
    tests = []
    for group, picked in _select(raw, spec):
        cols = {ch: _si(path, raw.format, ch, c, cmap) for ch, c in picked.items()}
        t, cols, note = _time_base(path, picked, cols)
        if t.size < MIN_SAMPLES:   # before differentiating anything
            raise DataError(f"{path}: channel {show(picked['force'].label)} (force): {t.size} samples"
                            + (" in the span every channel covers" if note else "")
                            + f": expected at least {MIN_SAMPLES}")
        _check_time(path, picked.get("time", picked["force"]).label, t)
        colnames = {ch: picked[ch].label for ch in cols}
        colnames["time"] = picked["time"].label if "time" in picked else "(time base)"
        opts = dict(options)
        for k, v in control.items():
            opts.setdefault(k, v)
        if any(c in cols for c in CONTROL_NAMES):
            for c in CONTROL_NAMES:
                opts.pop(c, None)
        opts.setdefault("motion_positive", cmap.motion_positive if cmap else "extension")
        opts.setdefault("force_positive", cmap.force_positive if cmap else "extension")
        tid = opts.pop("test_id", None) or _test_id(path, group)
        meta = {"source_file": str(path), "format": raw.format, "channels": {ch: picked[ch].label for ch in picked},
                "units": {ch: (picked[ch].unit or (cmap.units.get(ch) if cmap else "")) for ch in picked},
                "channel_map": cmap.source if cmap else "(from the channel names)", **note}
        if group is not None:
            meta["group"] = group
        test = build_test(str(path), {"time": t, **cols}, colnames, header_lines=0, test_id=tid, meta=meta,
                          derive_velocity=True, **opts)
        if any(c in cols for c in CONTROL_NAMES):   # the level a test is grouped (and held out) by
            u = test.channels[test.control_name]
            lo, hi = np.percentile(u, [1, 99])
            steady = hi - lo <= NOMINAL_SPREAD[test.control_name]
            test.control_nominal = round(test.control_nominal, NOMINAL_DECIMALS[test.control_name]) if steady else None
        if test.frequency_hz is None:
            f, a = sine_or_none(test.channels["displacement"], test.dt)
            test.frequency_hz, test.amplitude_m = f, a
            test.meta["excitation"] = "random (not a sine)" if f is None else "sine (estimated from displacement)"
        tests.append(test)
    seen: dict[str, Any] = {}
    for t in tests:  # issue 49: TDMS groups 'a b' and 'a_b' both became x_a_b, read as two tests of one id
        if t.test_id in seen:
            raise DataError(f"{path}: groups {show(seen[t.test_id])} and {show(t.meta.get('group'))} both give the test "
                            f"id {show(t.test_id)}: expected one id per group (rename a group, or give no test_id=)")
        seen[t.test_id] = t.meta.get("group")
    return tests


def lab_files(folder: Path) -> list[Path]:
    """The lab files of a folder (not its sub-folders), sorted by name. A symbolic link that leaves
    the folder is refused, never opened (the dataset folder's rule, fileformat.test_file_path: a
    folder must not make dampnet read, and echo, files elsewhere; issue 49)."""
    base = Path(folder).resolve()
    out = []
    for p in Path(folder).iterdir():
        if not is_lab_file(p):
            continue
        if p.is_symlink():
            try:
                target = p.resolve()
                inside = target.is_relative_to(base) and target != base
            except (OSError, RuntimeError):  # a link loop
                inside = False
            if not inside:
                raise DataError(f"{p}: a symbolic link leaving the folder {folder}: refused, expected the folder's "
                                "own files (copy the file in)")
        if p.is_file():
            out.append(p)
    return sorted(out)


def read_lab_folder(folder: str | os.PathLike, channel_map=None, progress: bool = False, **options) -> Dataset:
    """A Dataset of every lab file in `folder`, with a derived manifest (nothing is written there)."""
    folder = Path(folder)
    files = lab_files(folder)
    if not files:
        raise DataError(f"{folder}: a directory without manifest.csv or lab files: expected a dataset directory "
                        f"(manifest.csv + one CSV per test) or files ending in {', '.join(LAB_SUFFIXES)}")
    if "test_id" in options:
        raise DataError(f"{folder}: test_id= names one test: the folder's tests are named by their files")
    cmap = resolve_channel_map(folder, channel_map)
    it = files
    if progress:
        from tqdm import tqdm
        it = tqdm(files, desc=f"read {folder.name}", unit="file")
    tests, seen = [], {}
    for f in it:
        for t in read_lab_file(f, cmap, **options):
            if t.test_id in seen:
                raise DataError(f"{f}: test id {show(t.test_id)} also from {seen[t.test_id]}: expected unique "
                                "file names (and groups)")
            seen[t.test_id] = f.name
            tests.append(t)
    meta = {"reader": "lab", "manifest": "derived (no manifest.csv: one test per file or TDMS group)",
            "channel_map": cmap.source if cmap else "(from the channel names)", "files": [f.name for f in files]}
    meta.update(velocity_summary(tests))
    return Dataset(tests=tests, source=str(folder), meta=meta)

