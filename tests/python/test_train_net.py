"""The flat-weight MLP: analytic Jacobian against torch.autograd, packing, initialisation."""

import pytest
import torch

from dampnet.training.net import DTYPE, Layout, act


pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.mark.parametrize("hidden", [(5,), (4, 3)])
@pytest.mark.parametrize("activation", ["tanh", "sigmoid"])
def test_analytic_jacobian_matches_autograd(hidden, activation):
    g = torch.Generator().manual_seed(3)
    lay = Layout(3, hidden, activation)
    x = torch.randn(lay.n_params, dtype=DTYPE, generator=g)
    xs = 2 * torch.rand(17, 3, dtype=DTYPE, generator=g) - 1
    y, J = lay.jacobian(x, xs)
    J_ref = torch.autograd.functional.jacobian(lambda w: lay.forward(w, xs), x)
    assert J.shape == (17, lay.n_params)
    # Same float64 arithmetic in a different order: agreement to rounding error.
    torch.testing.assert_close(y, lay.forward(x, xs), rtol=1e-13, atol=1e-13)
    torch.testing.assert_close(J, J_ref, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("hidden", [(5,), (4, 3)])
@pytest.mark.parametrize("activation", ["tanh", "sigmoid"])
def test_a_combination_s_jacobian_matches_autograd(hidden, activation):
    """sum_k coef_k f(xs_k) (the priors' rows) and its Jacobian, summed per weight block, against
    torch.autograd on K separate forward passes."""
    g = torch.Generator().manual_seed(5)
    lay = Layout(3, hidden, activation)
    x = torch.randn(lay.n_params, dtype=DTYPE, generator=g)
    xs = 2 * torch.rand(4, 11, 3, dtype=DTYPE, generator=g) - 1  # K = 4 inputs per row, 11 rows
    coef = torch.randn(4, 11, dtype=DTYPE, generator=g)

    def separate(w):
        return sum(coef[k] * lay.forward(w, xs[k]) for k in range(4))

    y, J = lay.combination_jacobian(x, xs, coef)
    assert J.shape == (11, lay.n_params)
    torch.testing.assert_close(y, separate(x), rtol=1e-13, atol=1e-13)
    torch.testing.assert_close(lay.combination(x, xs, coef), separate(x), rtol=1e-13, atol=1e-13)
    torch.testing.assert_close(J, torch.autograd.functional.jacobian(separate, x), rtol=1e-12, atol=1e-12)


def test_jacobian_reuses_buffer():
    lay = Layout(2, (3,), "tanh")
    g = torch.Generator().manual_seed(0)
    xs = torch.rand(8, 2, dtype=DTYPE, generator=g)
    buf = torch.full((lay.n_params, 8), float("nan"), dtype=DTYPE)
    x = lay.init(g)
    _, J = lay.jacobian(x, xs, out=buf)
    assert J.data_ptr() == buf.data_ptr() and torch.isfinite(J).all()


def test_pack_unpack_roundtrip_and_layout():
    lay = Layout(3, (4, 2), "tanh")
    assert lay.n_params == 4 * 3 + 4 + 2 * 4 + 2 + 2 + 1
    x = torch.arange(lay.n_params, dtype=DTYPE)
    p = lay.unpack(x)
    assert p["w1"].shape == (4, 3) and p["w2"].shape == (2, 4) and p["w_out"].shape == (2,)
    assert p["w1"][1, 0] == 3  # row-major [out][in]
    assert torch.equal(lay.pack(p), x)


def test_init_is_seeded_and_nguyen_widrow_scaled():
    lay = Layout(3, (30,), "tanh")
    a = lay.init(torch.Generator().manual_seed(5))
    b = lay.init(torch.Generator().manual_seed(5))
    c = lay.init(torch.Generator().manual_seed(6))
    assert torch.equal(a, b) and not torch.equal(a, c)
    w1 = lay.unpack(a)["w1"]
    # Every row has the Nguyen-Widrow norm 0.7 * h^(1/n), stretched by 2 for tanh.
    torch.testing.assert_close(w1.norm(dim=1), torch.full((30,), 2 * 0.7 * 30 ** (1 / 3), dtype=DTYPE))


def test_layout_rejects_bad_shapes():
    with pytest.raises(ValueError, match="hidden"):
        Layout(3, (3, 3, 3), "tanh")
    with pytest.raises(ValueError, match="activation"):
        Layout(3, (3,), "relu")


def test_tanh_without_autograd_is_torchs_on_hard_inputs():
    """act's tanh without autograd (numpy's, in place) against torch.tanh: within 1 ulp on random
    and hard arguments (zero and signed zero, subnormals, the region where tanh rounds to +-1,
    huge, infinite, NaN), in place on a contiguous tensor and on a transposed view; float32 and
    tensors that need a gradient keep torch's. Cost: 0.1 s."""
    import numpy as np

    hard = [0.0, -0.0, 5e-324, -5e-324, 1e-300, 1e-8, -1e-8, 0.5, -0.5, 1.0, 19.06, 20.0, -20.0,
            354.0, 710.0, 1e300, -1e300, float("inf"), float("-inf"), float("nan")]
    z = torch.cat([torch.tensor(hard, dtype=DTYPE), torch.randn(4000, dtype=DTYPE, generator=torch.Generator().manual_seed(0)) * 4])
    want = torch.tanh(z)
    for given in (z.clone().view(-1, 4), z.clone().view(4, -1).T):
        got = act(given, "tanh")
        assert got.data_ptr() == given.data_ptr()  # in place: the caller's fresh pre-activation
        g, w = got.reshape(-1).numpy() if got.is_contiguous() else got.T.reshape(-1).numpy(), want.numpy()
        assert np.array_equal(np.isnan(g), np.isnan(w))
        ok = ~np.isnan(w)
        assert np.array_equal(np.signbit(g[ok]), np.signbit(w[ok]))
        ulps = np.abs(g[ok] - w[ok]) / np.spacing(np.maximum(np.abs(w[ok]), np.finfo(float).tiny))
        assert ulps.max() <= 1.0, ulps.max()
    f32 = z.float()
    assert torch.equal(act(f32.clone(), "tanh").nan_to_num(), torch.tanh(f32).nan_to_num())
    needs_grad = z[:8].clone().requires_grad_(True)
    assert act(needs_grad, "tanh").grad_fn is not None
