"""The diagnosis's three-way verdict (plus the artefact family):

  known_effect       catalogue effects explain the structure the leftover test finds (at least
                     leftover.MIN_EXPLAINED of it) with their parameters inside their physical range
                     (an effect whose parameter sits at the top of its grid is stretched to fit
                     something else, and is not named): name them, as the ranking always did
  unknown_structure  structure is left that no catalogue effect explains (none significant, or the
                     significant ones explain less than MIN_EXPLAINED of it): "not a known effect",
                     with how much and where
  nothing_left       the leftover test finds nothing above its null: what is left is noise (on the
                     force and on the inputs) and the model's own capacity, not a missing effect, when
                     the model's residual is within NOISE_LIKE_MAX of the force channel's noise;
                     above that, the sentence says so, and that capacity or an unrecorded
                     difference between tests cannot be told apart from these data
  artefact           a measurement artefact (dampnet.data.artefacts) is found: its data fix comes first,
                     and a catalogue effect it mimics (mistaken_for) is not named
  artefact_and_unknown_structure
                     an artefact, and the leftover test run again on the data with its fix applied
                     still finds structure that no catalogue effect explains: both are said, the
                     structure with how much and where (an artefact never hides what is left)
"""

from __future__ import annotations

from dampnet.data.artefacts import artefact
from dampnet.diagnosis.leftover import MIN_EXPLAINED
from dampnet.diagnosis.report import _num

KINDS = ("known_effect", "unknown_structure", "nothing_left", "artefact", "artefact_and_unknown_structure")
PER_TEST = ("sign_slip", "unit_slip", "sensor_offset")  # artefacts found test by test
#: a model residual up to this many times the force channel's noise is what noise on the inputs and
#: a model near its floor leave (the thesis-plan model sits at 2.5-2.9x); above it, "nothing above
#: the noise floor" would be a confident wrong statement (a 30-neuron model at 120 epochs on clean rig
#: data: 5.7x; the same with a hidden thermal effect and no temperature channel: 20x, and the leftover
#: test finds no structure in either: bench/experiments/noise_ratio.py)
NOISE_LIKE_MAX = 3.0


# a bin whose key is None holds the tests without that key (replays and random-content tests have no
# frequency; a dataset may have no nominal control)
_NO_KEY = {"frequency": "tests without a frequency", "control": "tests without a nominal control"}


def _bin_words(dim: str, value, unit: str) -> str:
    if value is None:
        return "in " + _NO_KEY.get(dim, "tests without one")
    return f"at {_num(value)}{unit}"


def _where_words(left: dict) -> str:
    w = left["where"]
    dim = w.get("most_uneven")
    if dim is None:
        return "spread evenly"
    bins = w.get(f"by_{dim}", [])
    key = {"frequency": "frequency_hz", "control": "control", "phase_deg": "phase_deg", "run_order": "tests"}[dim]
    top = max(bins, key=lambda b: b["rms_n"])
    low = min(bins, key=lambda b: b["rms_n"])
    unit = {"frequency": " Hz", "control": "", "phase_deg": " deg of the cycle", "run_order": ""}[dim]
    label = {"frequency": "frequency", "control": "control", "phase_deg": "phase of the cycle",
             "run_order": "run order"}[dim]
    if isinstance(top[key], str):
        return (f"most uneven by {label}: {top['rms_n']:.1f} N RMS in tests {top[key]} against "
                f"{low['rms_n']:.1f} N in tests {low[key]}")
    return (f"most uneven by {label}: {top['rms_n']:.1f} N RMS {_bin_words(dim, top[key], unit)} against "
            f"{low['rms_n']:.1f} N {_bin_words(dim, low[key], unit)}")


def _amount(left: dict) -> str:
    return (f"{left['structure_rms_n']:.1f} N RMS, {100 * left['score']:.1f} % of the residual's variance "
            f"held out (null {100 * left['null']['mean']:.2f} +- {100 * left['null']['sd']:.2f} %, z {left['z']:.1f})")


def three_way(accepted: dict, left0: dict, left1: dict | None, artefacts: list[dict], ctx=None,
              left_fixed: dict | None = None) -> dict:
    """{"kind", "sentence", "effects" (named catalogue ids), "artefacts" (found ids), "explained_share",
    "partial" (significant catalogue effects not named because they explain too little)}. `left_fixed`:
    the leftover test on the data with the artefacts' fixes applied (None: not run; then the test on
    the data as recorded stands for it)."""
    found = [a for a in artefacts if a.get("detected")]
    # only an artefact of the whole dataset can stand in for a catalogue effect seen across it: a
    # slip or a zero in some tests (PER_TEST) is reported beside the effect, not instead of it
    mimicked = {artefact(a["artefact"]).mistaken_for for a in found if a["artefact"] not in PER_TEST}
    kept = [c for c in accepted if c not in mimicked]
    # an effect whose parameter sits at the top of its physical range is stretched to fit: it
    # stands in for something the catalogue does not have, and is not named
    partial = [c for c in kept if accepted[c].get("at_grid_top")]
    kept = [c for c in kept if c not in partial]
    total = sum(float(accepted[c]["score"]) for c in kept)
    explained = total / left0["score"] if left0["score"] > 0 else None
    if kept and left0["significant"] and explained is not None and explained < MIN_EXPLAINED:
        partial, kept = partial + kept, []
    structure = left0["significant"]
    after = left1 if left1 is not None else left0
    beyond = left_fixed if left_fixed is not None else left0   # structure beyond the artefacts
    if found and not kept and beyond["significant"]:
        kind = "artefact_and_unknown_structure"
        sentence = ("a measurement artefact, and structure left that no catalogue effect explains: "
                    f"{_amount(beyond)}; {_where_words(beyond)}"
                    + (" (the leftover test on the data with the artefacts' fixes applied)" if left_fixed is not None
                       else "")
                    + ". Measurement artefact: " + "; ".join(a["sentence"] for a in found))
        if partial:
            share = sum(float(accepted[c]["score"]) for c in partial) / left0["score"] if left0["score"] > 0 else 0.0
            sentence += (f". Nearest catalogue effects: {', '.join(partial)}, significant but not named (together "
                         f"{100 * share:.0f} % of the structure before the fixes)")
    elif found:
        kind = "artefact"
        sentence = "measurement artefact: " + "; ".join(a["sentence"] for a in found)
        if kept:
            sentence += f". Also a catalogue effect: {', '.join(kept)}"
    elif kept:
        kind = "known_effect"
        sentence = (f"a catalogue effect explains it: {', '.join(kept)} (together "
                    f"{100 * total:.1f} % of the residual's variance held out"
                    + (f", {100 * explained:.0f} % of the structure the leftover test finds" if explained else "")
                    + ")")
        if left1 is not None and left1["significant"]:
            sentence += f"; structure is left after them too: {_amount(left1)}, {_where_words(left1)}"
    elif structure:
        kind = "unknown_structure"
        sentence = (f"not a known effect: structure is left that no catalogue effect explains, {_amount(left0)}; "
                    f"{_where_words(left0)}")
        if partial:
            share = sum(float(accepted[c]["score"]) for c in partial) / left0["score"]
            edge = [c for c in partial if accepted[c].get("at_grid_top")]
            sentence += (f". Nearest catalogue effects: {', '.join(partial)}, significant but not named: together "
                         f"they explain {100 * share:.0f} % of it"
                         + (f", and {', '.join(edge)} only with its parameter at the top of its physical range "
                            "(stretched to stand in for something else)" if edge else
                            f" (named only from {100 * MIN_EXPLAINED:.0f} %)"))
        sentence += " (see the residual's force-displacement loop and its run-order plot in the report)"
    else:
        kind = "nothing_left"
        ratio = after.get("model_residual_vs_noise")
        test = ("the leftover test finds no structure the model's inputs or their history predict "
                f"(score {100 * after['score']:.2f} %, z {after['z']:.1f})")
        residual = (f"the model's residual, {after['model_residual_rms_n']:.1f} N RMS, is {ratio:.1f}x the force "
                    f"channel's noise ({after['noise_floor_rms_n']:.2f} N RMS, {after['noise_floor_source']})"
                    if ratio is not None else "")
        if ratio is not None and ratio > NOISE_LIKE_MAX:
            # not noise, and not predictable from what was recorded: which of the two it is, these data
            # cannot tell (a missing effect that varies between tests, e.g. a temperature not recorded,
            # leaves exactly this)
            sentence = (f"no structure the recorded inputs predict, but not noise either: {test}; {residual}, more "
                        f"than the {NOISE_LIKE_MAX:g}x that noise on the inputs explains. What is left is either the "
                        "model's capacity (more epochs, restarts, a larger network) or something the data do not "
                        "record that differs between tests or along the campaign (a temperature, a changed setup): "
                        "which of the two is not testable from these data")
        else:
            sentence = (f"nothing above the noise floor: {test}"
                        + (f"; {residual}: the rest is noise on the inputs and the model's capacity, not a missing "
                           "effect" if ratio is not None else ""))
    return {"kind": kind, "sentence": sentence, "effects": kept, "artefacts": [a["artefact"] for a in found],
            "explained_share": explained, "partial": partial, "structure_left": bool(structure),
            "structure_beyond_artefacts": bool(found) and bool(beyond["significant"])}
