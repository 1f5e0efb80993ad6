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
# demos/: the play window's overlay, Dear ImGui with its GLFW and Vulkan backends (Debian's static
# library holds both; its pkg-config file adds stb, whose stb_truetype and stb_rect_pack it calls)
pkg_check_modules(IMGUI QUIET IMPORTED_TARGET imgui)
if(NOT IMGUI_FOUND)
  message(FATAL_ERROR "Dear ImGui not found: install the Debian package 'libimgui-dev'")
endif()

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
# the device path's FFTs: VkFFT (header only), which compiles its kernels with glslang's library
displace_require_package(glslang glslang-dev CONFIG)
# SPIRV-Tools' optimiser: render/pipelines.cpp freezes each pipeline's specialization constants with
# it, and tests/render/shader_size_test.cpp counts what each specialised pipeline holds (Debian's
# glslang-tools depends on the package)
displace_require_package(SPIRV-Tools-opt spirv-tools CONFIG)
find_path(VKFFT_INCLUDE_DIR vkFFT.h)
if(NOT VKFFT_INCLUDE_DIR)
  message(FATAL_ERROR "vkFFT.h not found: install the Debian package 'libvkfft-dev'")
endif()
# VkFFT 1.2.26 (Debian 12) initialises glslang's resource table for glslang 11, and glslang 12 added
# nine mesh-shader limits (the *_ext fields) before the last one: as C++ the header does not compile
# (and as C it fails on `= {}` for handles). The build uses a copy with the nine values added where
# glslang has them (glslang's own defaults); a header that needs no fix is used as it is.
set(DISPLACE_VKFFT_INCLUDE_DIR ${VKFFT_INCLUDE_DIR})
file(READ ${VKFFT_INCLUDE_DIR}/vkFFT.h vkfft_header)
find_path(GLSLANG_C_INTERFACE_DIR glslang/Include/glslang_c_interface.h)
file(READ ${GLSLANG_C_INTERFACE_DIR}/glslang/Include/glslang_c_interface.h glslang_interface)
set(vkfft_last_limit "/* .maxDualSourceDrawBuffersEXT = */ 1,")
if(glslang_interface MATCHES "max_mesh_output_vertices_ext" AND NOT vkfft_header MATCHES "maxMeshOutputVerticesEXT")
  string(REPLACE "${vkfft_last_limit}"
         "/* mesh limits of glslang 12, added by displace */ 256, 256, 128, 128, 128, 128, 128, 128, 4,\n${vkfft_last_limit}"
         vkfft_header "${vkfft_header}")
  # written only when it changes (file(WRITE) would touch it at every configure, and every file of
  # render/ that includes it would compile again)
  file(WRITE ${CMAKE_BINARY_DIR}/vkfft/vkFFT.h.new "${vkfft_header}")
  file(COPY_FILE ${CMAKE_BINARY_DIR}/vkfft/vkFFT.h.new ${CMAKE_BINARY_DIR}/vkfft/vkFFT.h ONLY_IF_DIFFERENT)
  set(DISPLACE_VKFFT_INCLUDE_DIR ${CMAKE_BINARY_DIR}/vkfft)
endif()

if(DISPLACE_TESTS)
  displace_require_package(GTest libgtest-dev CONFIG)
endif()
if(DISPLACE_BENCHMARKS)
  displace_require_package(benchmark libbenchmark-dev CONFIG)
endif()

# Debian's python3 (with the set-up's matplotlib, numpy and OpenImageIO), not one earlier on the PATH:
# the report's figures, the Python module and its tests
find_program(DISPLACE_SYSTEM_PYTHON python3 PATHS /usr/bin NO_DEFAULT_PATH)
if(NOT DISPLACE_SYSTEM_PYTHON)
  find_program(DISPLACE_SYSTEM_PYTHON python3 REQUIRED)
endif()
