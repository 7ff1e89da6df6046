"""The full vehicle's linear model: mass, damping and stiffness matrices of its vertical motion
(heave, roll, pitch and the four wheel hops), its state space, its modes, and the closed forms of
steady-state cornering (linear bicycle model, roll gradient).

Derived here from the vehicle's energies, independently of the runtime's force-by-force code
(cpp/include/dampnet/fullcar.hpp), so each is a check of the other. Coordinates
q = [z, phi, theta, z_us_fl, z_us_fr, z_us_rl, z_us_rr] (m, rad, rad, m...), from static
equilibrium; the dampers linear, c [N s/m] per corner; speed 0 (no lateral motion). With the
suspension deflection d_i = z + y_i phi - x_i theta - z_us,i = J_i q:

  V = sum_i k_s,i d_i^2 / 2 + sum_axles k_arb (d_l - d_r)^2 / 2 + sum_i k_t (z_us,i - z_r,i)^2 / 2
      - m_s g h phi^2 / 2                                   (gravity about the roll axis)
  R = sum_i c_i (d_i')^2 / 2 + sum_i c_t (z_us,i' - z_r,i')^2 / 2
  T = (m_s z'^2 + i_xx phi'^2 + i_yy theta'^2 + sum_i m_us,i z_us,i'^2) / 2
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dampnet import _core
from dampnet.sim.full_car.params import cg_to_axles

#: names of the coordinates q
COORDINATES = ("z", "phi", "theta", "z_us_fl", "z_us_fr", "z_us_rl", "z_us_rr")


def full_params(params: dict | None = None) -> dict:
    """The runtime's defaults (FULLCAR_FIELDS) updated with params."""
    p = {k: v[0] for k, v in _core.FULLCAR_FIELDS.items()}
    p.update(params or {})
    return p


def corner_positions(p: dict) -> tuple[np.ndarray, np.ndarray]:
    """x_i, y_i [m] of the corners FL, FR, RL, RR (x forward from the CG, y left)."""
    x = np.array([p["a"], p["a"], -p["b"], -p["b"]], dtype=float)
    y = np.array([p["t_f"], -p["t_f"], p["t_r"], -p["t_r"]], dtype=float) / 2
    return x, y


def roll_arm(p: dict) -> float:
    """h [m]: the sprung CG's height above the roll axis."""
    L = p["a"] + p["b"]
    return p["h_cg"] - (p["b"] * p["h_rc_f"] + p["a"] * p["h_rc_r"]) / L


@dataclass(frozen=True)
class VerticalModel:
    """M q'' + C q' + K q = Bz z_r + Bv z_r' (z_r: the road under the four wheels)."""

    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    Bz: np.ndarray
    Bv: np.ndarray

    def state_space(self) -> tuple[np.ndarray, np.ndarray]:
        """(A, B) of x = [q, q'] with the road displacement as input (valid with c_t = 0,
        where the road rate does not enter)."""
        n = self.M.shape[0]
        Minv = np.linalg.inv(self.M)
        A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ self.K, -Minv @ self.C]])
        B = np.vstack([np.zeros((n, 4)), Minv @ self.Bz])
        return A, B

    def modes(self) -> tuple[np.ndarray, np.ndarray]:
        """Natural frequencies [Hz] and damping ratios [-] of the seven modes, by frequency."""
        A, _ = self.state_space()
        lam = np.linalg.eigvals(A)
        lam = lam[lam.imag > 0]  # one of each conjugate pair (all modes underdamped here)
        order = np.argsort(np.abs(lam))
        lam = lam[order]
        return np.abs(lam) / (2 * np.pi), -lam.real / np.abs(lam)

    def energy(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """T + V [J] with the road at 0, for rows of q, q'."""
        q, qd = np.atleast_2d(q), np.atleast_2d(qd)
        return 0.5 * np.einsum("ni,ij,nj->n", qd, self.M, qd) + 0.5 * np.einsum("ni,ij,nj->n", q, self.K, q)


def vertical_model(params: dict | None = None, damping: float | np.ndarray = 0.0,
                   stiffness: float | np.ndarray = 0.0, inertance: float | np.ndarray = 0.0) -> VerticalModel:
    """The matrices for the parameters (defaults: the runtime's) and linear dampers of
    damping [N s/m] (one value, or one per corner); a damper's equivalent linear element may also
    carry a stiffness [N/m] and an inertance [kg] (force per relative acceleration) in parallel."""
    p = full_params(params)
    x, y = corner_positions(p)
    c = np.broadcast_to(np.asarray(damping, dtype=float), (4,))
    ks = np.array([p["k_s_f"], p["k_s_f"], p["k_s_r"], p["k_s_r"]])
    m_us = np.array([p["m_us_f"], p["m_us_f"], p["m_us_r"], p["m_us_r"]])
    J = np.zeros((4, 7))  # d = J q
    for i in range(4):
        J[i, :3] = [1.0, y[i], -x[i]]
        J[i, 3 + i] = -1.0
    K = sum(ks[i] * np.outer(J[i], J[i]) for i in range(4))
    C = sum(c[i] * np.outer(J[i], J[i]) for i in range(4))
    kd = np.broadcast_to(np.asarray(stiffness, dtype=float), (4,))
    bd = np.broadcast_to(np.asarray(inertance, dtype=float), (4,))
    K = K + sum(kd[i] * np.outer(J[i], J[i]) for i in range(4))
    for axle, k_arb in ((0, p["k_arb_f"]), (1, p["k_arb_r"])):
        Jd = J[2 * axle] - J[2 * axle + 1]
        K = K + k_arb * np.outer(Jd, Jd)
    W = np.zeros((4, 7))  # wheel coordinates
    W[np.arange(4), 3 + np.arange(4)] = 1.0
    K = K + p["k_t"] * W.T @ W
    C = C + p["c_t"] * W.T @ W
    K[1, 1] -= p["m_s"] * p["g"] * roll_arm(p)
    M = np.diag([p["m_s"], p["i_xx"], p["i_yy"], *m_us]) + sum(bd[i] * np.outer(J[i], J[i]) for i in range(4))
    return VerticalModel(M=M, C=C, K=K, Bz=p["k_t"] * W.T, Bv=p["c_t"] * W.T)


def tyre_cornering_stiffness(p: dict) -> np.ndarray:
    """K(N0_i) [N/rad] of the four tyres at their static loads (the linear tyre's)."""
    L = p["a"] + p["b"]
    m_corner = p["m_s"] * np.array([p["b"], p["b"], p["a"], p["a"]]) / (2 * L)
    m_us = np.array([p["m_us_f"], p["m_us_f"], p["m_us_r"], p["m_us_r"]])
    n0 = p["g"] * (m_corner + m_us)
    fz0 = p["tyre_fz0"]
    return p["tyre_pky1"] * fz0 * np.sin(2 * np.arctan(n0 / (p["tyre_pky2"] * fz0)))


def bicycle(params: dict | None = None) -> dict:
    """The linear bicycle model's steady state: axle cornering stiffnesses C_f, C_r [N/rad],
    understeer gradient K [rad/(m/s^2)] (delta = L / R + K a_y) and yaw-rate gain r / delta
    [1/s] at the parameters' speed. The whole car's mass at its CG (a_h, b_h [m] from the axles:
    the axle loads' split of the weight, unsprung masses at the axles), as the static loads."""
    p = full_params(params)
    ks = tyre_cornering_stiffness(p)
    Cf, Cr = ks[0] + ks[1], ks[2] + ks[3]
    m = p["m_s"] + 2 * p["m_us_f"] + 2 * p["m_us_r"]
    L = p["a"] + p["b"]
    a_h, b_h = cg_to_axles(p)
    K = m / L * (b_h / Cf - a_h / Cr)
    U = p["speed"]
    return {"C_f": Cf, "C_r": Cr, "a_h": a_h, "b_h": b_h, "understeer_gradient": K,
            "yaw_rate_gain": U / (L + K * U**2)}


def roll_gradient(params: dict | None = None) -> float:
    """Steady-state body roll per lateral acceleration [rad/(m/s^2)] of the roll-axis model.

    Per axle (track t, roll-centre height h_rc, lateral force Fy = m a_y b/L front, m a_y a/L
    rear): suspension roll stiffness K_s = (k_s + 2 k_arb) t^2 / 2, tyre roll stiffness
    K_t = k_t t^2 / 2. The axle's roll w (wheels' height difference / t) balances
    K_t w = K_s (phi - w) + Fy h_rc (tyres carry the suspension's moment and the links'
    transfer), and the body sum_axles K_s (phi - w) = m_s h a_y + m_s g h phi. Eliminating w:
      phi / a_y = (m_s h + sum K_s / (K_s + K_t) Fy / a_y h_rc) / (sum K_s K_t / (K_s + K_t) - m_s g h)
    """
    p = full_params(params)
    L = p["a"] + p["b"]
    m = p["m_s"] + 2 * p["m_us_f"] + 2 * p["m_us_r"]
    h = roll_arm(p)
    num, den = p["m_s"] * h, -p["m_s"] * p["g"] * h
    for t, k_s, k_arb, h_rc, share in ((p["t_f"], p["k_s_f"], p["k_arb_f"], p["h_rc_f"], p["b"] / L),
                                       (p["t_r"], p["k_s_r"], p["k_arb_r"], p["h_rc_r"], p["a"] / L)):
        Ks, Kt = (k_s + 2 * k_arb) * t**2 / 2, p["k_t"] * t**2 / 2
        num += Ks / (Ks + Kt) * m * share * h_rc
        den += Ks * Kt / (Ks + Kt)
    return num / den


#: the road patterns of the bounce sine sweep (FL, FR, RL, RR): all in phase, rear against front
ROAD_PATTERNS = {"heave": np.array([1.0, 1.0, 1.0, 1.0]), "pitch": np.array([1.0, 1.0, -1.0, -1.0])}


def road_response(freqs: np.ndarray, params: dict | None = None, damping: float | np.ndarray = 0.0,
                  pattern: str = "heave", stiffness: float = 0.0, inertance: float = 0.0) -> dict:
    """Frequency responses [per metre of road] of the linear vertical model to the road under the
    four wheels in `pattern` (ROAD_PATTERNS), at freqs [Hz]: {"z": heave at the CG [m/m], "phi",
    "theta" [rad/m], "wheel": the four wheels' mean height [m/m] (front and rear with the
    pattern's sign)}, complex. H(jw) = C (jw I - A)^-1 B u by a complex solve (c_t = 0 assumed
    by state_space; with c_t > 0 its road-rate input is added). stiffness, inertance: of each
    damper's equivalent linear element (vertical_model)."""
    p = full_params(params)
    vm = vertical_model(p, damping, stiffness, inertance)
    n = vm.M.shape[0]
    Minv = np.linalg.inv(vm.M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ vm.K, -Minv @ vm.C]])
    u = ROAD_PATTERNS[pattern]
    out = {k: np.zeros(len(freqs), dtype=complex) for k in ("z", "phi", "theta", "wheel")}
    for j, f in enumerate(np.asarray(freqs, dtype=float)):
        jw = 2j * np.pi * f
        rhs = np.concatenate([np.zeros(n), Minv @ (vm.Bz + jw * vm.Bv) @ u])
        x = np.linalg.solve(jw * np.eye(2 * n) - A, rhs)
        out["z"][j], out["phi"][j], out["theta"][j] = x[0], x[1], x[2]
        out["wheel"][j] = np.mean(x[3:7] * u)
    return out

