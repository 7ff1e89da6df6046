"""A trained model, exported by dampnet.export and compiled into the C++ runtime, reproduces the
Python model's predictions on held-out data: the StaticMlp<float/double> kernel from the
generated header, the C ABI (libdampnet), and the pybind11 path (MlpModel.predict), each at the
runtime's stated tolerance (float within 1e-5 of the force range, double within 1e-12 relative),
against the independent torch float64 reference."""

import numpy as np
import pytest

from dampnet import paths
from dampnet.rig import generate
from dampnet.export import write_header
from dampnet.training import torch_forward
from dampnet.features import feature_matrix
from dampnet.training.pipeline import train_dataset

from cbuild import compile_program, run

PROGRAM = r"""
#include <cstdio>
#include <vector>
#include "dampnet/dampnet.h"
#include "dampnet/mlp.hpp"
#include "model.h"

int main(int argc, char** argv) {
  if (argc != 2) return 2;
  std::FILE* f = std::fopen(argv[1], "r");
  if (!f) return 3;
  int n = 0, k = 0;
  if (std::fscanf(f, "%d %d", &n, &k) != 2 || k != DN_MODEL_N_INPUTS) return 4;
  std::vector<double> x(static_cast<size_t>(n) * k);
  for (auto& v : x) if (std::fscanf(f, "%lf", &v) != 1) return 5;
  std::fclose(f);
  const dn_mlp_desc desc = DN_MODEL_DESC_INIT;
  dampnet::StaticMlp<double, DN_MODEL_N_INPUTS, DN_MODEL_N_HIDDEN1, DN_MODEL_N_HIDDEN2> md;
  dampnet::StaticMlp<float, DN_MODEL_N_INPUTS, DN_MODEL_N_HIDDEN1, DN_MODEL_N_HIDDEN2> mf;
  if (md.load(&desc) != DN_OK || mf.load(&desc) != DN_OK) return 6;
  dn_mlp* mc = nullptr;
  if (dn_mlp_create(&desc, &mc) != DN_OK) return 7;
  for (int i = 0; i < n; ++i) {
    const double* xi = &x[static_cast<size_t>(i) * k];
    float xf[DN_MODEL_N_INPUTS];
    for (int j = 0; j < k; ++j) xf[j] = static_cast<float>(xi[j]);
    double yd = 0, yc = 0;
    float yf = 0, ycf = 0;
    md.forward(xi, &yd);
    mf.forward(xf, &yf);
    dn_mlp_forward(mc, xi, &yc, nullptr);
    dn_mlp_forward_f(mc, xf, &ycf, nullptr);
    std::printf("%.17g %.9g %.17g %.9g\n", yd, static_cast<double>(yf), yc, static_cast<double>(ycf));
  }
  dn_mlp_destroy(mc);
  return 0;
}
"""


@pytest.fixture(scope="module")
def trained():
    ds = generate("quick", seed=7)
    model, info, split = train_dataset(ds, decimate=25, max_epochs=80, seed=2)
    # hold-out samples (every 7th, to keep the text file small), inside and at the training range
    X = feature_matrix(split.holdout.tests, model.features)[::7]
    return model, X


@pytest.fixture(scope="module")
def runtime_outputs(trained, tmp_path_factory):
    model, X = trained
    d = tmp_path_factory.mktemp("rt")
    write_header(model, d / "model.h")
    (d / "main.cpp").write_text(PROGRAM)
    exe = compile_program([d / "main.cpp"], d / "rt", cxx=True,
                          include_dirs=[d, *paths.include_dirs()], libs=[paths.shared_library()])
    inp = d / "x.txt"
    inp.write_text(f"{len(X)} {X.shape[1]}\n" + "\n".join(" ".join(f"{v:.17g}" for v in r) for r in X))
    out = run([exe, inp]).stdout.split()
    return np.array(out, dtype=np.float64).reshape(len(X), 4)


def test_double_kernel_and_c_abi_match_the_reference(trained, runtime_outputs):
    model, X = trained
    ref = torch_forward(model, X)
    np.testing.assert_allclose(runtime_outputs[:, 0], ref, rtol=1e-12, atol=1e-12 * np.ptp(ref))
    np.testing.assert_allclose(runtime_outputs[:, 2], ref, rtol=1e-12, atol=1e-12 * np.ptp(ref))


def test_float_kernel_and_c_abi_within_1e5_of_the_force_range(trained, runtime_outputs):
    model, X = trained
    ref = torch_forward(model, X)
    span = 2.0 / model.out_gain  # the model's force range (mapminmax output range)
    for col in (1, 3):
        err = np.max(np.abs(runtime_outputs[:, col] - ref))
        assert err <= 1e-5 * span, (col, err, span)


def test_pybind11_predict_matches_the_reference(trained):
    model, X = trained
    ref = torch_forward(model, X)
    np.testing.assert_allclose(model.predict(X), ref, rtol=1e-12, atol=1e-12 * np.ptp(ref))
    yf = model.predict(X, single=True)
    assert np.max(np.abs(yf - ref)) <= 1e-5 * 2.0 / model.out_gain
