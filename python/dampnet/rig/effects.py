"""The rig's physics of the switchable effects (`dampnet rig --effects ID`), keyed by the
effect catalogue (dampnet.effects: ids, titles, what a model needs to capture each):

  gas_spring  position-dependent gas force: polytropic compression of the charge
  thermal     oil temperature varies between and within tests (temperature_c); viscosity falls with it
  valve_lag   the solenoid valve's ~40 ms response; the rig steps the control voltage within tests
  friction    stick-slip seal friction (LuGre), replacing the smooth Coulomb seal friction
  bump_stop   elastomer bump stop in the last 8 mm of compression travel
  mount_hysteresis  Bouc-Wen rubber hysteresis of a top mount in the load path (no candidate knows it)
  campaign_warming  the oil warms along the run order, no temperature channel (no candidate knows it)

(compressibility is in the catalogue too, always on in the truth damper's base physics:
TruthParams.compressibility_tau_s.)

To add an effect, add its identity to the catalogue (dampnet.effects.register_effect,
rig="switchable"), subclass `Effect` with `name` = its id and decorate the class with
``@register``. An effect may

  prepare(ctx) / prepare_step(ctx, state)   change the inputs the hydraulics see (ctx.opening, ...)
  force(ctx) / force_step(ctx, state)       add a force [N] (vectorised / one sample with state)
  prepare_1 / force_1                       the stepwise forms on Python floats (one_sample = True)
  control(t, voltage, levels, rng)          (rig) reshape the control voltage of a test
  initial_temperature(rng) / heating(...)   (rig) make the oil temperature vary

Stateless effects only need `force` (and/or `prepare`); the stepwise forms
default to calling them on one sample. The float forms are optional: TruthDamper.step (a loop's
callback, once per step) runs 3-5 times faster when every effect has them, and they must
give its forces bit for bit (numpy's ufuncs for exp, power and tanh, not math's: these differ in
the last bit).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from dampnet.effects import CATALOGUE
from dampnet.features import first_order_lag
from dampnet.rig.context import Context


class Effect:
    """Base class: an effect that does nothing."""

    name = "base"
    varies_temperature = False   # (rig) the effect sets the oil temperature of each test
    records_temperature = False  # (rig) ... and the rig logs it as the temperature channel

    def params(self) -> dict:
        return asdict(self) if hasattr(self, "__dataclass_fields__") else {}

    # -- force law, vectorised ------------------------------------------
    def prepare(self, ctx: Context) -> None:
        """Change ctx inputs (e.g. ctx.opening) before the hydraulics are evaluated."""

    def force(self, ctx: Context):
        """An additional force [N] (array like ctx.v), or None."""
        return None

    # -- force law, one sample with state --------------------------------
    def prepare_step(self, ctx: Context, state):
        self.prepare(ctx)
        return state

    def force_step(self, ctx: Context, state):
        return self.force(ctx), state

    # -- force law, one sample in Python floats (TruthDamper.step's fast path) --
    #: Set True in the body of every class that writes prepare* / force* and also writes
    #: prepare_1 / force_1: their values bit for bit (tests/python/test_rig_truth.py). A class
    #: that writes a force law without saying so sends TruthDamper.step down the Context path.
    one_sample = False

    def prepare_1(self, p, dt: float, x: float, v: float, opening: float, state):
        """prepare_step on floats (p the TruthParams): (the opening the hydraulics see, new state)."""
        return opening, state

    def force_1(self, p, dt: float, x: float, v: float, state):
        """force_step on floats (p the TruthParams): (an additional force [N] or None, new state)."""
        return None, state

    # -- rig hooks -------------------------------------------------------
    def control(self, t: np.ndarray, voltage: np.ndarray, levels, rng) -> np.ndarray:
        """The control voltage [V] the rig applies during a test."""
        return voltage

    def initial_temperature(self, rng, run: float = 0.0) -> float | None:
        """The oil temperature [degC] at the start of a test; `run` in [0, 1] is its place in the run order."""
        return None

    def heating(self, t: np.ndarray, power_w: np.ndarray, t0_c: float):
        return None

    def run_order(self, n_tests: int, seed: int):
        """(rig) The order the plan's tests are run in (a permutation), None: the plan's order.
        The dataset lists its tests in run order."""
        return None


def _maximum(a: float, b: float) -> float:
    """np.maximum on two floats: NaN if either is (Python's max keeps a NaN only in first place)."""
    return a if a >= b or a != a else b


EFFECTS: dict[str, Effect] = {}


def register(cls):
    """Class decorator: add an instance of `cls` to EFFECTS under cls.name, an id of the effect
    catalogue (dampnet.effects) whose rig role is "switchable"; ValueError otherwise."""
    info = CATALOGUE.get(cls.name)
    if info is None or info.rig != "switchable":
        raise ValueError(f"rig effect {cls.name!r}: register it in the effect catalogue first "
                         "(dampnet.effects.register_effect with rig='switchable'); switchable ids: "
                         f"{', '.join(sorted(k for k, e in CATALOGUE.items() if e.rig == 'switchable'))}")
    EFFECTS[cls.name] = cls()
    return cls


def get_effect(e) -> Effect:
    """An Effect from a name in EFFECTS (or an Effect, returned as is); ValueError if unknown."""
    if isinstance(e, Effect):
        return e
    if e not in EFFECTS:
        info = CATALOGUE.get(e) if isinstance(e, str) else None
        why = f" ({e} is {info.rig_words()})" if info is not None else ""
        raise ValueError(f"unknown effect {e!r}{why}: expected one of {', '.join(sorted(EFFECTS))}")
    return EFFECTS[e]


@register
@dataclass
class GasSpring(Effect):
    """Polytropic gas spring: F = -(p(x) - p0) A_rod, p(x) = p0 (V0 / (V0 + A_rod x))^n.

    The charge (p0 = 200 psi at mid-stroke) sits in a V0 = 20 cm^3 chamber
    behind the floating piston (a 2-inch body with a short gas section);
    compression (x < 0) pushes the rod in and shrinks the gas volume by
    A_rod |x|. n = 1.4: at dyno frequencies the gas has no time to exchange
    heat (adiabatic nitrogen). Rate at mid-stroke n p0 A_rod^2 / V0 = 3.8 N/mm
    (with 1-2.5 MPa, 12-22 mm rods and 20-200 cm^3 of gas, monotubes span a
    fraction of a N/mm to over 10 N/mm), +74 N at full extension
    and -136 N at full compression of a +-1 inch stroke: progressive in
    compression, as the gas volume shrinks by a quarter. (Until 2026-11-21 the
    chamber was 40 cm^3, 1.9 N/mm: a spring that small is about the size of the
    network's own error, and adding it cut the held-out error by only 25-28 %.)
    """

    name = "gas_spring"
    gas_volume_m3: float = 20e-6
    polytropic_n: float = 1.4

    def force(self, ctx):
        p = ctx.params
        ar = p.rod_area_m2
        v = self.gas_volume_m3 + ar * ctx.x
        pressure = p.gas_pressure_pa * (self.gas_volume_m3 / v) ** self.polytropic_n
        return -(pressure - p.gas_pressure_pa) * ar

    one_sample = True

    def force_1(self, p, dt, x, v, state):
        ar = p.rod_area_m2
        r = self.gas_volume_m3 / (self.gas_volume_m3 + ar * x)
        n = self.polytropic_n
        # ndarray ** n, which for these exponents is not np.power (numpy's fast_scalar_power)
        rn = float((np.array([r]) ** n)[0]) if n in (-1.0, 0.0, 0.5, 1.0, 2.0) else float(np.power(r, n))
        return -(p.gas_pressure_pa * rn - p.gas_pressure_pa) * ar, state


@register
@dataclass
class Thermal(Effect):
    """Oil temperature varies between and within tests; viscosity, so laminar loss, falls with it.

    Between tests: each test starts at a temperature drawn uniformly from
    [25, 65] degC (a dyno session warms and cools the damper between runs,
    much wider than the thesis's 100 +- 2 degF). Within a test the oil heats by
    the dissipated power: C dT/dt = P(t) - h (T - T_amb), C = 500 J/K (oil and
    inner tube), h = 2 W/K, T_amb = 25 degC; a 3 Hz, 0 V test heats by a few
    kelvin. The rig evaluates the force at the starting temperature, integrates
    the heating from that power, then evaluates the force on T(t) (one
    fixed-point pass; the heating changes P by well under 1 %). The temperature
    is recorded as the `temperature_c` channel.
    """

    name = "thermal"
    varies_temperature = True
    records_temperature = True
    t_min_c: float = 25.0
    t_max_c: float = 65.0
    heat_capacity_j_k: float = 500.0
    loss_w_k: float = 2.0
    ambient_c: float = 25.0

    def initial_temperature(self, rng, run: float = 0.0):
        return float(rng.uniform(self.t_min_c, self.t_max_c))

    def heating(self, t, power_w, t0_c):
        """Temperature [degC] along t [s] (uniform step) for dissipated power [W] (last axis), from t0_c."""
        dt = float(t[1] - t[0])
        a = np.exp(-self.loss_w_k * dt / self.heat_capacity_j_k)
        target = self.ambient_c + np.asarray(power_w) / self.loss_w_k
        zi = a * np.asarray(t0_c, dtype=np.float64)[..., None]
        from scipy.signal import lfilter  # here, not at import: `dampnet --help` stays free of scipy

        y, _ = lfilter([1.0 - a], [1.0, -a], target, axis=-1, zi=zi)
        return y


@register
@dataclass
class ValveLag(Effect):
    """The solenoid valve's response: opening follows the static opening with a first-order lag.

    The SP10-24 goes from closed to fully open in about 40 ms (thesis ch. 3);
    a first-order lag reaches 95 % in 3 tau, so tau = 40/3 ms. In the rig the
    control voltage steps within each test every `step_period_s` between the
    test's nominal voltage and a level at least 2 V away.
    """

    name = "valve_lag"
    response_time_s: float = 0.040
    step_period_s: float = 0.5

    @property
    def tau_s(self) -> float:
        return self.response_time_s / 3.0

    def prepare(self, ctx):
        ctx.opening = first_order_lag(ctx.opening, ctx.dt, self.tau_s)

    def prepare_step(self, ctx, state):
        u = float(ctx.opening[0])
        if state is not None:
            a = np.exp(-ctx.dt / self.tau_s)
            u = a * state + (1.0 - a) * u
        ctx.opening = np.array([u])
        return u

    one_sample = True

    def prepare_1(self, p, dt, x, v, opening, state):
        u = opening
        if state is not None:
            a = float(np.exp(-dt / self.tau_s))
            u = a * state + (1.0 - a) * u
        return u, u

    def control(self, t, voltage, levels, rng):
        v0 = float(voltage[0])
        lo, hi = min(levels), max(levels)
        alt = hi if v0 - lo < hi - v0 else lo
        if abs(alt - v0) < 2.0:
            alt = min(hi, v0 + 2.0) if v0 + 2.0 <= hi else max(lo, v0 - 2.0)
        phase = np.floor((t - t[0]) / self.step_period_s).astype(int) % 2
        return np.where(phase == 0, v0, alt)


@register
@dataclass
class Friction(Effect):
    """Stick-slip seal friction (LuGre), replacing the smooth Coulomb seal friction.

    dz/dt = v - sigma0 |v| z / g(v),  g(v) = F_c + (F_s - F_c) exp(-(v/v_s)^2),
    F = sigma0 z + sigma1 dz/dt. Breakaway F_s = 110 N, sliding F_c = 40 N (the
    base model's level), Stribeck velocity v_s = 20 mm/s, bristle stiffness
    sigma0 = 1e6 N/m (0.1 mm pre-sliding), damping sigma1 = 50 N s/m: rod seals
    stick at reversals and break away with a force peak, and the force
    depends on displacement history, not only on velocity. Integrated exactly
    for v held over each sample. On 1-inch sines the breakaway peak is about
    108 N at 0.25 Hz and 56 N at 3 Hz (faster reversals leave less time to stick).
    """

    name = "friction"
    static_n: float = 110.0
    coulomb_n: float = 40.0
    stribeck_m_s: float = 0.020
    sigma0_n_m: float = 1e6
    sigma1_n_s_m: float = 50.0

    def _g(self, v):
        return self.coulomb_n + (self.static_n - self.coulomb_n) * np.exp(-(v / self.stribeck_m_s) ** 2)

    def _lugre(self, v, dt, z):
        """Advance bristle state z over dt at velocity v (arrays); return (z_new, force)."""
        av = np.abs(v)
        rate = self.sigma0_n_m * av / self._g(v)
        zss = np.where(av > 0, np.sign(v) * self._g(v) / self.sigma0_n_m, z)
        z_new = zss + (z - zss) * np.exp(-rate * dt)
        dz = (z_new - z) / dt
        return z_new, self.sigma0_n_m * z_new + self.sigma1_n_s_m * dz

    def _z0(self, v0):
        """Steady sliding state at the first sample's velocity (0 at rest)."""
        return np.sign(v0) * self._g(v0) / self.sigma0_n_m

    def _base(self, ctx):
        p = ctx.params
        return p.seal_friction_n * np.tanh(ctx.v / p.seal_friction_v_eps_m_s)

    def force(self, ctx):
        v = np.atleast_2d(ctx.v)
        n = v.shape[-1]
        z = self._z0(v[..., 0])
        out = np.empty_like(v)
        for k in range(n):
            z, out[..., k] = self._lugre(v[..., k], ctx.dt, z)
        return out.reshape(ctx.v.shape) - self._base(ctx)

    def force_step(self, ctx, state):
        z = self._z0(ctx.v) if state is None else np.array([state])
        z, f = self._lugre(ctx.v, ctx.dt, z)
        return f - self._base(ctx), float(z[0])

    one_sample = True

    def _g_1(self, v):
        w = v / self.stribeck_m_s
        return self.coulomb_n + (self.static_n - self.coulomb_n) * float(np.exp(-(w * w)))

    def force_1(self, p, dt, x, v, state):
        sign = 1.0 if v > 0 else -1.0 if v < 0 else 0.0 if v == 0 else v    # np.sign
        z = sign * self._g_1(v) / self.sigma0_n_m if state is None else state
        av = abs(v)
        rate = self.sigma0_n_m * av / self._g_1(v)
        zss = sign * self._g_1(v) / self.sigma0_n_m if av > 0 else z
        z_new = zss + (z - zss) * float(np.exp(-rate * dt))
        dz = (z_new - z) / dt
        f = self.sigma0_n_m * z_new + self.sigma1_n_s_m * dz
        return f - p.seal_friction_n * float(np.tanh(v / p.seal_friction_v_eps_m_s)), z_new


@register
@dataclass
class BumpStop(Effect):
    """Elastomer bump stop on the rod, engaging `travel_m` = 8 mm before full compression.

    F = -k d^2 max(1 - c v, 0) for penetration d = -(x + stroke/2 - travel) > 0:
    a progressive (quadratic) polyurethane stop, k = 4.7e7 N/m^2 (3 kN at
    8 mm), with c = 1 s/m hysteresis: stiffer while compressing (v < 0) than
    while releasing. Zero elsewhere in the stroke.
    """

    name = "bump_stop"
    travel_m: float = 0.008
    stiffness_n_m2: float = 4.7e7
    damping_s_m: float = 1.0

    def force(self, ctx):
        engage = -(ctx.params.stroke_m / 2.0 - self.travel_m)
        d = np.maximum(engage - ctx.x, 0.0)
        return -self.stiffness_n_m2 * d * d * np.maximum(1.0 - self.damping_s_m * ctx.v, 0.0)

    one_sample = True

    def force_1(self, p, dt, x, v, state):
        d = _maximum(-(p.stroke_m / 2.0 - self.travel_m) - x, 0.0)
        return -self.stiffness_n_m2 * d * d * _maximum(1.0 - self.damping_s_m * v, 0.0), state


@register
@dataclass
class MountHysteresis(Effect):
    """Bouc-Wen hysteresis of a rubber top mount (or eye bushing) in the load path.

    F = F_y z / x_y with dz/dx = 1 - |z / x_y|^n (1/2 + 1/2 sgn(dx z)) (Bouc-Wen, A = 1,
    beta = gamma): after a reversal z follows the travel one to one until it crosses zero, then
    saturates at +-x_y. Yield force F_y = 150 N, yield travel x_y = 4 mm, n = 2. Rate-independent:
    the same loop at every frequency and control, a function of the displacement history, not of
    velocity. Integrated exactly for the travel of each sample in a few sub-steps (explicit, the
    step is far below x_y). An additive element: a simplification of a mount in series (whose
    compliance would also delay the force); it keeps the rig's force a sum of parts.
    """

    name = "mount_hysteresis"
    yield_force_n: float = 150.0
    yield_travel_m: float = 0.004
    exponent: float = 2.0
    substeps: int = 4

    def _advance(self, z, dx):
        h = dx / self.substeps
        for _ in range(self.substeps):
            r = np.abs(z / self.yield_travel_m) ** self.exponent
            z = z + h * (1.0 - r * 0.5 * (1.0 + np.sign(h * z)))
        return z

    def force(self, ctx):
        x = np.atleast_2d(ctx.x)
        z = np.zeros(x.shape[:-1])
        out = np.empty_like(x)
        out[..., 0] = 0.0
        for k in range(1, x.shape[-1]):
            z = self._advance(z, x[..., k] - x[..., k - 1])
            out[..., k] = z
        return (self.yield_force_n / self.yield_travel_m * out).reshape(np.shape(ctx.x))

    def force_step(self, ctx, state):
        x = float(ctx.x[0])
        z = 0.0 if state is None else float(self._advance(state[0], x - state[1]))
        return np.array([self.yield_force_n / self.yield_travel_m * z]), (z, x)

    one_sample = True

    def force_1(self, p, dt, x, v, state):
        z = 0.0 if state is None else float(self._advance(state[0], x - state[1]))
        return self.yield_force_n / self.yield_travel_m * z, (z, x)


@register
@dataclass
class CampaignWarming(Thermal):
    """The oil warms along the campaign's run order, and the rig logs no temperature.

    The campaign runs the plan in a random order (seeded by the rig's seed, as a lab that randomises
    its run order does; the dataset lists the tests in run order). The k-th test of N run starts at
    t_min_c + (t_max_c - t_min_c) k / (N - 1) (25 -> 65 degC over the campaign: the damper is run
    hot test after test), then heats within the test as `thermal`. No temperature channel is
    recorded: the thermal candidate cannot see differences between tests, so the diagnosis must
    find the drift over the run order. (Run in the plan's order, the warming would be a function of
    frequency and control, which a model learns and no test can tell from physics: only a random
    order or a repeated reference test reveals a drift.)
    """

    name = "campaign_warming"
    records_temperature = False

    def initial_temperature(self, rng, run: float = 0.0):
        return float(self.t_min_c + (self.t_max_c - self.t_min_c) * run)

    def run_order(self, n_tests, seed):
        return np.random.default_rng([int(seed), 7919]).permutation(n_tests)
