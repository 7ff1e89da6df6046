// Not linked into anything: compiled by cpp/embedded/CMakeLists.txt (try_compile) for the
// target, which reads these digits out of the object to write dn_sizes.h, the sizes of the
// C ABI's objects in this build (what dn_*_size() return) as constants a C firmware can size
// static storage with. (CMake's CheckTypeSize reads sizeof the same way when cross-compiling.)
#include "../src/internal.hpp"

#define DN_DIGIT_(n, k) char('0' + ((n) / (k)) % 10)
#define DN_NUM_(n) DN_DIGIT_(n, 100000), DN_DIGIT_(n, 10000), DN_DIGIT_(n, 1000), DN_DIGIT_(n, 100), \
                   DN_DIGIT_(n, 10), DN_DIGIT_(n, 1)
constexpr size_t kAlign = alignof(dn_mlp) > alignof(dn_damper) ? alignof(dn_mlp) : alignof(dn_damper);
constexpr size_t kAlign2 = alignof(dn_loop_model) > alignof(dn_loop_data) ? alignof(dn_loop_model) : alignof(dn_loop_data);
extern "C" const char dn_sizes_info[] = {
    'D', 'N', 'S', 'I', 'Z', 'E', 'S', '[', DN_NUM_(sizeof(dn_mlp)), ',', DN_NUM_(sizeof(dn_damper)), ',',
    DN_NUM_(sizeof(dn_loop_model)), ',', DN_NUM_(sizeof(dn_loop_data)), ',',
    DN_NUM_(kAlign > kAlign2 ? kAlign : kAlign2), ']', 0};
