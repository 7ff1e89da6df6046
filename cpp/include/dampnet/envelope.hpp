// The training envelope's bounded-time check (dampnet.h, "Training envelope"): per-input
// ranges and, per pair of inputs, a DN_ENVELOPE_CELLS x DN_ENVELOPE_CELLS occupancy bitmap of
// the training data's 2-D shadow. Fixed storage, no heap; check() is a loop over at most
// DN_ENVELOPE_MAX_PAIRS pairs reading one word each.
#pragma once

#include <cmath>
#include <cstdint>

#include "dampnet/dampnet.h"

namespace dampnet {

class Envelope {
 public:
  int load(const dn_envelope_desc* d) noexcept {
    if (!d) return DN_E_NULL;
    if (d->n_inputs < 1 || d->n_inputs > DN_MAX_INPUTS) return DN_E_SIZE;
    if (d->n_inputs >= 2 && !d->cells) return DN_E_NULL;
    return set(d->n_inputs, d->lo, d->hi, d->cells);
  }

  // The ranges alone, every cell marked: only DN_ENV_OUTSIDE_RANGE can be set (a model
  // exported without its envelope).
  int load_ranges(int n_inputs, const double* lo, const double* hi) noexcept {
    return set(n_inputs, lo, hi, nullptr);
  }

  int n_inputs() const noexcept { return n_; }

  // Flags of point x [n_inputs] (feature units): 0 inside, else DN_ENV_OUTSIDE_* bits.
  template <class T>
  uint32_t check(const T* x) const noexcept {
    int cell[DN_MAX_INPUTS];
    uint32_t flags = 0;
    for (int i = 0; i < n_; ++i) {
      const double v = double(x[i]);
      // !(lo <= v <= hi) is also true for NaN
      if (!(v >= lo_[i] && v <= hi_[i])) {
        flags |= DN_ENV_OUTSIDE_RANGE;
        cell[i] = -1;
        continue;
      }
      // in [0, CELLS]: v - lo is in [0, hi - lo], finite (checked at load)
      const int c = int((v - lo_[i]) * scale_[i]);
      cell[i] = c < DN_ENVELOPE_CELLS ? c : DN_ENVELOPE_CELLS - 1;
    }
    int p = 0;
    for (int i = 0; i < n_; ++i) {
      for (int j = i + 1; j < n_; ++j, ++p) {
        if (cell[i] < 0 || cell[j] < 0) continue;  // out of range: flagged above
        const int bit = cell[i] * DN_ENVELOPE_CELLS + cell[j];
        if (!((cells_[p * DN_ENVELOPE_PAIR_WORDS + bit / 32] >> (bit % 32)) & 1u)) flags |= DN_ENV_OUTSIDE_JOINT;
      }
    }
    return flags;
  }

 private:
  // Cells per feature unit of a range: 0 (one cell) for a constant input (hi == lo, as a model
  // trained on a constant column has) or a width too small to divide (below ~1e-307).
  static double scale_of(double lo, double hi) noexcept {
    const double s = double(DN_ENVELOPE_CELLS) / (hi - lo);
    return hi > lo && std::isfinite(s) ? s : 0.0;
  }

  // Validate, then copy (cells NULL: all marked); unchanged on error.
  int set(int n, const double* lo, const double* hi, const uint32_t* cells) noexcept {
    if (!lo || !hi) return DN_E_NULL;
    if (n < 1 || n > DN_MAX_INPUTS) return DN_E_SIZE;
    for (int i = 0; i < n; ++i) {
      if (!std::isfinite(lo[i]) || !std::isfinite(hi[i])) return DN_E_NONFINITE_PARAM;
      // hi < lo, or a width beyond double (then (x - lo) * scale could be Inf * 0)
      if (!(hi[i] >= lo[i]) || !std::isfinite(hi[i] - lo[i])) return DN_E_PARAM;
    }
    n_ = n;
    for (int i = 0; i < n; ++i) {
      lo_[i] = lo[i];
      hi_[i] = hi[i];
      scale_[i] = scale_of(lo[i], hi[i]);
    }
    const int words = n * (n - 1) / 2 * DN_ENVELOPE_PAIR_WORDS;
    for (int w = 0; w < words; ++w) cells_[w] = cells ? cells[w] : ~0u;
    return DN_OK;
  }

  int n_ = 0;
  double lo_[DN_MAX_INPUTS] = {};
  double hi_[DN_MAX_INPUTS] = {};
  double scale_[DN_MAX_INPUTS] = {};  // cells per feature unit
  uint32_t cells_[DN_ENVELOPE_MAX_PAIRS * DN_ENVELOPE_PAIR_WORDS] = {};
};

}  // namespace dampnet
