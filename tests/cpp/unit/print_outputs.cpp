// Prints the kernel's outputs for seeded random models and inputs, one line per
// sample ("shape k y_double y_float"), so that two builds (plain and Eigen) can
// be compared by the Python tests.
#include <cstdio>
#include <random>

#include "dampnet/mlp.hpp"
#include "random_model.hpp"

int main() {
  const int shapes[][4] = {{1, 1, 0, 0}, {3, 30, 0, 1}, {3, 30, 0, 0}, {8, 64, 0, 0},
                           {5, 16, 8, 1}, {8, 64, 64, 0}, {2, 7, 1, 1}};
  int s = 0;
  for (const auto& sh : shapes) {
    RandomModel rm(sh[0], sh[1], sh[2], sh[3], 100u + unsigned(s));
    dampnet::Mlp<double> md;
    dampnet::Mlp<float> mf;
    if (md.load(&rm.desc) != DN_OK || mf.load(&rm.desc) != DN_OK) return 1;
    std::mt19937 rng(7u + unsigned(s));
    for (int k = 0; k < 50; ++k) {
      std::vector<double> x = rm.sample(rng);
      std::vector<float> xf(x.begin(), x.end());
      double yd;
      float yf;
      md.forward(x.data(), &yd);
      mf.forward(xf.data(), &yf);
      std::printf("%d %d %.17g %.9g\n", s, k, yd, double(yf));
    }
    ++s;
  }
  return 0;
}
