// Prints the MLP kernel's backend this translation unit got (kernel/backend.hpp), as
// "kernel_isa NAME": ctest's test_kernel_backend compares it with the one CMake chose from its
// options, and tests/python/test_kernel_backend.py configures the options and checks it. The
// name is also in the binary as a string, for builds whose CPU cannot run the program.
#include <cstdio>

#include "dampnet/mlp.hpp"

extern "C" const char dn_kernel_backend_marker[] = "dn-kernel-backend:" DN_KERNEL_ISA ";";

int main() {
  std::printf("kernel_isa %s\n", dampnet::kernel_isa());
  return dn_kernel_backend_marker[0] == 'd' ? 0 : 1;
}
