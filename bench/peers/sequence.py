"""A recurrent sequence model of a damper's force, the kind published for MR dampers (a GRU over
a history window of the measured motion and control), as a peer model for bench/real_data.py.
Not a dampnet feature: it runs in torch only.

The model: the last `window` samples of (displacement [m], velocity [m/s], control), each
standardised with the training data's mean and standard deviation, go through a one-layer GRU
(`hidden` units); a linear layer maps its last state to the force, standardised likewise. The
first window-1 samples of a record see its first sample repeated (the record starts at rest as
far as the model knows).

Training (`train_gru`): Adam on the mean squared (standardised) force error over windows from
the training records (every `stride`-th window), mini-batches of `batch`; the budget is
`epochs` and `seconds` (whichever ends first); the epoch with the lowest error on the
validation windows (the last `val_fraction` of every training record, chronologically) is kept.
torch is held to `threads` threads. Everything the budget was, and what was used, is returned.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Sequence

import numpy as np


@dataclass
class SeqRecord:
    """One record: x [m], xdot [m/s], u (control), force [N] (None when only predicting)."""

    x: np.ndarray
    xdot: np.ndarray
    u: np.ndarray
    force: np.ndarray | None = None


def windows(inputs: np.ndarray, window: int) -> np.ndarray:
    """[T, C] -> [T, window, C]: at each sample the last `window` samples, the first repeated
    before the start."""
    pad = np.repeat(inputs[:1], window - 1, axis=0)
    a = np.concatenate([pad, inputs], axis=0)
    idx = np.arange(inputs.shape[0])[:, None] + np.arange(window)[None, :]
    return a[idx]


class GruPeer:
    """The trained GRU and its scaling; `predict(record)` -> force [N]."""

    def __init__(self, net, mean, std, f_mean, f_std, window, info):
        self.net, self.mean, self.std, self.f_mean, self.f_std = net, mean, std, f_mean, f_std
        self.window, self.info = window, info

    def _inputs(self, r: SeqRecord) -> np.ndarray:
        z = np.column_stack([r.x, r.xdot, r.u]).astype(np.float64)
        return ((z - self.mean) / self.std).astype(np.float32)

    def predict(self, r: SeqRecord, batch: int = 4096) -> np.ndarray:
        import torch

        w = windows(self._inputs(r), self.window)
        out = []
        self.net.eval()
        with torch.no_grad():
            for i in range(0, len(w), batch):
                out.append(self.net(torch.from_numpy(w[i:i + batch])).numpy())
        return np.concatenate(out).ravel().astype(np.float64) * self.f_std + self.f_mean

    def n_parameters(self) -> int:
        return int(sum(p.numel() for p in self.net.parameters()))

    def time_per_sample(self, r: SeqRecord, n: int = 300) -> float:
        """Seconds per sample as a real-time loop would run it: one window (batch of 1) a call."""
        import torch

        w = windows(self._inputs(r), self.window)[:n]
        self.net.eval()
        with torch.no_grad():
            for k in range(min(20, len(w))):
                self.net(torch.from_numpy(w[k:k + 1]))
            t0 = time.perf_counter()
            for k in range(len(w)):
                self.net(torch.from_numpy(w[k:k + 1]))
            return (time.perf_counter() - t0) / len(w)


def _net(hidden: int, channels: int = 3):
    import torch

    class Gru(torch.nn.Module):
        def __init__(self):
            super().__init__()
            self.gru = torch.nn.GRU(channels, hidden, batch_first=True)
            self.out = torch.nn.Linear(hidden, 1)

        def forward(self, w):
            h, _ = self.gru(w)
            return self.out(h[:, -1])

    return Gru()


def train_gru(records: Sequence[SeqRecord], *, window: int = 20, hidden: int = 32, epochs: int = 40,
              seconds: float = 120.0, batch: int = 256, lr: float = 3e-3, stride: int = 1,
              val_fraction: float = 0.15, seed: int = 0, threads: int = 1,
              max_windows: int = 60000) -> GruPeer:
    """Train the GRU on `records` within the budget (see the module docstring). `max_windows`
    caps the training windows per epoch (a random subset each epoch, when there are more)."""
    import torch

    if not records:
        raise ValueError("GRU: no training records")
    torch.set_num_threads(threads)
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    allz = np.concatenate([np.column_stack([r.x, r.xdot, r.u]) for r in records])
    allf = np.concatenate([r.force for r in records])
    mean, std = allz.mean(axis=0), allz.std(axis=0)
    std = np.where(std > 0, std, 1.0)
    f_mean, f_std = float(allf.mean()), float(allf.std() or 1.0)
    tr_w, tr_y, va_w, va_y = [], [], [], []
    for r in records:
        z = ((np.column_stack([r.x, r.xdot, r.u]) - mean) / std).astype(np.float32)
        w = windows(z, window)
        y = ((r.force - f_mean) / f_std).astype(np.float32)
        cut = int(len(y) * (1 - val_fraction))
        tr_w.append(w[:cut:stride])
        tr_y.append(y[:cut:stride])
        va_w.append(w[cut::max(stride, 1)])
        va_y.append(y[cut::max(stride, 1)])
    Wt, Yt = torch.from_numpy(np.concatenate(tr_w)), torch.from_numpy(np.concatenate(tr_y))
    Wv, Yv = torch.from_numpy(np.concatenate(va_w)), torch.from_numpy(np.concatenate(va_y))
    if len(Wv) > 20000:
        sel = torch.from_numpy(rng.choice(len(Wv), 20000, replace=False))
        Wv, Yv = Wv[sel], Yv[sel]
    net = _net(hidden)
    opt = torch.optim.Adam(net.parameters(), lr=lr)
    best, best_state, history = float("inf"), None, []
    ep = 0
    stop = "epochs"
    for ep in range(1, epochs + 1):
        net.train()
        n = len(Wt)
        order = torch.from_numpy(rng.permutation(n)[:max_windows])
        for i in range(0, len(order), batch):
            b = order[i:i + batch]
            opt.zero_grad()
            loss = torch.mean((net(Wt[b]).ravel() - Yt[b]) ** 2)
            loss.backward()
            opt.step()
        net.eval()
        with torch.no_grad():
            v = float(torch.mean((net(Wv).ravel() - Yv) ** 2))
        history.append(v)
        if v < best:
            best, best_state = v, {k: t.clone() for k, t in net.state_dict().items()}
        if time.perf_counter() - t0 > seconds:
            stop = "seconds"
            break
    net.load_state_dict(best_state)
    info = {"window": window, "hidden": hidden, "epochs_run": ep, "epochs_budget": epochs, "seconds_budget": seconds,
            "stopped_by": stop, "batch": batch, "lr": lr, "threads": threads, "training_windows": int(len(Wt)),
            "windows_per_epoch": int(min(len(Wt), max_windows)), "best_val_mse_std": best,
            "seconds": time.perf_counter() - t0}
    return GruPeer(net, mean, std, f_mean, f_std, window, info)
