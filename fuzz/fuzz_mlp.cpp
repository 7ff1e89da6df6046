// libFuzzer harness (a): model loading and the forward pass through the C ABI.
// dn_mlp_create from an arbitrary descriptor (sizes, weights, scaling, limits,
// activation, NULL arrays), then dn_mlp_forward / dn_mlp_forward_f on arbitrary
// inputs. Asserted (abort otherwise): *out is NULL exactly when creation fails;
// dn_mlp_n_inputs matches; every forward returns a finite output (dampnet.h: "The
// output is always finite") with a status >= 0 or DN_E_NONFINITE_OUTPUT, and a
// clamped mask with no bit beyond the model's inputs.
#include "fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  FuzzedDataProvider f(data, size);
  dn_fuzz::MlpDescBuf buf;
  buf.decode(f);
  dn_mlp* m = nullptr;
  const bool null_desc = f.ConsumeIntegralInRange<int>(0, 63) == 0;
  const int st = dn_mlp_create(null_desc ? nullptr : &buf.d, &m);
  if ((st == DN_OK) != (m != nullptr)) dn_fuzz::fail("*out NULL iff error", "dn_mlp_create", st);
  if (st > 0) dn_fuzz::fail("creation returned a warning", "dn_mlp_create", st);
  if (!m) return 0;
  const int ni = dn_mlp_n_inputs(m);
  if (ni != buf.d.n_inputs) dn_fuzz::fail("n_inputs differs from the descriptor", "dn_mlp_n_inputs", ni);
  const int n_calls = f.ConsumeIntegralInRange<int>(1, 16);
  for (int k = 0; k < n_calls; ++k) {
    std::vector<double> x(static_cast<size_t>(ni));  // exactly n_inputs: ASan catches an overread
    std::vector<float> xf(static_cast<size_t>(ni));
    for (int i = 0; i < ni; ++i) {
      const int lo = 0;
      // Inside the saturation range half of the time (the fast path), else anything.
      if (f.ConsumeBool() && std::isfinite(buf.sat_lo[size_t(i)]) && std::isfinite(buf.sat_hi[size_t(i)])) {
        const double w = f.ConsumeIntegralInRange<int>(lo, 1000) / 1000.0;
        x[size_t(i)] = buf.sat_lo[size_t(i)] + w * (buf.sat_hi[size_t(i)] - buf.sat_lo[size_t(i)]);
      } else {
        x[size_t(i)] = dn_fuzz::value(f);
      }
      const double xi = x[size_t(i)];
      // float input: the same value where float holds it, else a float limit or inf.
      xf[size_t(i)] = std::isnan(xi) ? NAN
                      : std::fabs(xi) > FLT_MAX ? (xi > 0 ? INFINITY : -INFINITY)
                                                : static_cast<float>(xi);
    }
    double y = NAN;
    uint32_t mask = 0xFFFFFFFFu;
    int s = dn_mlp_forward(m, x.data(), &y, f.ConsumeBool() ? &mask : nullptr);
    if (s < 0 && s != DN_E_NONFINITE_OUTPUT) dn_fuzz::fail("unexpected error", "dn_mlp_forward", s);
    dn_fuzz::check_finite(y, "non-finite output", "dn_mlp_forward", s);
    if (mask != 0xFFFFFFFFu && (mask >> ni) != 0) dn_fuzz::fail("mask bit beyond the inputs", "dn_mlp_forward", s);
    float yf = NAN;
    mask = 0xFFFFFFFFu;
    s = dn_mlp_forward_f(m, xf.data(), &yf, f.ConsumeBool() ? &mask : nullptr);
    if (s < 0 && s != DN_E_NONFINITE_OUTPUT) dn_fuzz::fail("unexpected error", "dn_mlp_forward_f", s);
    dn_fuzz::check_finite(yf, "non-finite output", "dn_mlp_forward_f", s);
    if (mask != 0xFFFFFFFFu && (mask >> ni) != 0) dn_fuzz::fail("mask bit beyond the inputs", "dn_mlp_forward_f", s);
  }
  // NULL arguments: a status, never a crash.
  double y;
  std::vector<double> x(static_cast<size_t>(ni), 0.0);
  if (dn_mlp_forward(m, nullptr, &y, nullptr) != DN_E_NULL || dn_mlp_forward(m, x.data(), nullptr, nullptr) != DN_E_NULL ||
      dn_mlp_forward(nullptr, x.data(), &y, nullptr) != DN_E_NULL)
    dn_fuzz::fail("NULL argument not refused", "dn_mlp_forward", 0);
  dn_mlp_destroy(m);
  return 0;
}
