"""The generated C/C++ header: the contract between training and the runtime.

One self-contained header per model (C99 and C++17, warning-clean, safe to
include from several translation units). It holds, for a prefix `p`:

  P_ID, P_N_INPUTS, P_N_HIDDEN1, P_N_HIDDEN2, P_ACTIVATION   sizes and kind
  P_DN_MAX_HIDDEN                                           the library build it needs
  P_IN_YMIN, P_OUT_OFFSET, P_OUT_GAIN, P_OUT_YMIN           output scaling
  p_feature_names[], p_feature_units[]                      ordered inputs
  p_w1[], p_b1[], (p_w2[], p_b2[]), p_w_out[], p_b_out[]    weights, [out][in] row-major
  p_in_offset[], p_in_gain[], p_sat_lo[], p_sat_hi[]        input scaling and limits
  P_DESC_INIT                                               a dn_mlp_desc initializer
  p_folded_*[], P_FOLDED_*, P_FOLDED_INIT                   the same model folded into float
                                                            weights: a dn_mlp_folded_f initializer
  P_N_TERMS and p_terms_*                                   physics terms (hybrid models)
  P_N_FEATURE_PARAMS, P_<PARAM>, p_feature_param_names[],   constants of derived features
  p_feature_param_values[] (arrays only when there are any)  (e.g. P_VELOCITY_LAG_TAU_S)
  P_CONTROL_INPUT, P_CONTROL_MIN, P_CONTROL_MAX,            the input reading the control (voltage or
                                                            current: dn_damper_input.u) and its range,
                                                            the damper inverse's (-1 and 0: none)
  P_HAS_ENVELOPE, p_envelope_lo[], p_envelope_hi[],          the training envelope's bounded-time
  p_envelope_cells[], P_ENVELOPE_DESC_INIT                  check (a dn_envelope_desc initializer),
                                                            only when exported with an envelope

C:   dn_mlp_desc d = P_DESC_INIT; dn_mlp_create(&d, &m);
     float-only targets: dn_mlp_folded_f f = P_FOLDED_INIT; dn_mlp_init_folded(&f, mem, bytes, &m);
C++: dampnet::StaticMlp<float, P_N_INPUTS, P_N_HIDDEN1, P_N_HIDDEN2> m; m.load(&d);
Envelope (each step, on the damper's inputs, e.g. dn_loop_out.features):
     dn_envelope_desc e = P_ENVELOPE_DESC_INIT; dn_envelope_create(&e, &env);
     dn_envelope_check(env, x, &flags);   /* 0: the model is inside its training data */
"""

from __future__ import annotations

import datetime as _dt
import keyword
import os
import re
from pathlib import Path

import numpy as np

from dampnet.model import MlpModel, check_runtime_accepts, folded_float
from dampnet.outputs import atomic_write_text

# C89/C99/C++17 keywords and names the header itself defines, which a prefix must not be.
_RESERVED = set(
    """auto break case char const continue default do double else enum extern float for goto if
    inline int long register restrict return short signed sizeof static struct switch typedef
    union unsigned void volatile while _Bool _Complex _Imaginary alignas alignof and asm bool
    catch class constexpr decltype delete explicit export false friend mutable namespace new
    noexcept not nullptr operator or private protected public static_assert template this
    thread_local throw true try typeid typename using virtual wchar_t xor""".split()
)

_IDENT = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


def check_prefix(prefix: str) -> str:
    """Return the prefix if it is a valid, non-reserved C identifier, else raise ValueError."""
    if not _IDENT.match(prefix) or prefix in _RESERVED or keyword.iskeyword(prefix):
        raise ValueError(f"header prefix {prefix!r}: expected a C identifier of letters, digits "
                         "and underscores, starting with a letter, and not a C/C++ keyword")
    if prefix.lower() == "dn":
        raise ValueError("header prefix 'dn' is reserved for the dampnet library")
    return prefix


def _banner_value(v, width: int = 160) -> str:
    """A short one-line rendering of a metadata value (long lists summarised, cut at width)."""
    if isinstance(v, dict):
        parts = []
        for k, x in v.items():
            if isinstance(x, (list, tuple)) and len(x) > 4:
                x = f"[{len(x)} items]"
            elif isinstance(x, dict):
                continue
            parts.append(f"{k}={x}")
        v = ", ".join(parts)
    text = " ".join(str(v).split())
    return text if len(text) <= width else text[: width - 3] + "..."


def _num(v: float) -> str:
    """A double literal that round-trips (17 significant digits)."""
    s = f"{float(v):.17g}"
    if "e" not in s and "." not in s and "inf" not in s and "nan" not in s:
        s += ".0"
    return s


def _array(name: str, values: np.ndarray, dims: str, layout: str) -> str:
    flat = np.asarray(values, dtype=np.float64).ravel()
    rows = []
    for i in range(0, flat.size, 4):
        rows.append("  " + ", ".join(_num(v) for v in flat[i:i + 4]) + ",")
    body = "\n".join(rows)
    return f"/* {layout} */\nstatic const double {name}[{dims}] = {{\n{body}\n}};\n"


def _f32(v) -> str:
    """A float literal that round-trips to the same float32 (9 significant digits)."""
    s = f"{float(v):.9g}"
    if not any(c in s for c in ".en"):
        s += ".0"
    return s + "f"


def _farray(name: str, values: np.ndarray, dims: str, layout: str) -> str:
    flat = np.asarray(values, dtype=np.float32).ravel()
    rows = ["  " + ", ".join(_f32(v) for v in flat[i:i + 6]) + "," for i in range(0, flat.size, 6)]
    return f"/* {layout} */\nstatic const float {name}[{dims}] = {{\n" + "\n".join(rows) + "\n};\n"


def _folded_block(p: str, P: str, model: MlpModel) -> list[str]:
    """The float-folded arrays and P_FOLDED_INIT (a dn_mlp_folded_f initializer)."""
    f = folded_float(model)
    head = ("/* The same model folded into float weights (dn_mlp_folded_f, dampnet.h): what dn_mlp_init's "
            "float copy\n   holds, for dn_mlp_init_folded on float-only targets (no double arithmetic at "
            "set-up). */")
    if f is None:
        return [head.replace("*/", "Not written: a folded value overflows float. */"), ""]
    h1, ni, h2 = f["n_hidden1"], f["n_inputs"], f["n_hidden2"]
    n_last = h2 or h1
    out = [head,
           f"#define {P}_FOLDED_OFFSETS {f['offsets_folded']} /* 1: b1 holds the input offsets */",
           f"#define {P}_FOLDED_B_OUT ({_f32(f['b_out'])}) /* [{model.output_unit}] */",
           f"#define {P}_FOLDED_OUT_OFFSET ({_f32(f['out_offset'])}) /* [{model.output_unit}] */",
           _farray(f"{p}_folded_w1", f["w1"], f"{h1} * {ni}",
                   f"layer 1, [{h1}][{ni}] row-major, input gains folded in, 1/feature unit"),
           _farray(f"{p}_folded_b1", f["b1"], f"{h1}", "layer 1 biases")]
    if h2:
        out += [_farray(f"{p}_folded_w2", f["w2"], f"{h2} * {h1}", f"layer 2, [{h2}][{h1}] row-major"),
                _farray(f"{p}_folded_b2", f["b2"], f"{h2}", "layer 2 biases")]
    out += [_farray(f"{p}_folded_w_out", f["w_out"], f"{n_last}",
                    f"output weights, output unscaling folded in, [{model.output_unit}]"),
            _farray(f"{p}_folded_in_offset", f["in_offset"], f"{ni}", "input offsets, feature units"),
            _farray(f"{p}_folded_sat_lo", f["sat_lo"], f"{ni}", "lower saturation limits, feature units"),
            _farray(f"{p}_folded_sat_hi", f["sat_hi"], f"{ni}", "upper saturation limits, feature units"),
            _farray(f"{p}_folded_sat_mid", f["sat_mid"], f"{ni}", "what a NaN input becomes, feature units")]
    w2 = f"{p}_folded_w2" if h2 else "(const float*)0"
    b2 = f"{p}_folded_b2" if h2 else "(const float*)0"
    out += ["/* Initializer for a dn_mlp_folded_f (dampnet.h), field by field in its order. */",
            f"#define {P}_FOLDED_INIT {{ {P}_N_INPUTS, {P}_N_HIDDEN1, {P}_N_HIDDEN2, {P}_FOLDED_OFFSETS, \\",
            f"    {p}_folded_w1, {p}_folded_b1, {w2}, {b2}, {p}_folded_w_out, \\",
            f"    {P}_FOLDED_B_OUT, {P}_FOLDED_OUT_OFFSET, {p}_folded_in_offset, \\",
            f"    {p}_folded_sat_lo, {p}_folded_sat_hi, {p}_folded_sat_mid }}",
            ""]
    return out


def _cstr(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


def build_defines(model: MlpModel) -> list[str]:
    """The dn_config.h limits a build of the library must raise to hold `model`, as "NAME=value"
    compile definitions; none for a network within the defaults. DN_MAX_HIDDEN when a hidden layer
    is wider than the default 64 (an averaged network: `dampnet train --average`). The FMU's and
    the firmware folder's builds take them from here."""
    from dampnet import _core

    need = max(model.hidden)
    return [f"DN_MAX_HIDDEN={need}"] if need > int(_core.MAX_HIDDEN_DEFAULT) else []


def header_text(model: MlpModel, prefix: str = "dn_model", envelope=None) -> str:
    """The header for a model, as text (see the module docstring for its contents); with the
    training envelope's grid when `envelope` (a dampnet.envelope.Envelope of this model) is given."""
    p = check_prefix(prefix)
    P = p.upper()
    n_in = model.n_inputs
    h1 = model.hidden[0]
    h2 = model.hidden[1] if len(model.hidden) > 1 else 0
    n_last = h2 or h1
    meta = model.meta
    stamp = meta.get("exported_at") or _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    banner_lines = [
        f"Generated by dampnet.export (dampnet {_package_version()}). DO NOT EDIT: regenerate instead.",
        f"model id: {model.model_id()}",
        f"exported: {stamp}",
        f"network: {n_in}-{'-'.join(str(h) for h in model.hidden)}-1, hidden activation "
        f"{model.activation}, linear output ({model.output} [{model.output_unit}])",
        "inputs: " + ", ".join(f"{f} [{u}]" for f, u in zip(model.features, model.units)),
    ]
    for key in ("algorithm", "trained_at", "training_time_s", "data", "torch_version", "metrics"):
        if key in meta:
            banner_lines.append(f"{key}: {_banner_value(meta[key])}")
    banner = "/*\n" + "\n".join(" * " + line.replace("*/", "* /") for line in banner_lines) + "\n */\n"

    guard = f"{P}_H_"
    out = [banner, f"#ifndef {guard}", f"#define {guard}", ""]
    out += [
        f'#define {P}_ID "{model.model_id()}"',
        f"#define {P}_N_INPUTS {n_in}",
        f"#define {P}_N_HIDDEN1 {h1}",
        f"#define {P}_N_HIDDEN2 {h2} /* 0: one hidden layer */",
        f"#define {P}_DN_MAX_HIDDEN {max(h1, h2)} /* the DN_MAX_HIDDEN (dn_config.h) a library holding this "
        + (f"network needs: more than the default, so build it with -D{build_defines(model)[0]} (CMake "
           f"-DDAMPNET_MAX_HIDDEN={max(h1, h2)}) */" if build_defines(model) else "network needs: within the default */"),
        f"#define {P}_ACTIVATION {_activation_value(model.activation)} "
        f"/* DN_ACT_{model.activation.upper()} */",
        "/* mapminmax: x_scaled = (x - in_offset) * in_gain + IN_YMIN;",
        "   y = (y_scaled - OUT_YMIN) / OUT_GAIN + OUT_OFFSET */",
        f"#define {P}_IN_YMIN ({_num(model.in_ymin)})",
        f"#define {P}_OUT_OFFSET ({_num(model.out_offset)}) /* [{model.output_unit}] */",
        f"#define {P}_OUT_GAIN ({_num(model.out_gain)}) /* [1/{model.output_unit}] */",
        f"#define {P}_OUT_YMIN ({_num(model.out_ymin)})",
        "",
        "/* Input features, in the order the network takes them, and their units. */",
        f"static const char* const {p}_feature_names[{n_in}] = {{"
        + ", ".join(_cstr(f) for f in model.features) + "};",
        f"static const char* const {p}_feature_units[{n_in}] = {{"
        + ", ".join(_cstr(u) for u in model.units) + "};",
        "",
    ]
    out.append(_array(f"{p}_w1", model.w1, f"{h1} * {n_in}",
                      f"hidden layer 1 weights, [{h1}][{n_in}] row-major: w1[j * {n_in} + i] "
                      "connects input i to neuron j"))
    out.append(_array(f"{p}_b1", model.b1, f"{h1}", "hidden layer 1 biases"))
    if h2:
        out.append(_array(f"{p}_w2", model.w2, f"{h2} * {h1}",
                          f"hidden layer 2 weights, [{h2}][{h1}] row-major"))
        out.append(_array(f"{p}_b2", model.b2, f"{h2}", "hidden layer 2 biases"))
    out.append(_array(f"{p}_w_out", model.w_out, f"{n_last}", f"output weights, [1][{n_last}]"))
    out.append(_array(f"{p}_b_out", np.array([model.b_out]), "1", "output bias"))
    out.append(_array(f"{p}_in_offset", model.in_offset, f"{n_in}",
                      "input mapminmax xoffset (training minimum), feature units"))
    out.append(_array(f"{p}_in_gain", model.in_gain, f"{n_in}", "input mapminmax gain, 1/feature unit"))
    out.append(_array(f"{p}_sat_lo", model.sat_lo, f"{n_in}",
                      "lower saturation limit (training range), feature units"))
    out.append(_array(f"{p}_sat_hi", model.sat_hi, f"{n_in}",
                      "upper saturation limit (training range), feature units"))
    out.append(_control_block(P, model))
    out.append(_terms_block(p, P, model))
    out.append(_feature_params_block(p, P, model))
    w2 = f"{p}_w2" if h2 else "(const double*)0"
    b2 = f"{p}_b2" if h2 else "(const double*)0"
    out += [
        "/* Initializer for a dn_mlp_desc (dampnet.h), field by field in its order. */",
        f"#define {P}_DESC_INIT {{ {P}_N_INPUTS, {P}_N_HIDDEN1, {P}_N_HIDDEN2, {P}_ACTIVATION, \\",
        f"    {p}_w1, {p}_b1, {w2}, {b2}, {p}_w_out, {p}_b_out, \\",
        f"    {p}_in_offset, {p}_in_gain, {P}_IN_YMIN, {P}_OUT_OFFSET, {P}_OUT_GAIN, {P}_OUT_YMIN, \\",
        f"    {p}_sat_lo, {p}_sat_hi }}",
        "",
        *_folded_block(p, P, model),
        *([_envelope_block(p, P, model, envelope)] if envelope is not None else []),
        f"#endif /* {guard} */",
        "",
    ]
    return "\n".join(out)


def _envelope_block(p: str, P: str, model: MlpModel, envelope) -> str:
    """The training envelope's ranges and per-pair occupancy bitmaps (dampnet.envelope.grid) and
    a dn_envelope_desc initializer."""
    from dampnet.envelope import check_belongs
    from dampnet.envelope.grid import DILATE_CELLS, grid_cells, grid_size

    check_belongs(envelope, model)
    cells = grid_cells(envelope)
    n = model.n_inputs
    words = [f"0x{int(w):08x}u" for w in cells.ravel()]
    rows = ["  " + ", ".join(words[i:i + 6]) + "," for i in range(0, len(words), 6)]
    lines = ["/* Training envelope (dampnet.h, \"Training envelope\"): each input's training range and, for",
             f"   each of the {cells.shape[0]} pairs of inputs, a DN_ENVELOPE_CELLS^2 bitmap of the cells its",
             f"   {envelope.params.get('n_points', envelope.points.shape[0])} stored training samples fell in "
             f"(grown by {DILATE_CELLS} cell). */",
             "#include <stdint.h>",
             f"#define {P}_HAS_ENVELOPE 1",
             f"#define {P}_ENVELOPE_CELLS {grid_size()} /* the grid it was written for: dampnet.h's DN_ENVELOPE_CELLS */",
             f"#if defined(DN_ENVELOPE_CELLS) && DN_ENVELOPE_CELLS != {P}_ENVELOPE_CELLS",
             f'#error "{p}: envelope written for a {grid_size()}-cell grid; this dampnet.h has another"',
             "#endif",
             _array(f"{p}_envelope_lo", envelope.lo, f"{n}", "training range, lower limit, feature units"),
             _array(f"{p}_envelope_hi", envelope.hi, f"{n}", "training range, upper limit, feature units")]
    if cells.size:
        lines.append(f"/* [{cells.shape[0]}][DN_ENVELOPE_PAIR_WORDS = {cells.shape[1]}] */\n"
                     f"static const uint32_t {p}_envelope_cells[{cells.size}] = {{\n" + "\n".join(rows) + "\n};\n")
    cells_ptr = f"{p}_envelope_cells" if cells.size else "(const uint32_t*)0"
    lines.append(f"#define {P}_ENVELOPE_DESC_INIT {{ {P}_N_INPUTS, {p}_envelope_lo, {p}_envelope_hi, {cells_ptr} }}\n")
    return "\n".join(lines)


def _control_block(P: str, model: MlpModel) -> str:
    from dampnet.features import control_input

    k = control_input(model.features)
    lines = ["/* The damper's control, for dn_damper_inverse (a controller's demanded force -> control): the",
             "   input reading dn_damper_input.u (-1: none, or two; the inverse then refuses) and its range,",
             "   the input's saturation limits (dn_damper_control_range gives the same). */",
             f"#define {P}_CONTROL_INPUT {-1 if k is None else k}"]
    if k is not None:
        unit = model.units[k]
        lines += [f"#define {P}_CONTROL_MIN ({_num(model.sat_lo[k])}) /* [{unit}] */",
                  f"#define {P}_CONTROL_MAX ({_num(model.sat_hi[k])}) /* [{unit}] */"]
    else:
        lines += [f"#define {P}_CONTROL_MIN (0.0) /* no control */", f"#define {P}_CONTROL_MAX (0.0) /* no control */"]
    return "\n".join(lines) + "\n"


def _terms_block(p: str, P: str, model: MlpModel) -> str:
    """Physics terms of a hybrid model: kind ids and parameters, one row per term."""
    terms = model.terms
    lines = ["/* Physics terms added to the network output (hybrid model); 0 for a pure MLP. */",
             f"#define {P}_N_TERMS {len(terms)}"]
    if terms:
        lines.append(f"static const char* const {p}_term_kinds[{len(terms)}] = {{"
                     + ", ".join(_cstr(t["kind"]) for t in terms) + "};")
        width = max(len(t.get("params", [])) for t in terms) or 1
        rows = np.zeros((len(terms), width))
        for i, t in enumerate(terms):
            rows[i, :len(t.get("params", []))] = t.get("params", [])
        lines.append(f"static const int {p}_term_n_params[{len(terms)}] = {{"
                     + ", ".join(str(len(t.get("params", []))) for t in terms) + "};")
        lines.append(f"#define {P}_TERM_PARAMS {width}")
        lines.append(_array(f"{p}_term_params", rows, f"{len(terms)} * {width}",
                            f"term parameters, [{len(terms)}][{width}] row-major; meaning per kind "
                            "in dampnet's hybrid-term table"))
    return "\n".join(lines) + "\n"


def _feature_params_block(p: str, P: str, model: MlpModel) -> str:
    """Constants of derived features (e.g. the control lag's time constant): one macro each,
    and, when there are any, name/value arrays to pass to dn_damper_create_neural as they are."""
    items = sorted(model.feature_params.items())
    lines = ["/* Constants of derived input features (unit in the name's suffix). */",
             f"#define {P}_N_FEATURE_PARAMS {len(items)}"]
    for key, value in items:
        if not _IDENT.match(key):
            raise ValueError(f"feature parameter {key!r}: expected an identifier")
        lines.append(f"#define {P}_{key.upper()} ({_num(value)})")
    if items:
        names = ", ".join(_cstr(k) for k, _ in items)
        values = ", ".join(_num(v) for _, v in items)
        lines.append(f"static const char* const {p}_feature_param_names[{len(items)}] = {{{names}}};")
        lines.append(f"static const double {p}_feature_param_values[{len(items)}] = {{{values}}};")
    return "\n".join(lines) + "\n"


def _package_version() -> str:
    """The package's version (dampnet.__version__, from its metadata): a header says which
    dampnet wrote it. A committed header (export/dn_model_default.h) is rewritten after a
    version bump by export/make_default_model.py --rewrite (tests/python/test_export.py)."""
    from dampnet import __version__  # at call time: dampnet's __init__ may import this module

    return __version__


def _activation_value(name: str) -> int:
    """The dn_activation value of an activation name (the runtime's ACTIVATIONS registry)."""
    from dampnet import _core

    try:
        return _core.ACTIVATIONS[name][0]
    except KeyError:
        raise ValueError(f"activation {name!r}: expected one of {', '.join(_core.ACTIVATIONS)}") from None


def write_header(model: MlpModel, path: str | os.PathLike, prefix: str = "dn_model",
                 overwrite: bool = False, envelope=None) -> Path:
    """Write the model's header (with `envelope`'s grid when given) to path atomically; refuses
    to overwrite unless asked, and a model the runtime would refuse (check_runtime_accepts)."""
    check_runtime_accepts(model)
    return atomic_write_text(path, header_text(model, prefix, envelope), overwrite)
