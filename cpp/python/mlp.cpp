// dampnet._core.Mlp: an immutable MLP evaluated by the C++ kernel (dn_mlp_*).
#include "mlp.hpp"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstdint>
#include <memory>
#include <string>

#include "common.hpp"
#include "dampnet/dampnet.h"
#include "fields.hpp"

namespace dnpy {

namespace {

// A dn_mlp owned by Python, with the description's arrays validated by shape.
class PyMlp {
 public:
  PyMlp(DArray w1, DArray b1, py::object w2, py::object b2, DArray w_out, DArray b_out,
        DArray in_offset, DArray in_gain, double in_ymin, double out_offset, double out_gain,
        double out_ymin, DArray sat_lo, DArray sat_hi, const std::string& activation) {
    if (w1.ndim() != 2) throw py::value_error("w1 must be 2-D [n_hidden1, n_inputs]");
    if (w1.shape(0) > DN_MAX_HIDDEN || w1.shape(1) > DN_MAX_INPUTS)  // before the int casts
      throw py::value_error("Mlp: w1 is [n_hidden1, n_inputs]: at most " +
                            std::to_string(DN_MAX_HIDDEN) + " x " + std::to_string(DN_MAX_INPUTS) + " (" +
                            dn_status_str(DN_E_SIZE) + ")");
    dn_mlp_desc d{};
    d.n_hidden1 = static_cast<int>(w1.shape(0));
    d.n_inputs = static_cast<int>(w1.shape(1));
    DArray w2a, b2a;
    if (!w2.is_none()) {
      w2a = DArray::ensure(w2);
      b2a = DArray::ensure(b2);
      if (!w2a || w2a.ndim() != 2 || w2a.shape(1) != d.n_hidden1 || w2a.shape(0) > DN_MAX_HIDDEN2)
        throw py::value_error("w2 must be 2-D [n_hidden2, n_hidden1] with n_hidden2 <= " +
                              std::to_string(DN_MAX_HIDDEN2) + " (" + dn_status_str(DN_E_SIZE) + ")");
      if (!b2a) throw py::value_error("b2 must be an array of n_hidden2 numbers when w2 is given");
      d.n_hidden2 = static_cast<int>(w2a.shape(0));
      expect(b2a, d.n_hidden2, "b2");
      d.w2 = w2a.data();
      d.b2 = b2a.data();
    }
    const int n_last = d.n_hidden2 > 0 ? d.n_hidden2 : d.n_hidden1;
    expect(b1, d.n_hidden1, "b1");
    expect(w_out, n_last, "w_out");
    expect(b_out, 1, "b_out");
    for (auto* a : {&in_offset, &in_gain, &sat_lo, &sat_hi}) expect(*a, d.n_inputs, "scaling/limits");
    d.activation = dnpy::parse_enum(py::str(activation), "Mlp", "activation");
    d.w1 = w1.data();
    d.b1 = b1.data();
    d.w_out = w_out.data();
    d.b_out = b_out.data();
    d.in_offset = in_offset.data();
    d.in_gain = in_gain.data();
    d.in_ymin = in_ymin;
    d.out_offset = out_offset;
    d.out_gain = out_gain;
    d.out_ymin = out_ymin;
    d.sat_lo = sat_lo.data();
    d.sat_hi = sat_hi.data();
    dn_mlp* m = nullptr;
    check(dn_mlp_create(&d, &m), "Mlp");
    m_.reset(m);
    n_in_ = d.n_inputs;
  }

  int n_inputs() const { return n_in_; }
  const dn_mlp* handle() const { return m_.get(); }

  // One sample: (force, status, clamped_mask).
  py::tuple forward(DArray x, bool single) const {
    expect(x, n_in_, "x");
    uint32_t mask = 0;
    int st;
    double y;
    if (single) {
      float xf[DN_MAX_INPUTS], yf;
      for (int i = 0; i < n_in_; ++i) xf[i] = static_cast<float>(x.data()[i]);
      st = dn_mlp_forward_f(m_.get(), xf, &yf, &mask);
      y = yf;
    } else {
      st = dn_mlp_forward(m_.get(), x.data(), &y, &mask);
    }
    return py::make_tuple(y, st, mask);
  }

  // Many samples [n, n_inputs] in C++ with the GIL released: (y, status, mask).
  py::tuple predict(DArray x, bool single) const {
    if (x.ndim() != 2 || x.shape(1) != n_in_)
      throw py::value_error("x must be 2-D [n_samples, " + std::to_string(n_in_) + "]");
    const py::ssize_t n = x.shape(0);
    py::array_t<double> y(n);
    py::array_t<int32_t> st(n);
    py::array_t<uint32_t> mask(n);
    const double* xp = x.data();
    double* yp = y.mutable_data();
    int32_t* sp = st.mutable_data();
    uint32_t* mp = mask.mutable_data();
    const dn_mlp* m = m_.get();
    const int ni = n_in_;
    {
      py::gil_scoped_release release;
      for (py::ssize_t r = 0; r < n; ++r) {
        if (single) {
          float xf[DN_MAX_INPUTS], yf;
          for (int i = 0; i < ni; ++i) xf[i] = static_cast<float>(xp[r * ni + i]);
          sp[r] = dn_mlp_forward_f(m, xf, &yf, &mp[r]);
          yp[r] = yf;
        } else {
          sp[r] = dn_mlp_forward(m, xp + r * ni, &yp[r], &mp[r]);
        }
      }
    }
    return py::make_tuple(y, st, mask);
  }

 private:
  static void expect(const DArray& a, py::ssize_t n, const char* name) {
    if (a.size() != n)
      throw py::value_error(std::string(name) + ": expected " + std::to_string(n) +
                            " values, got " + std::to_string(a.size()));
  }
  struct Deleter {
    void operator()(dn_mlp* m) const { dn_mlp_destroy(m); }
  };
  std::unique_ptr<dn_mlp, Deleter> m_;
  int n_in_ = 0;
};

}  // namespace

const dn_mlp* mlp_handle(py::handle mlp) { return constructed<PyMlp>(mlp).handle(); }

void bind_mlp(py::module_& mod) {
  refuse_reinit(py::class_<PyMlp>(mod, "Mlp", "An immutable MLP model evaluated by the C++ kernel; may be shared by threads "
                          "(predict releases the GIL).")
      .def(py::init<DArray, DArray, py::object, py::object, DArray, DArray, DArray, DArray, double,
                    double, double, double, DArray, DArray, const std::string&>(),
           py::arg("w1"), py::arg("b1"), py::arg("w2"), py::arg("b2"), py::arg("w_out"),
           py::arg("b_out"), py::arg("in_offset"), py::arg("in_gain"), py::arg("in_ymin"),
           py::arg("out_offset"), py::arg("out_gain"), py::arg("out_ymin"), py::arg("sat_lo"),
           py::arg("sat_hi"), py::arg("activation"))
      .def_property_readonly("n_inputs", method(&PyMlp::n_inputs))
      .def("forward", method(&PyMlp::forward), py::arg("x"), py::arg("single") = false,
           "One sample -> (output, status, clamped_mask).")
      .def("predict", method(&PyMlp::predict), py::arg("x"), py::arg("single") = false,
           "Samples [n, n_inputs] -> (outputs[n], status[n], clamped_mask[n]); GIL released."));

}

}  // namespace dnpy
