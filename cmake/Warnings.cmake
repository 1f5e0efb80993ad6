# Warnings and sanitizers as INTERFACE targets that every project target links.
add_library(displace_warnings INTERFACE)
target_compile_options(displace_warnings INTERFACE -Wall -Wextra -Wpedantic -Wshadow)

# Vulkan structs are value-initialised from their sType alone ({VK_STRUCTURE_TYPE_...}); the rest is
# zero. The Vulkan code links this after displace_options: clang takes the later of -Wextra and this.
add_library(displace_vulkan_structs INTERFACE)
target_compile_options(displace_vulkan_structs INTERFACE -Wno-missing-field-initializers)

add_library(displace_sanitizers INTERFACE)
# any undefined behaviour ends the program (a test fails), not a line in its output
if(DISPLACE_SANITIZE OR DISPLACE_FUZZ)
  # -g1: the line tables a report's stack needs, not the full debug information (a fifth of the
  # compile time)
  target_compile_options(displace_sanitizers INTERFACE -fsanitize=address,undefined -fno-sanitize-recover=undefined
                         -fno-omit-frame-pointer -g1)
  target_link_options(displace_sanitizers INTERFACE -fsanitize=address,undefined)
  # what code that must know asks (GCC says __SANITIZE_ADDRESS__, clang 14 only __has_feature)
  target_compile_definitions(displace_sanitizers INTERFACE DISPLACE_ADDRESS_SANITIZER=1)
  # clang's -fsanitize=undefined checks float-to-integer casts too (GCC's does not); one of them in a
  # header of Debian's toml++ is suppressed by its file name (tests/sanitizers/ubsan.supp), which only
  # a recoverable check allows: UBSAN_OPTIONS=halt_on_error=1 still stops at any other
  if(CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    target_compile_options(displace_sanitizers INTERFACE -fsanitize-recover=float-cast-overflow)
  endif()
endif()
if(DISPLACE_TSAN)
  if(DISPLACE_SANITIZE OR DISPLACE_FUZZ)
    message(FATAL_ERROR "DISPLACE_TSAN does not go with DISPLACE_SANITIZE or DISPLACE_FUZZ: one build each")
  endif()
  target_compile_options(displace_sanitizers INTERFACE -fsanitize=thread -fno-omit-frame-pointer -g1)
  target_link_options(displace_sanitizers INTERFACE -fsanitize=thread)
endif()
if(DISPLACE_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    message(FATAL_ERROR "DISPLACE_FUZZ needs clang (libFuzzer): configure with -DCMAKE_CXX_COMPILER=clang++")
  endif()
  # the fuzzer's coverage (-fsanitize=fuzzer-no-link) only in the code it fuzzes: the app layer, the
  # scene reader and the mesh checks (their CMakeLists). Its comparison tracing in every library made
  # the suite in the same build 3-4x slower (the bakers' inner loops); only the fuzz targets link
  # its main
endif()

add_library(displace_options INTERFACE)
target_link_libraries(displace_options INTERFACE displace_warnings displace_sanitizers)
# the build's own headers (displace/simd_clones.h)
target_include_directories(displace_options INTERFACE ${PROJECT_SOURCE_DIR}/cmake/include)
