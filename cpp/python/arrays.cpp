// Loop.simulate's result arrays, expanded from DN_LOOP_OUT_LIST (see arrays.hpp).
#include "arrays.hpp"

#include <cstring>
#include <string>
#include <vector>

#include "huge_pages.hpp"

namespace dnpy {

namespace {

// The result's key of each quantity: its dn_loop_out name, but "control" for u.
#define DNPY_OUT_KEY_(name, doc) (std::strcmp(#name, "u") == 0 ? "control" : #name),
const char* const kOutKeys[] = {DN_LOOP_OUT_LIST(DNPY_OUT_KEY_)};
#undef DNPY_OUT_KEY_

// The array under `key`, exactly of this dtype and shape, C-contiguous and writeable.
template <class A>
A take(const py::dict& out, const char* key, std::initializer_list<py::ssize_t> shape) {
  if (!out.contains(key)) throw py::value_error(std::string("simulate: out has no '") + key + "'");
  py::object o = out[key];
  if (!py::isinstance<A>(o)) throw py::value_error(std::string("simulate: out['") + key + "'] has the wrong dtype");
  A a = o.cast<A>();
  bool ok = a.ndim() == (py::ssize_t)shape.size() && a.writeable() &&
            (a.flags() & py::array::c_style) && (a.flags() & py::detail::npy_api::NPY_ARRAY_ALIGNED_);
  int k = 0;
  for (py::ssize_t e : shape) ok = ok && a.shape(k++) == e;
  if (!ok)
    throw py::value_error(std::string("simulate: out['") + key +
                          "'] must be a writeable, aligned, C-contiguous array of the result's shape");
  return a;
}

using Span = std::pair<const char*, const char*>;

Span span(const py::array& a) {
  const char* p = static_cast<const char*>(a.data());
  return {p, p + a.nbytes()};
}

bool overlap(Span a, Span b) { return a.first && b.first && a.first < b.second && b.first < a.second; }

}  // namespace

SimulateArrays::SimulateArrays(py::ssize_t n, int nf) : nf_(nf) {
  state_ = fresh_array<double>(n, DN_LOOP_STATE_SIZE);
  for (auto& q : quantity_) q = fresh_array<double>(n);
  features_ = fresh_array<double>(n, nf);
  status_ = fresh_array<int32_t>(n);
}

SimulateArrays::SimulateArrays(const py::object& out_obj, py::ssize_t n, int nf,
                               std::initializer_list<Span> inputs)
    : nf_(nf) {
  if (!py::isinstance<py::dict>(out_obj))
    throw py::type_error("simulate: out must be None or a dict of arrays (a previous result)");
  const py::dict out = out_obj.cast<py::dict>();
  using AD = py::array_t<double>;
  state_ = take<AD>(out, "state", {n, (py::ssize_t)DN_LOOP_STATE_SIZE});
  for (std::size_t q = 0; q < kNumOutQuantities; ++q) quantity_[q] = take<AD>(out, kOutKeys[q], {n});
  features_ = take<AD>(out, "features", {n, (py::ssize_t)nf});
  status_ = take<py::array_t<int32_t>>(out, "status", {n});
  // The outputs are written while the inputs are read: they must not share memory.
  std::vector<py::array> outs{state_};
  for (const auto& q : quantity_) outs.push_back(q);
  outs.push_back(features_);
  outs.push_back(status_);
  for (const py::array& a : outs) {
    const Span o = span(a);
    for (const Span& i : inputs)
      if (overlap(o, i))
        throw py::value_error("simulate: out's arrays must not share memory with road, road_rate or u");
    for (const py::array& b : outs)
      if (&a != &b && a.nbytes() > 0 && overlap(o, span(b)))
        throw py::value_error("simulate: out's arrays must not share memory with each other");
  }
}

SimulateArrays::Writer SimulateArrays::writer() {
  Writer w;
  for (std::size_t q = 0; q < kNumOutQuantities; ++q) w.q[q] = quantity_[q].mutable_data();
  w.features = features_.mutable_data();
  w.nf = nf_;
  return w;
}

void SimulateArrays::Writer::operator()(py::ssize_t k, const dn_loop_out& o) const noexcept {
  for (std::size_t q = 0; q < kNumOutQuantities; ++q) this->q[q][k] = o.*kOutQuantities[q];
  for (int i = 0; i < nf; ++i) features[k * nf + i] = o.features[i];
}

py::dict SimulateArrays::to_dict() const {
  py::dict r;
  r["state"] = state_;
  for (std::size_t q = 0; q < kNumOutQuantities; ++q) r[kOutKeys[q]] = quantity_[q];
  r["features"] = features_;
  r["status"] = status_;
  return r;
}

}  // namespace dnpy
