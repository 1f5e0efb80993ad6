#!/usr/bin/env bash
# The installed package from a program outside the project (issue 33): installs the build into a
# temporary prefix, configures demos/embed against it alone, builds and runs it.
#   install_test.sh SOURCE_DIR BUILD_DIR WORK_DIR CXX_COMPILER
set -euo pipefail
source_dir="$1"
build_dir="$2"
work="$3"
compiler="$4"
rm -rf "$work"
mkdir -p "$work"
prefix="$work/prefix"

cmake --install "$build_dir" --prefix "$prefix" >"$work/install.log"
# the package names nothing of the source or build tree: it works where they are gone
if grep -rlF -e "$source_dir" -e "$build_dir" "$prefix/lib/cmake/displace"; then
  echo "install_test: the package refers to the source or build tree (above)" >&2
  exit 1
fi
for header in sim/sim.h sim/device/device_sim.h bake/bake.h bake/device/device_cones.h render/render.h \
    pipeline/frame_pipeline.h pipeline/query.h vulkan/device_info.h vulkan/error.h; do
  test -f "$prefix/include/displace/$header" || { echo "install_test: $header not installed" >&2; exit 1; }
done

# every installed header compiles on its own (it includes what it uses), and the headers that only
# name a device (a scene's) pull in no Vulkan
include_dir="$prefix/include/displace"
count=0
while IFS= read -r header; do
  relative="${header#"$include_dir"/}"
  if ! printf '#include "%s"\nint main() {}\n' "$relative" |
      "$compiler" -std=c++20 -fsyntax-only -I"$include_dir" -x c++ - 2>"$work/header.log"; then
    cat "$work/header.log" >&2
    echo "install_test: $relative does not compile on its own" >&2
    exit 1
  fi
  count=$((count + 1))
done < <(find "$include_dir" -name '*.h' | sort)
for header in pipeline/scene.h vulkan/device_info.h sim/sim.h sim/device/device_sim.h bake/bake.h \
    bake/device/device_cones.h render/files.h; do
  dependencies="$(printf '#include "%s"\n' "$header" | "$compiler" -std=c++20 -M -I"$include_dir" -x c++ -)"
  if [[ "$dependencies" == *vulkan/vulkan* ]]; then  # the Vulkan headers, not displace's vulkan/ base
    echo "install_test: $header includes Vulkan" >&2
    exit 1
  fi
done

cmake -S "$source_dir/demos/embed" -B "$work/embed" -DCMAKE_PREFIX_PATH="$prefix" \
  -DCMAKE_CXX_COMPILER="$compiler" >"$work/configure.log"
cmake --build "$work/embed" >"$work/build.log"
"$work/embed/embed" "$work/last.png" | tee "$work/run.log"
grep -q "^frame 9 at" "$work/run.log"
test "$(grep -c "^height at" "$work/run.log")" -eq 3
test -s "$work/last.png"

# the version: the project's, and an incompatible request is refused
version="$(sed -n 's/^set(PACKAGE_VERSION "\(.*\)")$/\1/p' "$prefix/lib/cmake/displace/displaceConfigVersion.cmake")"
project_version="$(sed -n 's/^project(displace VERSION \([0-9.]*\) .*/\1/p' "$source_dir/CMakeLists.txt")"
test "$version" = "$project_version" || { echo "install_test: package version $version, project $project_version" >&2; exit 1; }
mkdir -p "$work/newer"
printf 'cmake_minimum_required(VERSION 3.25)\nproject(newer LANGUAGES CXX)\nfind_package(displace 99.0 CONFIG REQUIRED)\n' \
  >"$work/newer/CMakeLists.txt"
if cmake -S "$work/newer" -B "$work/newer/build" -DCMAKE_PREFIX_PATH="$prefix" >"$work/newer.log" 2>&1; then
  echo "install_test: find_package(displace 99.0) accepted version $version" >&2
  exit 1
fi
# the Python module (issue 51), where the build made it: a fresh Debian python3 with only the prefix on
# its path (not the build tree) imports it and runs one query
python_dir="$prefix/lib/python3/dist-packages"
module="no Python module"
if [ -d "$build_dir/python/displace" ]; then
  test -f "$python_dir/displace/__init__.pyi" || { echo "install_test: the module's stubs are not installed" >&2; exit 1; }
  env -i PATH=/usr/bin:/bin PYTHONPATH="$python_dir" HOME="$work" /usr/bin/python3 -c '
import displace, sys
assert displace.__file__.startswith(sys.argv[1]), displace.__file__
result = displace.query(displace.Scene.builtin("calm"), 1.0, [[3.0, 4.0]])
print("python: height at (3, 4) m:", float(result["height_m"][0]))
' "$python_dir" | tee "$work/python.log"
  grep -q "^python: height at" "$work/python.log"
  module="the Python module imported from it"
fi
echo "install_test: displace $version installed ($count headers, each compiling on its own), demos/embed built against it and ran, $module"
