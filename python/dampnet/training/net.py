"""The MLP as a flat parameter vector: forward pass, analytic Jacobian, initialisation.

Training works on one float64 vector `x` holding every weight, in the order
w1 [h1, n_in] (row-major), b1 [h1], (w2 [h2, h1], b2 [h2]), w_out [n_last], b_out [1]
— PyTorch's [out][in] layout, so unpacking gives `MlpModel` fields directly.
Inputs and output are in mapminmax-scaled units ([-1, 1] over the training range).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from dampnet.model import ACTIVATIONS

DTYPE = torch.float64


def act(z: torch.Tensor, kind: str) -> torch.Tensor:
    """Hidden activation: 'tanh' (MATLAB tansig) or 'sigmoid' (logsig). z is a fresh
    pre-activation the caller no longer needs: without autograd, tanh overwrites it."""
    if kind != "tanh":
        return torch.sigmoid(z)
    if z.requires_grad or z.dtype != torch.float64:
        return torch.tanh(z)
    # numpy's SIMD float64 tanh, in place on the tensor's memory: 4.8x faster than torch's on one
    # thread (a [20000, 30] array: 1.2 against 5.7 ms), within 1 ulp of it
    # (test_train_net.py); with torch's, tanh took 2.5 s of a 7.6 s LM training (cProfile, the
    # first training of test_diagnose_hidden.py's gas_spring case)
    a = z.numpy()
    np.tanh(a, out=a)
    return z


def act_deriv(a: torch.Tensor, kind: str) -> torch.Tensor:
    """Derivative of the activation written in terms of its output a = act(z)."""
    return 1.0 - a * a if kind == "tanh" else a * (1.0 - a)


@dataclass(frozen=True)
class Layout:
    """Sizes of an n_in-h1(-h2)-1 MLP and where each tensor sits in the flat vector."""

    n_in: int
    hidden: tuple[int, ...]
    activation: str  # one of dampnet.model.ACTIVATIONS

    def __post_init__(self) -> None:
        if len(self.hidden) not in (1, 2) or min(self.hidden) < 1:
            raise ValueError(f"hidden: one or two layers of >= 1 neurons expected, got {self.hidden}")
        if self.activation not in ACTIVATIONS:
            raise ValueError(f"activation: one of {', '.join(map(repr, ACTIVATIONS))} expected, got {self.activation!r}")

    @property
    def shapes(self) -> list[tuple[str, tuple[int, ...]]]:
        h1 = self.hidden[0]
        s = [("w1", (h1, self.n_in)), ("b1", (h1,))]
        if len(self.hidden) == 2:
            s += [("w2", (self.hidden[1], h1)), ("b2", (self.hidden[1],))]
        return s + [("w_out", (self.hidden[-1],)), ("b_out", (1,))]

    @property
    def n_params(self) -> int:
        return sum(math.prod(shape) for _, shape in self.shapes)

    def unpack(self, x: torch.Tensor) -> dict[str, torch.Tensor]:
        """Views of x as the named weight tensors (no copies)."""
        out, i = {}, 0
        for name, shape in self.shapes:
            n = math.prod(shape)
            out[name] = x[i:i + n].view(shape)
            i += n
        return out

    def pack(self, p: dict[str, torch.Tensor]) -> torch.Tensor:
        return torch.cat([torch.as_tensor(p[name], dtype=DTYPE).reshape(-1) for name, _ in self.shapes])

    # -- evaluation ------------------------------------------------------------
    def forward(self, x: torch.Tensor, xs: torch.Tensor) -> torch.Tensor:
        """Scaled output [N] for scaled inputs xs [N, n_in]; differentiable in x."""
        p = self.unpack(x)
        a = act(torch.addmm(p["b1"], xs, p["w1"].T), self.activation)
        if "w2" in p:
            a = act(torch.addmm(p["b2"], a, p["w2"].T), self.activation)
        return a @ p["w_out"] + p["b_out"]

    def jacobian(self, x: torch.Tensor, xs: torch.Tensor,
                 out: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """Output y [N] and its Jacobian dy/dx [N, n_params], by hand-written backprop.

        The Jacobian is computed into a [n_params, N] row-major buffer (`out`,
        reusable across epochs) and returned as its transposed view: every
        column block is then one contiguous batched write, about twice as
        fast as filling an [N, n_params] array, and J.T @ J is still one BLAS call.
        """
        p = self.unpack(x)
        n = xs.shape[0]
        Jt = torch.empty(self.n_params, n, dtype=DTYPE) if out is None else out
        rows, i = {}, 0
        for name, shape in self.shapes:  # row blocks in the flat order
            k = math.prod(shape)
            rows[name] = Jt[i:i + k]
            i += k
        xt = xs.T.contiguous()  # [n_in, N]
        h1 = self.hidden[0]
        a1 = act(torch.addmm(p["b1"].unsqueeze(1), p["w1"], xt), self.activation)  # [h1, N]
        if "w2" in p:
            h2 = self.hidden[1]
            a2 = act(torch.addmm(p["b2"].unsqueeze(1), p["w2"], a1), self.activation)  # [h2, N]
            y = p["w_out"] @ a2 + p["b_out"]
            rows["w_out"].copy_(a2)
            d2 = act_deriv(a2, self.activation).mul_(p["w_out"].unsqueeze(1))  # dy/dz2
            rows["b2"].copy_(d2)
            torch.mul(d2.unsqueeze(1), a1.unsqueeze(0), out=rows["w2"].view(h2, h1, n))
            d1 = (p["w2"].T @ d2).mul_(act_deriv(a1, self.activation))  # dy/dz1 [h1, N]
        else:
            y = p["w_out"] @ a1 + p["b_out"]
            rows["w_out"].copy_(a1)
            d1 = act_deriv(a1, self.activation).mul_(p["w_out"].unsqueeze(1))
        rows["b_out"].fill_(1.0)
        rows["b1"].copy_(d1)
        torch.mul(d1.unsqueeze(1), xt.unsqueeze(0), out=rows["w1"].view(h1, self.n_in, n))
        return y, Jt.T

    # -- weighted sums of outputs (the priors' rows) ----------------------------
    def combination(self, x: torch.Tensor, xs: torch.Tensor, coef: torch.Tensor) -> torch.Tensor:
        """sum_k coef[k] * f(xs[k]) [M] for inputs xs [K, M, n_in] and coefficients coef [K, M]:
        one forward pass over the K*M rows; differentiable in x."""
        k, m, n_in = xs.shape
        return (self.forward(x, xs.reshape(k * m, n_in)).view(k, m) * coef).sum(0)

    def combination_jacobian(self, x: torch.Tensor, xs: torch.Tensor, coef: torch.Tensor,
                             out: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """`combination` [M] and its Jacobian [M, n_params] (the transposed view of a [n_params, M]
        buffer, `out` when given, as `jacobian`'s), by hand-written backprop over all K*M rows at once.

        A prior row compares the network at K inputs (the control prior: a point between levels
        and the same motion at every level; the monotone prior: a step below and above in
        velocity). Its Jacobian is sum_k coef_k J(xs_k); summing it per weight block, input by
        input, never builds the K [n_params, M] Jacobians (bench/epoch_cost.py times both)."""
        p = self.unpack(x)
        k, m, n_in = xs.shape
        Jt = torch.empty(self.n_params, m, dtype=DTYPE) if out is None else out
        rows, i = {}, 0
        for name, shape in self.shapes:
            size = math.prod(shape)
            rows[name] = Jt[i:i + size]
            i += size
        Jt.zero_()
        y = torch.zeros(m, dtype=DTYPE)
        h1 = self.hidden[0]
        w1 = rows["w1"].view(h1, n_in, m)
        # one input at a time: its [h, M] arrays stay in cache (all K at once ran 1.2x slower than
        # K full Jacobians on the thesis plan's prior, K = 15)
        for kk in range(k):
            c = coef[kk]
            xt = xs[kk].T  # [n_in, M]
            a1 = act(torch.addmm(p["b1"].unsqueeze(1), p["w1"], xt), self.activation)  # [h1, M]
            if "w2" in p:
                h2 = self.hidden[1]
                a2 = act(torch.addmm(p["b2"].unsqueeze(1), p["w2"], a1), self.activation)  # [h2, M]
                y.add_((p["w_out"] @ a2 + p["b_out"]).mul_(c))
                rows["w_out"].addcmul_(a2, c)
                cd2 = act_deriv(a2, self.activation).mul_(p["w_out"].unsqueeze(1)).mul_(c)  # coef * dy/dz2
                rows["b2"].add_(cd2)
                rows["w2"].view(h2, h1, m).addcmul_(cd2.unsqueeze(1), a1.unsqueeze(0))
                cd1 = (p["w2"].T @ cd2).mul_(act_deriv(a1, self.activation))  # coef * dy/dz1
            else:
                y.add_((p["w_out"] @ a1 + p["b_out"]).mul_(c))
                rows["w_out"].addcmul_(a1, c)
                cd1 = act_deriv(a1, self.activation).mul_(p["w_out"].unsqueeze(1)).mul_(c)
            rows["b1"].add_(cd1)
            w1.addcmul_(cd1.unsqueeze(1), xt.unsqueeze(0))
            rows["b_out"][0].add_(c)
        return y, Jt.T

    # -- initialisation -------------------------------------------------------
    def init(self, generator: torch.Generator) -> torch.Tensor:
        """Nguyen-Widrow initial weights (as MATLAB initnw), reproducible from the generator.

        Hidden layers: random unit-direction rows scaled to 0.7 * h^(1/n) and
        biases spread over [-mag, mag], then stretched to the activation's
        active input range ([-2, 2] tanh, [-4, 4] sigmoid) for inputs in [-1, 1].
        Output layer: uniform in [-1, 1] / sqrt(fan-in), so the initial output
        is of the order of the scaled target (MATLAB uses [-1, 1]).
        """
        stretch = 2.0 if self.activation == "tanh" else 4.0
        p: dict[str, torch.Tensor] = {}
        fan_in = self.n_in
        for li, h in enumerate(self.hidden, start=1):
            mag = 0.7 * h ** (1.0 / fan_in)
            w = torch.randn(h, fan_in, dtype=DTYPE, generator=generator)
            w = mag * w / w.norm(dim=1, keepdim=True)
            b = mag * torch.linspace(-1.0, 1.0, h, dtype=DTYPE) * torch.sign(w[:, 0]) if h > 1 \
                else torch.zeros(1, dtype=DTYPE)
            p[f"w{li}"], p[f"b{li}"] = w * stretch, b * stretch
            fan_in = h
        last = self.hidden[-1]
        p["w_out"] = (2 * torch.rand(last, dtype=DTYPE, generator=generator) - 1) / math.sqrt(last)
        p["b_out"] = 2 * torch.rand(1, dtype=DTYPE, generator=generator) - 1
        return self.pack(p)
