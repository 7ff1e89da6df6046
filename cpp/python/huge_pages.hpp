// Why this exists: Loop.simulate writes ~10 fresh result arrays of one value per step; for
// long roads the first touch of fresh memory costs one page fault per 4 KiB, which on a VM
// costs more than the kernel's zeroing of the page. From 4 MiB up (Linux) the array's memory is therefore an
// anonymous mapping of whole, 2 MiB-aligned huge pages with MADV_HUGEPAGE (THP is
// "madvise" on many systems), owned by the array (a capsule unmaps it): first touch takes
// one page fault per 2 MiB. (numpy's own allocator advises huge pages for large arrays too,
// but its malloc'd blocks are not 2 MiB-aligned, so each array's first and last partial
// huge pages fault per 4 KiB.) Same contents, fresh memory; smaller arrays, other systems
// and any failure to map take numpy's allocator.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstddef>
#include <vector>

namespace dnpy {

namespace py = pybind11;

// A huge-page mapping of at least `bytes` and its owner (the capsule unmaps it), or a null
// pointer when the size is below the threshold, the system has none or mapping failed.
void* map_huge_pages(std::size_t bytes, py::object* owner);

// A fresh C-contiguous [rows] or [rows, cols] array (see the file comment).
template <class T>
py::array_t<T> fresh_array(py::ssize_t rows, py::ssize_t cols = -1) {
  const std::vector<py::ssize_t> shape = cols < 0 ? std::vector<py::ssize_t>{rows}
                                                  : std::vector<py::ssize_t>{rows, cols};
  const std::size_t bytes = std::size_t(rows) * std::size_t(cols < 0 ? 1 : cols) * sizeof(T);
  py::object owner;
  if (void* p = map_huge_pages(bytes, &owner)) return py::array_t<T>(shape, static_cast<T*>(p), owner);
  return py::array_t<T>(shape);
}

}  // namespace dnpy
