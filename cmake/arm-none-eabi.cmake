# Cross toolchain for Arm Cortex-M (Debian's gcc-arm-none-eabi + libnewlib-arm-none-eabi):
#   cmake -B build/cortex-m4 --toolchain cmake/arm-none-eabi.cmake -DDAMPNET_ARM_CPU=cortex-m4
# or a preset of CMakePresets.json (cmake --preset cortex-m4). DAMPNET_ARM_CPU chooses the core:
#   cortex-m4  Cortex-M4F: -mcpu=cortex-m4 -mfpu=fpv4-sp-d16 -mfloat-abi=hard (single-precision FPU)
#   cortex-m7  Cortex-M7:  -mcpu=cortex-m7 -mfpu=fpv5-d16 -mfloat-abi=hard (double-precision FPU)
# The library is then built freestanding (CMakeLists.txt: no exceptions, RTTI or thread-safe
# statics, only the static library, dampnet's capacities lowered by DAMPNET_CAP_*), and the
# QEMU firmware of cpp/embedded/ beside it.
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)
set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_CXX_COMPILER arm-none-eabi-g++)
set(CMAKE_ASM_COMPILER arm-none-eabi-gcc)
set(CMAKE_AR arm-none-eabi-ar)
set(CMAKE_RANLIB arm-none-eabi-ranlib)
set(CMAKE_OBJCOPY arm-none-eabi-objcopy)
set(CMAKE_SIZE arm-none-eabi-size)
# Compiler checks build a static library (no start files or linker script here).
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)
set(CMAKE_TRY_COMPILE_PLATFORM_VARIABLES DAMPNET_ARM_CPU)

if(NOT DAMPNET_ARM_CPU)
  set(DAMPNET_ARM_CPU cortex-m4)
endif()
set(DAMPNET_ARM_CPU "${DAMPNET_ARM_CPU}" CACHE STRING "Arm core: cortex-m4 (M4F) or cortex-m7")
if(DAMPNET_ARM_CPU STREQUAL "cortex-m4")
  set(DN_ARM_FLAGS "-mcpu=cortex-m4 -mfpu=fpv4-sp-d16 -mfloat-abi=hard -mthumb")
elseif(DAMPNET_ARM_CPU STREQUAL "cortex-m7")
  set(DN_ARM_FLAGS "-mcpu=cortex-m7 -mfpu=fpv5-d16 -mfloat-abi=hard -mthumb")
else()
  message(FATAL_ERROR "DAMPNET_ARM_CPU=${DAMPNET_ARM_CPU}: expected cortex-m4 or cortex-m7")
endif()
set(CMAKE_C_FLAGS_INIT "${DN_ARM_FLAGS}")
set(CMAKE_CXX_FLAGS_INIT "${DN_ARM_FLAGS}")
set(CMAKE_ASM_FLAGS_INIT "${DN_ARM_FLAGS}")
# newlib-nano, our own start-up code, unused sections dropped.
set(CMAKE_EXE_LINKER_FLAGS_INIT "--specs=nano.specs -nostartfiles -Wl,--gc-sections")

set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
