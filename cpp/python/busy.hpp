// The busy flag of a mutable bound object (a Loop): one call at a time.
// A Loop is one loop state; two threads stepping it at once (simulate releases the GIL)
// would interleave their steps and both return wrong results. Serialising them with a
// lock would not make the results right either (each call continues from whatever state
// the other left), so a second concurrent call is refused with RuntimeError instead: the
// fix is one Loop per thread. The flag is an atomic exchange (a few ns per call), set by
// BusyGuard's constructor and cleared by its destructor, so no exception leaves it set.
#pragma once

#include <pybind11/pybind11.h>

#include <atomic>
#include <stdexcept>
#include <string>

namespace dnpy {

class BusyGuard {
 public:
  // what: "Loop.simulate"; contract: what to do instead, for the message.
  BusyGuard(std::atomic<bool>& flag, const char* what, const char* contract) : flag_(flag) {
    if (flag_.exchange(true, std::memory_order_acquire))
      throw std::runtime_error(std::string(what) +
                               ": this object is already in use by another call (another thread, "
                               "or a callback re-entering it); " + contract);
  }
  ~BusyGuard() { flag_.store(false, std::memory_order_release); }
  BusyGuard(const BusyGuard&) = delete;
  BusyGuard& operator=(const BusyGuard&) = delete;

 private:
  std::atomic<bool>& flag_;
};

inline constexpr const char* kLoopContract =
    "a Loop holds one mutable loop state and must not be used by two calls at once: give each "
    "thread its own Loop (Loop(model), QuarterCar.spawn()); a LoopModel, Damper and Mlp are "
    "immutable and may be shared between threads";

}  // namespace dnpy
