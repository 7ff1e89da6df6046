// dampnet._core.Envelope: the training envelope's bounded-time check (dn_envelope_*), the
// runtime flag an FMU or a HIL loop computes each step, evaluated here on a run's inputs.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstdint>
#include <memory>
#include <string>

#include "common.hpp"
#include "dampnet/dampnet.h"

namespace dnpy {

namespace {

using CellArray = py::array_t<uint32_t, py::array::c_style | py::array::forcecast>;

class PyEnvelope {
 public:
  PyEnvelope(DArray lo, DArray hi, CellArray cells) {
    if (lo.ndim() != 1 || lo.size() < 1 || lo.size() > DN_MAX_INPUTS)
      throw py::value_error("Envelope: lo must be 1-D with 1.." + std::to_string(DN_MAX_INPUTS) +
                            " values (one per model input), got " + std::to_string(lo.size()));
    const int n = static_cast<int>(lo.size());
    if (hi.ndim() != 1 || hi.size() != n)
      throw py::value_error("Envelope: hi must be 1-D with " + std::to_string(n) + " values like lo");
    const py::ssize_t pairs = n * (n - 1) / 2;
    if (cells.ndim() != 2 || cells.shape(0) != pairs || cells.shape(1) != DN_ENVELOPE_PAIR_WORDS)
      throw py::value_error("Envelope: cells must be [" + std::to_string(pairs) + ", " +
                            std::to_string(DN_ENVELOPE_PAIR_WORDS) + "] uint32 (one bitmap per pair of inputs)");
    dn_envelope_desc d{n, lo.data(), hi.data(), pairs ? cells.data() : nullptr};
    dn_envelope* e = nullptr;
    check(dn_envelope_create(&d, &e), "Envelope");
    e_.reset(e);
    n_ = n;
  }

  int n_inputs() const { return n_; }

  // Flags [n] (uint32, 0 inside, DN_ENV_OUTSIDE_* bits) of points x [n, n_inputs]; GIL released.
  py::array_t<uint32_t> check_points(DArray x) const {
    if (x.ndim() != 2 || x.shape(1) != n_)
      throw py::value_error("Envelope.check: x must be 2-D [n_points, " + std::to_string(n_) + "]");
    const py::ssize_t n = x.shape(0);
    py::array_t<uint32_t> flags(n);
    const double* xp = x.data();
    uint32_t* fp = flags.mutable_data();
    const dn_envelope* e = e_.get();
    const int ni = n_;
    {
      py::gil_scoped_release release;
      for (py::ssize_t r = 0; r < n; ++r) dn_envelope_check(e, xp + r * ni, &fp[r]);
    }
    return flags;
  }

 private:
  struct Deleter {
    void operator()(dn_envelope* e) const { dn_envelope_destroy(e); }
  };
  std::unique_ptr<dn_envelope, Deleter> e_;
  int n_ = 0;
};

}  // namespace

void bind_envelope(py::module_& mod) {
  refuse_reinit(py::class_<PyEnvelope>(mod, "Envelope",
                         "A model's coarse training envelope (per-input ranges and per-pair occupancy "
                         "bitmaps, dampnet.h 'Training envelope'); immutable, may be shared by threads.")
      .def(py::init<DArray, DArray, CellArray>(), py::arg("lo"), py::arg("hi"), py::arg("cells"))
      .def_property_readonly("n_inputs", method(&PyEnvelope::n_inputs))
      .def("check", method(&PyEnvelope::check_points), py::arg("x"),
           "Points [n, n_inputs] (feature units) -> flags[n] uint32: 0 inside, bit 0 an input outside "
           "its range (or NaN), bit 1 a pair of inputs in an empty cell; GIL released."));
  mod.attr("ENVELOPE_CELLS") = DN_ENVELOPE_CELLS;
  mod.attr("ENVELOPE_PAIR_WORDS") = DN_ENVELOPE_PAIR_WORDS;
  mod.attr("ENV_OUTSIDE_RANGE") = DN_ENV_OUTSIDE_RANGE;
  mod.attr("ENV_OUTSIDE_JOINT") = DN_ENV_OUTSIDE_JOINT;
}

}  // namespace dnpy
