// No heap allocation in forward: every allocation entry point is counted while
// a million forward calls run (alloc_counter.hpp: interposed in the plain build, the
// sanitizer's allocation hook under ASan; pytest runs both builds).
#include <cstdlib>
#include <new>
#include <random>
#include <vector>

#include "check.hpp"
#include "dampnet/mlp.hpp"
#include "random_model.hpp"

#include "alloc_counter.hpp"

int main() {
  RandomModel rm(3, 30, 0, DN_ACT_SIGMOID, 1);
  RandomModel rm2(4, 16, 16, DN_ACT_TANH, 2);
  dn_mlp* cm = nullptr;
  CHECK(dn_mlp_create(&rm.desc, &cm) == DN_OK);
  auto* md = new dampnet::Mlp<double>;
  auto* sf = new dampnet::StaticMlp<float, 4, 16, 16>;
  CHECK(md->load(&rm.desc) == DN_OK);
  CHECK(sf->load(&rm2.desc) == DN_OK);

  // The counter sees every allocation entry point (else this test could not fail).
  CHECK(dn_alloc_counter_self_test(false) == 0);

  double x[3] = {0.1, -0.2, 0.3}, y = 0, acc = 0;
  float xf[4] = {0.1f, 0.2f, 0.3f, 0.4f}, yf = 0, ycf = 0;
  g_counting = true;
  for (int k = 0; k < 1000000; ++k) {
    x[0] = 1e-6 * k;
    md->forward(x, &y);
    acc += y;
    sf->forward(xf, &yf);
    dn_mlp_forward(cm, x, &y, nullptr);
    dn_mlp_forward_f(cm, xf, &ycf, nullptr);
  }
  g_counting = false;
  std::printf("allocations during 4e6 forward calls: %ld (checksum %g)\n", g_allocs, acc);
  CHECK(g_allocs == 0);
  dn_mlp_destroy(cm);
  delete md;
  delete sf;
  TEST_MAIN_RETURN();
}
