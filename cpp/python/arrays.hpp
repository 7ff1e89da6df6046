// The result arrays of Loop.simulate (arrays.cpp): "state" [n, DN_LOOP_STATE_SIZE], one [n]
// array per dn_loop_out quantity (DN_LOOP_OUT_LIST, in its order; its "u" is named
// "control" here, the trajectory's name for it since 0.1), "features" [n, n_features] and
// "status" [n] int32. Fresh arrays, or the arrays of a previous result (out=) checked and
// written in place.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstddef>
#include <cstdint>
#include <iterator>
#include <utility>

#include "dampnet/dampnet.h"

namespace dnpy {

namespace py = pybind11;

// dn_loop_out's scalar quantities, in DN_LOOP_OUT_LIST order: the one table simulate's
// arrays and the step report read them through.
#define DNPY_OUT_MEMBER_(name, doc) &dn_loop_out::name,
inline double dn_loop_out::* const kOutQuantities[] = {DN_LOOP_OUT_LIST(DNPY_OUT_MEMBER_)};
#undef DNPY_OUT_MEMBER_
constexpr std::size_t kNumOutQuantities = std::size(kOutQuantities);

class SimulateArrays {
 public:
  // n samples of a damper with nf neural inputs.
  SimulateArrays(py::ssize_t n, int nf);  // fresh arrays
  // out's arrays (a previous result of the same shapes), refused with ValueError/TypeError
  // unless each is writeable, aligned, C-contiguous, of the result's dtype and shape and
  // shares no memory with another or with the inputs.
  SimulateArrays(const py::object& out, py::ssize_t n, int nf,
                 std::initializer_list<std::pair<const char*, const char*>> inputs);

  // Raw pointers for the loop, written with the GIL released.
  double* state() { return state_.mutable_data(); }
  int32_t* status() { return status_.mutable_data(); }
  // Sample k of a step's report (not the status).
  struct Writer {
    double* q[kNumOutQuantities];
    double* features;
    int nf;
    void operator()(py::ssize_t k, const dn_loop_out& o) const noexcept;
  };
  Writer writer();

  py::dict to_dict() const;  // the result, keys in the order above

 private:
  int nf_;
  py::array_t<double> state_, quantity_[kNumOutQuantities], features_;
  py::array_t<int32_t> status_;
};

}  // namespace dnpy
