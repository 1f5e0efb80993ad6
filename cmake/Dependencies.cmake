# Every dependency comes from a Debian package; a missing one stops the configure step with the
# package name to install (cmake/setup.sh installs them all).

macro(displace_require_package name debian_package)
  find_package(${name} ${ARGN} QUIET)
  if(NOT ${name}_FOUND)
    message(FATAL_ERROR "${name} not found: install the Debian package '${debian_package}' "
                        "(or run 'bash cmake/setup.sh build', which installs every dependency)")
  endif()
endmacro()

displace_require_package(TBB libtbb-dev CONFIG)
displace_require_package(PkgConfig pkg-config)
pkg_check_modules(FFTW3F QUIET IMPORTED_TARGET fftw3f)
if(NOT FFTW3F_FOUND)
  message(FATAL_ERROR "fftw3f (single precision FFTW) not found: install the Debian package 'libfftw3-dev'")
endif()
# OpenImageIO through pkg-config: Debian's CMake config for it also demands the command-line tools
# (openimageio-tools, which pulls in Qt) and an OpenCV include directory, neither of which we use.
pkg_check_modules(OPENIMAGEIO QUIET IMPORTED_TARGET OpenImageIO)
if(NOT OPENIMAGEIO_FOUND)
  message(FATAL_ERROR "OpenImageIO not found: install the Debian package 'libopenimageio-dev'")
endif()
find_package(Threads REQUIRED)
# pipeline/: scene files in TOML
displace_require_package(tomlplusplus libtomlplusplus-dev CONFIG)
# demos/: the command line (CLI11), text formatting (fmt) and the JSON of `bake --stats` (nlohmann-json)
displace_require_package(CLI11 libcli11-dev CONFIG)
displace_require_package(fmt libfmt-dev CONFIG)
displace_require_package(nlohmann_json nlohmann-json3-dev CONFIG)
# demos/: the `displace play` window (a Vulkan surface through GLFW; its tests run under xvfb-run)
displace_require_package(glfw3 libglfw3-dev CONFIG)

# render/: Vulkan (loader + headers), GLM, and glslang's compiler for the shaders at build time.
# The CPU driver (mesa-vulkan-drivers: lavapipe) and the validation layers are runtime packages;
# cmake/setup.sh installs them too.
find_package(Vulkan QUIET)
if(NOT Vulkan_FOUND)
  message(FATAL_ERROR "Vulkan not found: install the Debian package 'libvulkan-dev'")
endif()
displace_require_package(glm libglm-dev CONFIG)
find_program(GLSLANG_VALIDATOR glslangValidator)
if(NOT GLSLANG_VALIDATOR)
  message(FATAL_ERROR "glslangValidator not found: install the Debian package 'glslang-tools'")
endif()

if(DISPLACE_TESTS)
  displace_require_package(GTest libgtest-dev CONFIG)
endif()
if(DISPLACE_BENCHMARKS)
  displace_require_package(benchmark libbenchmark-dev CONFIG)
endif()
