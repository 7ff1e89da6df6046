// Seeded random MLP descriptions for the C++ tests (storage owned by the struct).
#pragma once
#include <random>
#include <vector>

#include "dampnet/dampnet.h"

struct RandomModel {
  std::vector<double> w1, b1, w2, b2, w_out, b_out, in_offset, in_gain, sat_lo, sat_hi;
  dn_mlp_desc desc{};

  RandomModel(int n_in, int h1, int h2, int act, unsigned seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> n01(0.0, 1.0);
    auto fill = [&](std::vector<double>& v, int n, double s) {
      v.resize(n);
      for (auto& x : v) x = s * n01(rng);
    };
    fill(w1, h1 * n_in, 1.0);
    fill(b1, h1, 0.5);
    if (h2 > 0) {
      fill(w2, h2 * h1, 1.0 / std::sqrt(double(h1)));
      fill(b2, h2, 0.5);
    }
    fill(w_out, h2 > 0 ? h2 : h1, 1.0);
    fill(b_out, 1, 0.1);
    in_offset.resize(n_in);
    in_gain.resize(n_in);
    sat_lo.resize(n_in);
    sat_hi.resize(n_in);
    std::uniform_real_distribution<double> u(-3.0, 3.0);
    for (int i = 0; i < n_in; ++i) {
      double lo = u(rng), hi = lo + 0.5 + std::fabs(u(rng));
      sat_lo[i] = lo;
      sat_hi[i] = hi;
      in_offset[i] = lo;
      in_gain[i] = 2.0 / (hi - lo);
    }
    desc.n_inputs = n_in;
    desc.n_hidden1 = h1;
    desc.n_hidden2 = h2;
    desc.activation = act;
    desc.w1 = w1.data();
    desc.b1 = b1.data();
    desc.w2 = h2 > 0 ? w2.data() : nullptr;
    desc.b2 = h2 > 0 ? b2.data() : nullptr;
    desc.w_out = w_out.data();
    desc.b_out = b_out.data();
    desc.in_offset = in_offset.data();
    desc.in_gain = in_gain.data();
    desc.in_ymin = -1.0;
    desc.out_offset = -2000.0;  // a force range of about 4 kN
    desc.out_gain = 2.0 / 4000.0;
    desc.out_ymin = -1.0;
    desc.sat_lo = sat_lo.data();
    desc.sat_hi = sat_hi.data();
  }

  // An input inside the saturation range.
  std::vector<double> sample(std::mt19937& rng) const {
    std::vector<double> x(desc.n_inputs);
    for (int i = 0; i < desc.n_inputs; ++i) {
      std::uniform_real_distribution<double> u(sat_lo[i], sat_hi[i]);
      x[i] = u(rng);
    }
    return x;
  }
};
