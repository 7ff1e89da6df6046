"""Every public callable of dampnet._core (and dampnet.sim.quarter_car.loop) called with arbitrary arguments.

Run as a script (tests/python/test_bindings_fuzz.py starts it in a subprocess, so that a
crash of the interpreter is a failing test, not a dead pytest):

    python tests/python/bindings_fuzz_driver.py [EXAMPLES_PER_TARGET [SEED]]

(SEED: a long run exploring other calls than the test's derandomized ones.)

The targets are found by introspection (every class, its constructor, static methods,
methods, properties and attributes; the module's functions), so a new binding is fuzzed
without being listed here. Each call gets arbitrary positional arguments: None, bools,
ints (huge too), floats (NaN, Inf, huge, subnormal), text (including the runtime's own
enum, field, feature and term names), bytes, dicts of fields with values of any type,
lists, numpy arrays of any dtype, shape and layout (empty, Fortran order, strided, read
only, zero-stride broadcast), objects whose __float__/__index__/__len__/__array__/__repr__
raise, and live objects of every bound class (models, dampers, loops, callback dampers
whose function raises, returns garbage or re-enters its own loop, and instances made by
__new__ without __init__).

A call must return or raise an Exception that is not SystemError (which means a binding
returned an error without setting one); after it, every loop state of the example is still
finite (the runtime refuses non-finite input and keeps the state). Hypothesis runs
derandomized (fixed seed), without a database, so every run makes the same calls.
Each call is written to stderr first: after a crash the last line names it.

Long runs (the module of commit d327938 unless noted; each: the command, its result):
    python tests/python/bindings_fuzz_driver.py 150      13200 calls, no crash (27f0a72)
    python tests/python/bindings_fuzz_driver.py 100 1     8800 calls, no crash
    python tests/python/bindings_fuzz_driver.py 100 2     8800 calls, no crash
    python tests/python/bindings_fuzz_driver.py 300 3    26400 calls, no crash
Before the fixes a 40-per-target run crashed in its first minute (Loop.reset(None)), and
then on Loop.__new__(Loop).simulate(...).
"""

from __future__ import annotations

import faulthandler
import inspect
import math
import sys

import numpy as np
from hypothesis import HealthCheck, Phase, given, seed, settings
from hypothesis import strategies as st

from dampnet import _core
from dampnet.sim.quarter_car import loop as dloop

faulthandler.enable()

# ---- odd objects -------------------------------------------------------------------------


class BadNumber:
    """Looks numeric, raises on every conversion."""

    def __float__(self):
        raise RuntimeError("BadNumber.__float__")

    def __index__(self):
        raise RuntimeError("BadNumber.__index__")

    def __int__(self):
        raise RuntimeError("BadNumber.__int__")

    def __repr__(self):
        raise RuntimeError("BadNumber.__repr__")


class LyingSequence:
    """Claims 2**62 elements, has none."""

    def __len__(self):
        return 2**62

    def __getitem__(self, i):
        raise IndexError(i)


class BadArray:
    def __array__(self, *args, **kwargs):
        raise RuntimeError("BadArray.__array__")


class NotAString:
    def __str__(self):
        raise RuntimeError("NotAString.__str__")


class MutatingFloat:
    """Converts to a float and empties the dict it was found in, mid-iteration."""

    def __init__(self, d):
        self.d = d

    def __float__(self):
        self.d.clear()
        return 1.0


NAMES = ["passive", "skyhook_onoff", "skyhook_continuous", "groundhook_onoff",
         "groundhook_continuous", "external", "rk4", "semi_euler", "per_stage", "per_step",
         "implicit", "explicit", "linear", "tanh", "sigmoid", "", "\x00", "velocity",
         "acceleration", "displacement", "voltage", "position_poly", "bump_stop",
         "control_lag_tau_s", "force", "state", "status", "features"]
FIELDS = (list(_core.VEHICLE_FIELDS) + list(_core.CONTROLLER_FIELDS) +
          ["mass", "Kind", "dt ", "state", "force", "x"])

floats = st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                   st.sampled_from([math.nan, math.inf, -math.inf, 1e308, -1e308, 5e-324, -0.0,
                                    1e-3, 0.5, 700.0]))
ints = st.one_of(st.integers(-2**70, 2**70),
                 st.sampled_from([0, 1, -1, 2, 3, 5, 7, 8, 9, 13, 64, 65, 2**31, -2**31 - 1, 2**63]))
hashable_leaves = st.one_of(st.none(), st.booleans(), ints, floats, st.text(max_size=12),
                            st.sampled_from(NAMES), st.binary(max_size=6))
leaves = st.one_of(hashable_leaves, st.builds(BadNumber), st.builds(LyingSequence),
                   st.builds(BadArray), st.builds(NotAString), st.builds(object),
                   st.sampled_from([np.float64(1.0), np.int64(1), np.bool_(True), np.float32(np.nan),
                                    np.int64(2**62), 1 + 2j, Ellipsis, float, int]))

SHAPES = [(), (0,), (1,), (2,), (3,), (5,), (13,), (64,), (65,), (2, 3), (3, 3), (5, 3), (3, 13),
          (2, 0), (0, 3), (1, 1, 1), (4, 2, 2)]
DTYPES = [np.float64, np.float32, np.int32, np.int64, np.uint8, np.bool_, np.complex128, object, "U3"]


@st.composite
def arrays(draw):
    shape = draw(st.sampled_from(SHAPES))
    dtype = draw(st.sampled_from(DTYPES))
    fill = draw(st.sampled_from(["zeros", "ones", "nan", "inf", "ramp", "big"]))
    n = int(np.prod(shape)) if shape else 1
    base = {"zeros": np.zeros(n), "ones": np.ones(n), "nan": np.full(n, np.nan),
            "inf": np.full(n, np.inf), "ramp": np.linspace(-1.0, 1.0, n),
            "big": np.full(n, 1e300)}[fill]
    with np.errstate(all="ignore"):
        if dtype == "U3":
            a = base.astype(str).astype("U3")
        elif dtype is object:
            a = base.astype(object)
        else:
            a = base.astype(dtype)
    a = a.reshape(shape)
    layout = draw(st.sampled_from(["c", "f", "strided", "readonly", "broadcast", "bad_items"]))
    if layout == "f" and a.ndim >= 2:
        a = np.asfortranarray(a)
    elif layout == "strided" and a.ndim >= 1:
        a = np.repeat(a, 2, axis=0)[::2]
    elif layout == "readonly":
        a.flags.writeable = False
    elif layout == "broadcast" and a.ndim >= 1 and dtype is not object:
        a = np.broadcast_to(a.reshape(-1)[:1] if a.size else a.reshape(-1), (1000,) if a.size else (0,))
    elif layout == "bad_items" and a.ndim >= 1 and a.size:
        a = np.array([BadNumber()] * a.size, dtype=object).reshape(a.shape)
    return a


def fields_dicts(values):
    return st.dictionaries(st.one_of(st.sampled_from(FIELDS), hashable_leaves), values, max_size=4)


values = st.recursive(st.one_of(leaves, arrays()),
                      lambda inner: st.one_of(st.lists(inner, max_size=4), fields_dicts(inner)),
                      max_leaves=6)

# ---- live objects of every bound class ----------------------------------------------------


def make_mlp(n_in, hidden2=False):
    rng = np.random.default_rng(n_in)
    h = 4
    w2 = rng.normal(size=(3, h)) if hidden2 else None
    b2 = rng.normal(size=3) if hidden2 else None
    return _core.Mlp(rng.normal(size=(h, n_in)), rng.normal(size=h), w2, b2,
                     rng.normal(size=3 if hidden2 else h), np.array([0.1]),
                     np.zeros(n_in), np.ones(n_in), -1.0, 0.0, 1e-3, -1.0,
                     -np.ones(n_in) * 10, np.ones(n_in) * 10, "tanh")


class Pool:
    """Fresh live objects for one example (calls may change them)."""

    def __init__(self):
        self.mlp = make_mlp(3)
        self.mlp2 = make_mlp(2, hidden2=True)
        self.loops: list = []
        holder: dict = {}

        def reenter(inp):  # steps the loop that is evaluating it: refused, never a crash
            return holder["loop"].step_force(0.0, 0.0)

        def adds_term(inp):  # changes the damper that is evaluating it
            holder["damper"].add_term("position_poly", np.zeros(4))
            return 0.0

        callbacks = [lambda inp: 100.0 * inp.v, lambda inp: 1 / 0, lambda inp: "abc",
                     lambda inp: None, lambda inp: math.nan, lambda inp: math.inf,
                     lambda inp: BadNumber(), lambda inp: 10**400, reenter, adds_term]
        self.dampers = [_core.Damper.linear(1500.0),
                        _core.Damper.parametric(500.0, 4000.0, 2000.0, 50.0, 5.0, 0.01),
                        _core.Damper.table(np.array([-1.0, 0.0, 1.0]), np.array([0.0, 5.0]),
                                           np.array([[-1e3, 0.0, 1e3], [-2e3, 0.0, 2e3]])),
                        _core.Damper.neural(self.mlp, ["velocity", "acceleration", "displacement"]),
                        _core.Damper.neural(self.mlp2, ["velocity", "voltage"], {}, True)]
        self.dampers += [_core.Damper.callback(fn) for fn in callbacks]
        holder["damper"] = self.dampers[-1]
        configs = [({}, {}), ({"integrator": "semi_euler"}, {"kind": "skyhook_onoff"}),
                   ({"damper_eval": "per_step", "accel_feature": "linear"}, {"kind": "external"})]
        self.models = []
        for i, d in enumerate(self.dampers):
            veh, ctrl = configs[i % len(configs)]
            self.models.append(_core.LoopModel(d, veh, ctrl))
        self.loops = [_core.Loop(m) for m in self.models]
        holder["loop"] = self.loops[-2]
        self.report = self.loops[0].step(0.001, 0.0)
        self.result = self.loops[3].simulate(np.zeros(5), np.zeros(5))
        self.cars = [dloop.QuarterCar(self.dampers[0]), dloop.QuarterCar(self.dampers[3])]
        # made by __new__ without __init__: pybind11 would hand them to methods as raw memory
        self.uninitialised = {cls: cls.__new__(cls) for cls in
                              (_core.Mlp, _core.Damper, _core.LoopModel, _core.Loop, _core.Envelope,
                               _core.FullCarModel, _core.FullCar)}
        # the full vehicle: a linear and a neural model (their __init__ again is refused)
        self.fullcar_models = [_core.FullCarModel([self.dampers[0]] * 4),
                               _core.FullCarModel([self.dampers[3]] * 4, {"damper_eval": "per_step"},
                                                  {"kind": "skyhook_onoff"})]
        self.fullcars = [_core.FullCar(m) for m in self.fullcar_models]
        self.envelopes = [_core.Envelope(np.array([-1.0, 0.0, -5.0]), np.array([1.0, 5.0, 5.0]),
                                         np.full((3, _core.ENVELOPE_PAIR_WORDS), 0x0F0F0F0F, np.uint32))]
        self.by_class = {
            _core.Mlp: [self.mlp, self.mlp2], _core.Damper: self.dampers,
            _core.LoopModel: self.models, _core.Loop: self.loops,
            _core.DamperInput: [_core.DamperInput()], _core.StepReport: [self.report],
            _core.Envelope: self.envelopes,
            _core.FullCarModel: self.fullcar_models, _core.FullCar: self.fullcars,
            dloop.QuarterCar: self.cars}
        for cls, obj in self.uninitialised.items():
            self.by_class[cls].append(obj)

    def all_objects(self):
        return [o for objs in self.by_class.values() for o in objs] + [self.result]

    def check_states(self):
        for lp in self.loops[:-1] + [c.loop for c in self.cars]:  # the last is uninitialised
            try:
                s = lp.state
            except RuntimeError:  # busy: only while a call is under way, never after one
                raise AssertionError("a Loop is still marked busy after a call returned")
            assert np.isfinite(s).all(), f"non-finite loop state after a call: {s}"
        for car in self.fullcars[:-1]:   # the last is uninitialised
            assert np.isfinite(car.state).all(), f"non-finite full-car state after a call: {car.state}"


# ---- targets ------------------------------------------------------------------------------

DUNDERS = {"__getitem__", "__contains__", "__len__", "__iter__", "__repr__", "__init__", "__call__"}


def targets():
    """(name, kind, cls, attr): kind is one of function, constructor, static, method, property."""
    out = []
    for name in sorted(dir(_core)):
        obj = getattr(_core, name)
        if isinstance(obj, type) and not issubclass(obj, BaseException):
            out.append((name, "constructor", obj, None))
            for attr in sorted(dir(obj)):
                if attr.startswith("__") and attr not in DUNDERS:
                    continue
                raw = inspect.getattr_static(obj, attr)
                if isinstance(raw, staticmethod) or type(raw).__name__ == "staticmethod":
                    out.append((f"{name}.{attr}", "static", obj, attr))
                elif isinstance(raw, property) or inspect.isgetsetdescriptor(raw) or \
                        inspect.ismemberdescriptor(raw):
                    out.append((f"{name}.{attr}", "property", obj, attr))
                elif callable(getattr(obj, attr)):
                    out.append((f"{name}.{attr}", "method", obj, attr))
        elif callable(obj):
            out.append((name, "function", obj, None))
    # the Python layer over it
    for name in ("QuarterCar", "damper_from_model", "add_terms", "static_term_force", "truth_damper"):
        out.append((f"loop.{name}", "function", getattr(dloop, name), None))
    for attr in ("step", "simulate", "reset", "spawn", "state", "dt"):
        raw = inspect.getattr_static(dloop.QuarterCar, attr)
        kind = "property" if isinstance(raw, property) else "method"
        out.append((f"QuarterCar.{attr}", kind, dloop.QuarterCar, attr))
    return out


def short(x) -> str:
    try:
        r = repr(x)
    except Exception:
        r = f"<{type(x).__name__} with a failing repr>"
    r = " ".join(r.split())  # one line per call
    return r if len(r) <= 160 else r[:157] + "..."


def call(pool: Pool, kind, cls, attr, pick, args, use_live_self):
    """Make the call and return its result."""
    if kind in ("function", "constructor"):
        return cls(*args)
    if kind == "static":
        return getattr(cls, attr)(*args)
    objs = pool.by_class.get(cls, [])
    if kind == "method":
        if use_live_self and objs:
            return getattr(objs[pick % len(objs)], attr)(*args)
        return getattr(cls, attr)(*args)  # unbound: the first argument stands for self
    if kind == "property":
        if not objs:
            return getattr(cls, attr)
        obj = objs[pick % len(objs)]
        if args:
            setattr(obj, attr, args[0])
            return None
        return getattr(obj, attr)
    raise AssertionError(kind)


# an arbitrary value, or ("live", i): the i-th live object of the example's pool
live_or_value = st.one_of(values, st.tuples(st.just("live"), st.integers(0, 1000)))


def resolve(pool: Pool, a):
    if isinstance(a, tuple) and len(a) == 2 and a[0] == "live":
        objs = pool.all_objects()
        return objs[a[1] % len(objs)]
    if isinstance(a, dict) and a:
        # sometimes a value that empties its own dict while being read
        k = next(iter(a))
        if isinstance(k, str) and k == "dt":
            a[k] = MutatingFloat(a)
    return a


@st.composite
def out_dicts(draw):
    """simulate's out=: a previous result with one entry replaced by anything."""
    key = draw(st.sampled_from(["state", "force", "control", "x", "v", "a", "acc_s", "acc_us",
                                "features", "status", "missing"]))
    how = draw(st.sampled_from(["value", "huge_claim", "view_of_other", "wrong_len", "same"]))
    return key, how, draw(values)


def make_out(pool: Pool, key, how, value):
    out = {k: v.copy() for k, v in pool.result.items()}
    if key == "missing":
        out.pop("force")
    elif how == "value":
        out[key] = value
    elif how == "huge_claim":  # claims 2**40 elements of memory it does not have
        out[key] = np.lib.stride_tricks.as_strided(np.zeros(1, out[key].dtype), shape=(2**40,),
                                                   strides=(0,))
    elif how == "view_of_other":
        out[key] = out["force"] if key != "force" else out["control"]
    elif how == "wrong_len":
        out[key] = np.zeros((len(out[key]) + 1,) + out[key].shape[1:], out[key].dtype)
    return out


def run(examples: int, seed_value: int | None = None) -> int:
    tg = targets()
    cfg = settings(max_examples=examples, derandomize=seed_value is None, database=None, deadline=None,
                   suppress_health_check=list(HealthCheck), phases=[Phase.explicit, Phase.generate],
                   report_multiple_bugs=False)
    maybe_seed = seed(seed_value) if seed_value is not None else (lambda f: f)
    calls = 0
    for name, kind, cls, attr in tg:
        arg_lists = st.lists(live_or_value, max_size=5 if kind != "property" else 1)

        @maybe_seed
        @cfg
        @given(args=arg_lists, pick=st.integers(0, 100), live_self=st.booleans(),
               out=st.one_of(st.none(), out_dicts()))
        def one(args, pick, live_self, out):
            nonlocal calls
            pool = Pool()
            real = [resolve(pool, a) for a in args]
            kwargs = {}
            if attr == "simulate" and out is not None:
                real = [np.zeros(5), np.zeros(5)]
                kwargs["out"] = make_out(pool, *out)
            sys.stderr.write(f"CALL {name} {kind} live={live_self} pick={pick} "
                             f"args={short(real)} kwargs={short(kwargs)}\n")
            sys.stderr.flush()
            calls += 1
            try:
                res = call(pool, kind, cls, attr, pick, real, live_self) if not kwargs else \
                    getattr(pool.loops[pick % len(pool.loops)], "simulate")(*real, **kwargs)
            except SystemError:
                raise
            except Exception:
                res = None
            if isinstance(res, dict) and "state" in res and isinstance(res["state"], np.ndarray):
                for k in ("state", "force", "x", "v"):
                    assert np.isfinite(res[k]).all(), f"{name}: non-finite {k} in a returned result"
            pool.check_states()

        one()
    print(f"bindings fuzz: {len(tg)} targets, {calls} calls, no crash")
    return 0


if __name__ == "__main__":
    sys.exit(run(int(sys.argv[1]) if len(sys.argv) > 1 else 25,
                 int(sys.argv[2]) if len(sys.argv) > 2 else None))
