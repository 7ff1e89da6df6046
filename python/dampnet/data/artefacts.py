"""The catalogue of measurement artefacts: what the recording did to the data, not what the damper does.

The effect catalogue (dampnet.effects) lists physics a model should learn. An artefact is a
fault of the acquisition (a channel recorded late, a sign or unit slipped in one channel, a sensor
zero that moved, a drift over the run order that no logged channel explains): a model must not
learn it, the data must be fixed. Each entry says how the diagnosis tests for it
(dampnet.diagnosis.artefacts), which physical effect it would otherwise be mistaken for, and the
data fix; the fixes are here (they return a new Dataset and never touch the files) and every front
end (dampnet train / evaluate / diagnose --align-force-s / --run-order-drift-pct, the Python
API) calls them.

    time_offset      a channel recorded late (force vs the motion channels); fix: realign
    run_order_drift  the force drifts along the run order, no channel explains it; fix: a run-order
                     term (each test's force rescaled to the first test's), better: log temperature
    sign_slip        one channel's sign flipped in some tests; fix: flip it back
    unit_slip        one channel in another unit in some tests (mm, lbf); fix: rescale
    sensor_offset    a channel's zero moved in some tests; fix: subtract the offset

The rig (dampnet.rig.sensors.record_artefact) can put each into its data, so the tests can check
that the diagnosis names the artefact, never a physical effect.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dampnet.data import Dataset, DataError


@dataclass(frozen=True)
class ArtefactInfo:
    id: str
    title: str
    what: str           # what it does to the data
    mistaken_for: str   # the physical effect (catalogue id) it looks like, "" if none
    fix: str            # the data fix, in words (a command option where dampnet applies it)


ARTEFACTS: dict[str, ArtefactInfo] = {}


def register_artefact(info: ArtefactInfo) -> ArtefactInfo:
    """Add (or replace) an artefact of the catalogue."""
    ARTEFACTS[info.id] = info
    return info


def artefact(artefact_id: str) -> ArtefactInfo:
    """The catalogue entry of `artefact_id`; ValueError listing the known ids."""
    try:
        return ARTEFACTS[artefact_id]
    except (KeyError, TypeError):
        raise ValueError(f"unknown artefact {artefact_id!r}: expected one of {', '.join(sorted(ARTEFACTS))}") from None


register_artefact(ArtefactInfo(
    id="time_offset", title="force channel recorded late (time offset between channels)",
    what="the acquisition chain (a filter, a second DAQ, a buffered load-cell amplifier) records the force "
         "some milliseconds after the motion it belongs to: every force feature, including the seal "
         "friction's flip at velocity reversals, arrives late by the same time",
    mistaken_for="compressibility",
    fix="realign the channels: `--align-force-s SECONDS` (dampnet train, evaluate, diagnose) moves the "
        "force earlier by the estimated offset; a model must not learn the delay as an oil lag"))

register_artefact(ArtefactInfo(
    id="run_order_drift", title="force drifting along the run order (no channel explains it)",
    what="the force changes steadily from the first test of the campaign to the last (oil warming "
         "without a temperature channel, a load-cell gain drift); the model's inputs cannot see it",
    mistaken_for="thermal",
    fix="`--run-order-drift-pct PERCENT` (dampnet train, evaluate, diagnose) rescales each test's force "
        "to the first test's condition by a run-order term (first order in the drift); better, log the oil "
        "temperature and add it (`dampnet train --add thermal`), or randomise the run order so the drift "
        "averages out"))

register_artefact(ArtefactInfo(
    id="sign_slip", title="a channel's sign flipped in some tests",
    what="one channel (velocity, displacement or force) recorded with the opposite sign in some tests "
         "(a swapped connector, a sign convention of another rig)",
    mistaken_for="",
    fix="flip the channel back in those tests (dampnet.data.artefacts.flip_sign)"))

register_artefact(ArtefactInfo(
    id="unit_slip", title="a channel in another unit in some tests",
    what="one channel recorded in another unit in some tests (displacement in mm, force in lbf)",
    mistaken_for="",
    fix="rescale the channel in those tests (dampnet.data.artefacts.rescale)"))

register_artefact(ArtefactInfo(
    id="sensor_offset", title="a sensor's zero moved in some tests",
    what="a constant added to one channel in some tests (displacement zeroed at another position, a load "
         "cell's zero drifting)",
    mistaken_for="gas_spring",
    fix="subtract the offset in those tests (dampnet.data.artefacts.remove_offset)"))


# -- the data fixes -----------------------------------------------------------------------

#: the largest share of a test a channel shift may cut: a recording delay is milliseconds, a test
#: seconds (issue 49: --align-force-s 0.5 on a 0.667 s test cut 75 % of it without a word)
MAX_SHIFT_SHARE = 0.10


def _samples(test, seconds: float, what: str) -> int:
    if not np.isfinite(seconds):
        raise ValueError(f"{what}: expected a finite time [s], got {seconds}")
    k = int(round(abs(seconds) / test.dt))
    if k > MAX_SHIFT_SHARE * len(test) or k >= len(test) - 10:
        cut = "is longer than" if k >= len(test) else f"would cut {100 * k / len(test):.0f} % of"
        raise DataError(f"{what}: {abs(seconds):g} s {cut} test {test.test_id} "
                        f"({len(test)} samples, {len(test) * test.dt:.3g} s); expected a shift of at most "
                        f"{100 * MAX_SHIFT_SHARE:.0f} % of every test")
    return k


def shift_channel(ds: Dataset, channel: str, seconds: float, note: str) -> Dataset:
    """A copy of `ds` whose `channel` is moved by `seconds` [s] relative to the other channels
    (positive: the channel's samples come later in time, i.e. it is delayed), to the nearest
    sample; each test loses the samples the shift leaves without a partner."""
    tests = []
    for t in ds.tests:
        if channel not in t.channels:
            raise DataError(f"test {t.test_id}: no {channel!r} channel to shift (channels: {', '.join(sorted(t.channels))})")
        k = _samples(t, seconds, note)
        if k == 0:
            tests.append(t.copy())
            continue
        n = len(t)
        keep, moved = (slice(k, n), slice(0, n - k)) if seconds > 0 else (slice(0, n - k), slice(k, n))
        ch = {name: np.array(c[keep]) for name, c in t.channels.items()}
        ch[channel] = np.array(t.channels[channel][moved])
        tests.append(t.copy(time=np.array(t.time[:n - k]), channels=ch))
    return ds.subset(tests, note=note)


def align_force(ds: Dataset, seconds: float) -> Dataset:
    """Undo a force channel recorded `seconds` [s] late: the force moves earlier by that time
    (`--align-force-s`). A new Dataset; the files it came from are not touched."""
    return shift_channel(ds, "force", -float(seconds), f"force realigned by {-float(seconds):+g} s (--align-force-s)")


def remove_run_order_drift(ds: Dataset, percent: float) -> Dataset:
    """Undo a force drift along the run order (`--run-order-drift-pct`): the tests, in their
    stated run order (dampnet.data.runorder: the manifest's run_order or started column; else the
    dataset's order), drift linearly by `percent` [%] of the force from the first test to the last
    (as `dampnet diagnose` estimates it: force_change_percent); the test at place s in [0, 1] of
    the run (i / (n - 1) for the i-th of n) has its force divided by 1 + percent / 100 * s, which
    brings every test to the first
    test's condition. A run-order term of first order: a warming's effect on the force is not
    one gain, so logging the temperature is the better fix. A new Dataset; files untouched."""
    p = float(percent)
    if not (np.isfinite(p) and -90.0 < p < 900.0):
        raise ValueError(f"--run-order-drift-pct = {percent}: expected the force's change from the first test "
                         "to the last in percent, finite, between -90 and 900 (exclusive)")
    n = len(ds.tests)
    if n < 2:
        raise DataError(f"--run-order-drift-pct: a drift from the first test to the last needs at least two tests "
                        f"in run order; {ds.source} has {n}")
    from dampnet.data.runorder import run_positions

    pos = run_positions(ds.tests)   # the stated run order (dampnet.data.runorder), else the dataset's
    tests = []
    for i, t in enumerate(ds.tests):
        if "force" not in t.channels:
            raise DataError(f"test {t.test_id}: no 'force' channel to correct (channels: {', '.join(sorted(t.channels))})")
        gain = 1.0 + p / 100.0 * float(pos[i])
        tests.append(t.copy(channels={**t.channels, "force": np.asarray(t.channels["force"]) / gain}))
    return ds.subset(tests, note=f"force drift along the run order of {p:+g} % removed (--run-order-drift-pct)")


def _pick(ds: Dataset, tests) -> list[int]:
    ids = ds.test_ids
    if tests is None:
        return list(range(len(ids)))
    out = []
    for t in tests:
        if t not in ids:
            raise DataError(f"no test {t!r} in {ds.source} (tests: {', '.join(ids[:8])}{' ...' if len(ids) > 8 else ''})")
        out.append(ids.index(t))
    return out


def _per_test(ds: Dataset, channel: str, tests, op, note: str) -> Dataset:
    picked = set(_pick(ds, tests))
    out = []
    for i, t in enumerate(ds.tests):
        if i in picked:
            if channel not in t.channels:
                raise DataError(f"test {t.test_id}: no {channel!r} channel (channels: {', '.join(sorted(t.channels))})")
            ch = dict(t.channels)
            ch[channel] = op(np.asarray(t.channels[channel], dtype=np.float64))
            t = t.copy(channels=ch)
        out.append(t)
    return ds.subset(out, note=note)


def flip_sign(ds: Dataset, channel: str, tests=None) -> Dataset:
    """`channel` times -1 in `tests` (ids; None: every test)."""
    return _per_test(ds, channel, tests, lambda c: -c, f"{channel} sign flipped in {tests or 'all tests'}")


def rescale(ds: Dataset, channel: str, factor: float, tests=None) -> Dataset:
    """`channel` times `factor` in `tests` (e.g. 1e-3 for a displacement recorded in mm)."""
    if not np.isfinite(factor) or factor == 0:
        raise ValueError(f"rescale {channel}: expected a finite, non-zero factor, got {factor}")
    return _per_test(ds, channel, tests, lambda c: c * factor, f"{channel} times {factor:g} in {tests or 'all tests'}")


def remove_offset(ds: Dataset, channel: str, offset: float, tests=None) -> Dataset:
    """`channel` minus `offset` (its SI unit) in `tests`."""
    if not np.isfinite(offset):
        raise ValueError(f"remove_offset {channel}: expected a finite offset, got {offset}")
    return _per_test(ds, channel, tests, lambda c: c - offset, f"{channel} minus {offset:g} in {tests or 'all tests'}")
