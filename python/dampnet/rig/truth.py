"""The truth damper: a physical model of a 2-inch monotube with an external bypass valve.

The damper of the reference thesis (chapter 3): a Fox 2.0 monotube (Chevrolet
Silverado rear), converted to an electro-hydraulic semi-active damper by an
external bypass between the chambers through a HydraForce SP10-24 proportional
solenoid valve, driven by an EVDR controller (0-5 V in -> 0.02-1.18 A out,
Table 2), nitrogen charge 200 psi. Force F [N] is positive when the damper
resists extension; x [m], v [m/s] positive in extension, x = 0 at mid-stroke.

    F = F_h(v_h, u, T) + F_seal(v) + F_gas + sum(effect forces)

1. Hydraulics, per direction (rebound v_h > 0, compression v_h < 0), with
   flow Q = A_ann |v_h| [m^3/s] through the piston valve and the bypass in parallel:

       Q = Cd * A(dp) * sqrt(2 dp / rho),  A(dp) = A_bleed + u * A_bypass + k_shim * max(dp - p_crack, 0)

   a fixed bleed orifice (quadratic, progressive at low speed), the bypass
   opening u in [0, 1], and a shim stack that cracks open at p_crack and
   opens in proportion to the excess pressure (blow-off knee, digressive
   above it: dp ~ Q^(2/3)). In series, a laminar passage loss R_lam(T) Q
   whose resistance scales with oil viscosity. F_h = sign(v_h) (dp + R_lam Q) A_ann.
   Rebound is stiffer than compression (smaller bleed, higher crack pressure),
   as the thesis found ("tuned for slow rebound"). Values: Cd = 0.7 and
   rho = 870 kg/m^3 (mineral damper oil); piston 46 mm, rod 5/8 in (Fox 2.0
   internals); bleeds 3.7 / 6.2 mm^2 (rebound / compression), crack pressures
   0.6 / 0.3 MPa, shim gains 1.2e-11 / 6.7e-11 m^2/Pa, laminar resistance
   4e8 Pa s/m^3. With the valve closed (0 V) these give about 360 / 150 N at
   0.04 m/s (1 inch, 0.25 Hz) and 2.8 / 1.3 kN at 0.48 m/s (1 inch, 3 Hz), the
   range of a light-truck rear damper and of the thesis's Table 4 errors.

2. Control: voltage V -> controller current i by Table 2 (piecewise linear,
   0 V -> 20 mA ... 5 V -> 1180 mA); current -> opening u = clip((i - i_crack) /
   (i_full - i_crack), 0, 1) with i_crack = 20 mA, i_full = 1.18 A (the SP10-24
   is normally closed and proportional up to 1.2 A). A_bypass = 32 mm^2 at
   full opening (a 7 gpm valve), which brings rebound force at 3 Hz from 2.8
   to 0.9 kN: voltage lowers damping, most in rebound, as the thesis found
   (equation (2), and "especially during rebound").

3. Oil compressibility: the chamber pressure builds through the oil's
   effective bulk modulus (with entrained gas and seal/tube compliance,
   beta_eff ~ 0.3 GPa), so force lags velocity. Linearised about mid-range
   operation, tau = V_chamber / beta_eff * d(dp)/dQ ~ 3e-4 m^3 / 0.3 GPa *
   2e9 Pa s/m^3 = 2 ms: the hydraulics see v_h, a first-order lag of v
   (exact discretisation, v_h[k] = a v_h[k-1] + (1 - a) v[k], a = exp(-dt/tau)).

4. Seal friction: F_seal = F_c tanh(v / v_eps), F_c = 40 N (rod seal, wiper,
   piston band of a 2-inch shock), v_eps = 2 mm/s. The `friction` effect
   replaces it with a stick-slip (LuGre) model.

5. Gas preload: F_gas = -p0 A_rod = -273 N (p0 = 200 psi = 1.379 MPa on a
   5/8 in rod): the charge pushes the rod out. The `gas_spring` effect adds
   the position dependence.

6. Temperature: viscosity mu(T) = mu_ref exp(B (1/T - 1/T_ref)), B = 3000 K
   (damper oils lose about half their viscosity per 20 K), T_ref = 37.8 degC
   (the thesis's 100 degF test temperature); R_lam scales with mu.
   Without a temperature input the damper is at T_ref.

`truth_force` is vectorised over time (last axis, possibly a batch of
equal-length tests); `TruthDamper.step` is its stateful, one-sample form
and reproduces it sample for sample.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import asdict, dataclass

import numpy as np

from dampnet.features import first_order_lag
from dampnet.rig.context import Context
from dampnet.rig.effects import Effect, get_effect

PSI = 6894.757293168
INCH = 0.0254

#: Table 2 of the thesis: controller input voltage [V] -> controller output current [A].
TABLE2_VOLTAGE_V = (0.0, 0.5, 1.0, 1.25, 1.5, 1.75, 2.0, 2.25, 2.5, 2.75, 3.0, 3.5, 4.0, 4.5, 5.0)
TABLE2_CURRENT_A = (0.020, 0.050, 0.100, 0.130, 0.165, 0.195, 0.240, 0.290, 0.335, 0.410, 0.440,
                    0.585, 0.730, 0.890, 1.180)


@dataclass
class TruthParams:
    """Parameters of the truth damper (SI units; see the module doc for why these values)."""

    piston_diameter_m: float = 0.046
    rod_diameter_m: float = 0.625 * INCH
    stroke_m: float = 2.0 * INCH
    oil_density_kg_m3: float = 870.0
    discharge_coefficient: float = 0.7
    bleed_area_rebound_m2: float = 3.7e-6
    bleed_area_compression_m2: float = 6.2e-6
    crack_pressure_rebound_pa: float = 0.6e6
    crack_pressure_compression_pa: float = 0.3e6
    shim_gain_rebound_m2_pa: float = 1.2e-11      # added area per pascal above p_crack
    shim_gain_compression_m2_pa: float = 6.7e-11
    laminar_resistance_pa_s_m3: float = 4.0e8     # at temperature_ref_c
    bypass_area_max_m2: float = 32e-6
    controller_voltage_v: tuple = TABLE2_VOLTAGE_V
    controller_current_a: tuple = TABLE2_CURRENT_A
    valve_crack_current_a: float = 0.020
    valve_full_current_a: float = 1.180
    compressibility_tau_s: float = 0.002
    seal_friction_n: float = 40.0
    seal_friction_v_eps_m_s: float = 0.002
    gas_pressure_pa: float = 200.0 * PSI
    temperature_ref_c: float = 37.8
    viscosity_b_k: float = 3000.0

    @property
    def piston_area_m2(self) -> float:
        return np.pi / 4 * self.piston_diameter_m ** 2

    @property
    def rod_area_m2(self) -> float:
        return np.pi / 4 * self.rod_diameter_m ** 2

    @property
    def annulus_area_m2(self) -> float:
        return self.piston_area_m2 - self.rod_area_m2

    def to_dict(self) -> dict:
        d = asdict(self)
        d["controller_voltage_v"] = list(self.controller_voltage_v)
        d["controller_current_a"] = list(self.controller_current_a)
        return d


def controller_current(voltage, p: TruthParams) -> np.ndarray:
    """Controller output current [A] for input voltage [V] (Table 2, piecewise linear, clipped)."""
    return np.interp(voltage, p.controller_voltage_v, p.controller_current_a)


def valve_opening(current, p: TruthParams) -> np.ndarray:
    """Static bypass valve opening in [0, 1] for solenoid current [A]."""
    # minimum/maximum, not np.clip: the same on arrays, and a fifth of its cost on the one float
    # TruthDamper.step passes per sample
    u = (np.asarray(current) - p.valve_crack_current_a) / (p.valve_full_current_a - p.valve_crack_current_a)
    return np.minimum(np.maximum(u, 0.0), 1.0)


def viscosity_ratio(temperature_c, p: TruthParams) -> np.ndarray:
    """mu(T) / mu(T_ref) (Andrade): exp(B (1/T - 1/T_ref)), T in kelvin."""
    tk = np.asarray(temperature_c, dtype=np.float64) + 273.15
    return np.exp(p.viscosity_b_k * (1.0 / tk - 1.0 / (p.temperature_ref_c + 273.15)))


def seal_friction(v, p: TruthParams):
    """Seal friction [N] at velocity v [m/s]: F_c tanh(v / v_eps) (arrays or one float)."""
    return p.seal_friction_n * np.tanh(v / p.seal_friction_v_eps_m_s)


def gas_preload(p: TruthParams) -> float:
    """Gas preload [N]: the charge pressure on the rod, pushing it out."""
    return -p.gas_pressure_pa * p.rod_area_m2


def orifice_pressure(q, area0, k_shim, p_crack, p: TruthParams) -> np.ndarray:
    """Pressure drop [Pa] for flow q >= 0 [m^3/s] through area0 [m^2] plus a shim stack (vectorised Newton).

    Solves q = c s (area0 + k (s^2 - p_crack)+), s = sqrt(dp), c = Cd sqrt(2/rho):
    increasing and convex in s, so Newton from an upper bound converges monotonically.
    """
    q = np.asarray(q, dtype=np.float64)
    area0, k_shim, p_crack = (np.broadcast_to(np.asarray(a, dtype=np.float64), q.shape)
                              for a in (area0, k_shim, p_crack))
    c = p.discharge_coefficient * np.sqrt(2.0 / p.oil_density_kg_m3)
    s = q / (c * area0)                                   # shims closed
    open_ = s * s > p_crack
    if np.any(open_):
        qo, a0, k, pc = q[open_], area0[open_], k_shim[open_], p_crack[open_]
        sc = np.cbrt(qo / (c * k)) + np.sqrt(pc)          # an upper bound when shims dominate
        so = np.minimum(s[open_], sc)
        for _ in range(100):
            ex = np.maximum(so * so - pc, 0.0)
            g = c * so * (a0 + k * ex) - qo
            dg = c * (a0 + k * ex) + 2.0 * c * k * so * so * (ex > 0)
            step = g / dg
            so = so - step
            if np.all(np.abs(step) <= 1e-12 * so):
                break
        s = s.copy()
        s[open_] = so
    return s * s


def hydraulic_force(v_h, opening, temperature_c, p: TruthParams) -> np.ndarray:
    """Hydraulic force [N] for lagged velocity v_h [m/s], bypass opening [0..1], temperature [degC]."""
    v_h = np.asarray(v_h, dtype=np.float64)
    opening = np.broadcast_to(np.asarray(opening, dtype=np.float64), v_h.shape)
    reb = v_h >= 0
    q = p.annulus_area_m2 * np.abs(v_h)
    a0 = np.where(reb, p.bleed_area_rebound_m2, p.bleed_area_compression_m2) + opening * p.bypass_area_max_m2
    k = np.where(reb, p.shim_gain_rebound_m2_pa, p.shim_gain_compression_m2_pa)
    pc = np.where(reb, p.crack_pressure_rebound_pa, p.crack_pressure_compression_pa)
    dp = orifice_pressure(q, a0, k, pc, p)
    dp_lam = p.laminar_resistance_pa_s_m3 * viscosity_ratio(temperature_c, p) * q
    return np.sign(v_h) * (dp + dp_lam) * p.annulus_area_m2


def _controller_current_1(voltage: float, xp: tuple, fp: tuple) -> float:
    """controller_current of one float (np.interp with xp, fp as floats), bit for bit: numpy's C
    loop (compiled_base.c, arr_interp) for one point, without numpy's per-call cost."""
    if voltage != voltage:
        return voltage
    j = bisect.bisect_right(xp, voltage) - 1       # xp[j] <= voltage < xp[j + 1]
    if j < 0:
        return fp[0]
    if j >= len(xp) - 1:
        return fp[-1]
    if xp[j] == voltage:
        return fp[j]
    slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
    out = slope * (voltage - xp[j]) + fp[j]
    if out != out:                                 # as numpy: nan one way, try the other
        out = slope * (voltage - xp[j + 1]) + fp[j + 1]
        if out != out and fp[j] == fp[j + 1]:
            out = fp[j]
    return out


def _hydraulic_force_1(v_h: float, opening: float, temperature_c: float, p: TruthParams,
                       viscosity: float | None = None) -> float:
    """hydraulic_force (with orifice_pressure's Newton) for one sample, in Python floats.

    TruthDamper.step's path: a loop calls it once per corner per step, where numpy's per-call
    overhead on 1-element arrays was 170 us a step (60 s of a full-car study); the step is about 7
    times faster (bench/experiments/truth_step.py). The same law and the same iteration as the
    vectorised form (orifice_pressure's Newton is the one part written twice: masked arrays there,
    one float here), which tests/python/test_rig_truth.py holds it to (rtol 1e-9).
    viscosity: viscosity_ratio(temperature_c, p) if the caller has it."""
    reb = v_h >= 0
    q = p.annulus_area_m2 * abs(v_h)
    a0 = (p.bleed_area_rebound_m2 if reb else p.bleed_area_compression_m2) + opening * p.bypass_area_max_m2
    k = p.shim_gain_rebound_m2_pa if reb else p.shim_gain_compression_m2_pa
    pc = p.crack_pressure_rebound_pa if reb else p.crack_pressure_compression_pa
    c = p.discharge_coefficient * math.sqrt(2.0 / p.oil_density_kg_m3)
    s = q / (c * a0)                                      # shims closed
    if s * s > pc:
        s = min(s, math.cbrt(q / (c * k)) + math.sqrt(pc))
        for _ in range(100):
            ex = max(s * s - pc, 0.0)
            g = c * s * (a0 + k * ex) - q
            dg = c * (a0 + k * ex) + (2.0 * c * k * s * s if ex > 0 else 0.0)
            step = g / dg
            s -= step
            if abs(step) <= 1e-12 * s:
                break
    if viscosity is None:
        viscosity = float(viscosity_ratio(temperature_c, p))
    dp_lam = p.laminar_resistance_pa_s_m3 * viscosity * q
    return math.copysign(1.0, v_h) * (s * s + dp_lam) * p.annulus_area_m2 if v_h != 0 else 0.0


def _context(x, v, voltage, temperature, dt, p):
    x = np.asarray(x, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    voltage = np.broadcast_to(np.asarray(voltage, dtype=np.float64), v.shape)
    temp = np.broadcast_to(np.asarray(p.temperature_ref_c if temperature is None else temperature,
                                      dtype=np.float64), v.shape)
    cur = controller_current(voltage, p)
    return Context(x=x, v=v, voltage=voltage, temperature=temp, dt=float(dt), params=p,
                   current=cur, opening=valve_opening(cur, p))


def _resolve(effects):
    return [get_effect(e) for e in effects]


def base_force(ctx: Context) -> np.ndarray:
    """Hydraulic + seal friction + gas preload [N]; fills ctx.parts."""
    p = ctx.params
    ctx.parts["hydraulic"] = hydraulic_force(ctx.v_h, ctx.opening, ctx.temperature, p)
    ctx.parts["seal_friction"] = seal_friction(ctx.v, p)
    ctx.parts["gas_preload"] = np.full(ctx.v.shape, gas_preload(p))
    return ctx.parts["hydraulic"] + ctx.parts["seal_friction"] + ctx.parts["gas_preload"]


def truth_force(displacement, velocity, voltage, temperature=None, *, dt: float,
                params: TruthParams | None = None, effects=(), return_parts: bool = False):
    """Noise-free damper force [N] from time series (time along the last axis, uniform step dt [s]).

    displacement [m], velocity [m/s] (positive in extension), voltage [V]
    (the controller input), temperature [degC] (None: T_ref). `effects` are
    names in EFFECTS or Effect objects; the stateful parts (oil-compressibility
    lag, valve lag, stick-slip friction) start in steady state at the first sample.
    With return_parts, also returns {component name: force [N]}.
    """
    p = params or TruthParams()
    effs = _resolve(effects)
    ctx = _context(displacement, velocity, voltage, temperature, dt, p)
    for e in effs:
        e.prepare(ctx)                      # e.g. valve lag filters ctx.opening
    ctx.v_h = first_order_lag(ctx.v, ctx.dt, p.compressibility_tau_s)
    f = base_force(ctx)
    for e in effs:
        fe = e.force(ctx)
        if fe is not None:
            ctx.parts[e.name] = fe
            f = f + fe
    return (f, ctx.parts) if return_parts else f


_LAW = ("prepare", "prepare_step", "force", "force_step")


def _one_sample(effect: Effect) -> bool:
    """Whether TruthDamper.step may run `effect` by its float forms (prepare_1, force_1): every
    class of it that writes a force law says it wrote them too (one_sample = True in its body)."""
    return all(vars(k).get("one_sample", False) for k in type(effect).__mro__
               if k is not Effect and any(name in vars(k) for name in _LAW))


class TruthDamper:
    """The truth damper, one sample at a time, for a loop (a quarter-car model).

    `step(dt, x, v, voltage, temperature=None) -> force [N]` reproduces
    `truth_force` sample for sample when called with the same series.
    """

    def __init__(self, params: TruthParams | None = None, effects=()):
        self.params = params or TruthParams()
        self.effects = _resolve(effects)
        self.reset()

    def reset(self) -> None:
        self._v_h = None
        self._states = {e.name: None for e in self.effects}
        self._floats = all(_one_sample(e) for e in self.effects)   # step's float path
        self._table = None          # (voltage, current tuples as given, as floats)
        self._viscosity = None      # (temperature [degC], viscosity_ratio there)

    def step(self, dt: float, x: float, v: float, voltage: float, temperature: float | None = None) -> float:
        """Force [N] at displacement x [m], velocity v [m/s], control voltage [V], temperature [degC]."""
        if self._floats:
            return self._step_floats(dt, x, v, voltage, temperature)
        return self._step_context(dt, x, v, voltage, temperature)

    def _step_floats(self, dt, x, v, voltage, temperature) -> float:
        """step in Python floats (numpy's ufuncs only where math's differ: tanh, exp, power):
        bit for bit _step_context's force (tests/python/test_rig_truth.py), 3-5 times faster:
        14 -> 4.6 us a call without effects, 20 -> 6.2 with the gas spring, 33 -> 6.2 with friction."""
        p = self.params
        dt, x, v = float(dt), float(x), float(v)
        temp = p.temperature_ref_c if temperature is None else float(temperature)
        table = self._table
        if table is None or table[0] is not p.controller_voltage_v or table[1] is not p.controller_current_a:
            table = (p.controller_voltage_v, p.controller_current_a,
                     tuple(float(a) for a in np.asarray(p.controller_voltage_v, dtype=np.float64)),
                     tuple(float(a) for a in np.asarray(p.controller_current_a, dtype=np.float64)))
            if isinstance(p.controller_voltage_v, tuple) and isinstance(p.controller_current_a, tuple):
                self._table = table               # lists may change in place: converted each step
        current = _controller_current_1(float(voltage), table[2], table[3])
        u = (current - p.valve_crack_current_a) / (p.valve_full_current_a - p.valve_crack_current_a)
        opening = min(max(u, 0.0), 1.0) if u == u else u
        states = self._states
        effects = self.effects
        for e in effects:
            opening, states[e.name] = e.prepare_1(p, dt, x, v, opening, states[e.name])
        if self._v_h is None or p.compressibility_tau_s <= 0:
            self._v_h = v
        else:
            a = math.exp(-dt / p.compressibility_tau_s)
            self._v_h = a * self._v_h + (1.0 - a) * v
        visc = self._viscosity
        if visc is None or visc[0] != temp:
            visc = self._viscosity = (temp, float(viscosity_ratio(temp, p)))
        f = (_hydraulic_force_1(self._v_h, opening, temp, p, visc[1])
             + float(seal_friction(v, p)) + gas_preload(p))
        for e in effects:
            fe, states[e.name] = e.force_1(p, dt, x, v, states[e.name])
            if fe is not None:
                f += fe
        return f

    def _step_context(self, dt, x, v, voltage, temperature) -> float:
        """step through a Context of 1-element arrays and the effects' prepare_step / force_step."""
        p = self.params
        temp = p.temperature_ref_c if temperature is None else float(temperature)
        current = float(controller_current(voltage, p))
        opening = float(valve_opening(current, p))
        ctx = Context(x=np.array([float(x)]), v=np.array([float(v)]), voltage=np.array([float(voltage)]),
                      temperature=np.array([temp]), dt=float(dt), params=p, current=np.array([current]),
                      opening=np.array([opening]))
        for e in self.effects:
            self._states[e.name] = e.prepare_step(ctx, self._states[e.name])
        if self._v_h is None or p.compressibility_tau_s <= 0:
            self._v_h = float(v)
        else:
            a = math.exp(-dt / p.compressibility_tau_s)
            self._v_h = a * self._v_h + (1.0 - a) * float(v)
        ctx.v_h = np.array([self._v_h])
        # base_force, one sample: hydraulics + seal friction + gas preload (the parts the effects may read)
        hydraulic = _hydraulic_force_1(self._v_h, float(ctx.opening[0]), temp, p)
        seal = float(seal_friction(float(v), p))
        gas = gas_preload(p)
        ctx.parts.update(hydraulic=np.array([hydraulic]), seal_friction=np.array([seal]), gas_preload=np.array([gas]))
        f = hydraulic + seal + gas
        for e in self.effects:
            fe, self._states[e.name] = e.force_step(ctx, self._states[e.name])
            if fe is not None:
                f += float(np.asarray(fe).reshape(-1)[0])
        return f
