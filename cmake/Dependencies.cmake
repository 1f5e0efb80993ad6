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
displace_require_package(OpenImageIO libopenimageio-dev CONFIG)
# Debian's OpenImageIO config lists /usr/include/opencv4 even when OpenCV's headers are not
# installed; keep only the include directories that exist.
get_target_property(_oiio_includes OpenImageIO::OpenImageIO INTERFACE_INCLUDE_DIRECTORIES)
set(_oiio_existing)
foreach(_dir IN LISTS _oiio_includes)
  if(EXISTS "${_dir}")
    list(APPEND _oiio_existing "${_dir}")
  endif()
endforeach()
set_target_properties(OpenImageIO::OpenImageIO PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${_oiio_existing}")
displace_require_package(PkgConfig pkg-config)
pkg_check_modules(FFTW3F QUIET IMPORTED_TARGET fftw3f)
if(NOT FFTW3F_FOUND)
  message(FATAL_ERROR "fftw3f (single precision FFTW) not found: install the Debian package 'libfftw3-dev'")
endif()
find_package(Threads REQUIRED)

if(DISPLACE_TESTS)
  displace_require_package(GTest libgtest-dev CONFIG)
endif()
if(DISPLACE_BENCHMARKS)
  displace_require_package(benchmark libbenchmark-dev CONFIG)
endif()
