#!/bin/bash
# tests/device/pack.sh BUILD_DIR PACK_DIR - packs the Vulkan-only test program and the device probe
# (displace_device_tests, displace_device_probe) with the shared libraries they load, the Khronos
# validation layer and a run script, for a machine with a GPU and a Vulkan driver but none of this
# project's packages (no apt-get there). About 40 MB; OpenImageIO's 260 libraries stay behind, which
# is why these two programs do without the application layer.
#
# On the GPU machine: bash PACK_DIR/run.sh [OUT_DIR] runs every suite of displace_device_tests with
# validation on, then the probe (tests/device/device_probe.cpp), writing tests.txt, probe.txt and the
# probe's pictures to OUT_DIR (default: PACK_DIR/out). DISPLACE_PACK_TESTS=0 skips the tests; the
# probe's own variables (DISPLACE_PROBE_PART, _DEVICE_BAKE, _DEVICE_RINGS, _CONE_MAPS) pass through.
set -euo pipefail
if [ $# -ne 2 ]; then
  echo "usage: $0 BUILD_DIR PACK_DIR" >&2
  exit 2
fi
build=$1
pack=$2
for program in displace_device_tests displace_device_probe; do
  if [ ! -x "$build/tests/$program" ]; then
    echo "$0: error: $build/tests/$program is missing; build it first (cmake --build $build)" >&2
    exit 1
  fi
done
rm -rf "$pack"
mkdir -p "$pack/lib" "$pack/glibc" "$pack/layers"
cp "$build/tests/displace_device_tests" "$build/tests/displace_device_probe" "$pack/"

# glibc goes apart: the programs use the machine's own when it is as new as this one's, else this
# one's through its loader
glibc='^(libc|libm|libdl|libpthread|librt)\.so|^ld-linux'
for library in $(ldd "$pack/displace_device_tests" "$pack/displace_device_probe" | awk '$3 ~ /^\// {print $3}' | sort -u); do
  if [[ $(basename "$library") =~ $glibc ]]; then
    cp -L "$library" "$pack/glibc/"
  else
    cp -L "$library" "$pack/lib/"
  fi
done
for library in libdl.so.2 libpthread.so.0 librt.so.1; do
  [ -e "/lib/x86_64-linux-gnu/$library" ] && cp -L "/lib/x86_64-linux-gnu/$library" "$pack/glibc/"
done
cp -L "$(ldd "$pack/displace_device_tests" | awk '/ld-linux/ {print $1}')" "$pack/glibc/"

# glvnd's libraries: the NVIDIA driver's Vulkan ICD (libGLX_nvidia) needs libGLdispatch and libEGL,
# and a bare machine may have the driver without them (on an H200 without libEGL the loader said
# "Could not get 'vkCreateInstance' via 'vk_icdGetInstanceProcAddr'" and found no driver)
for library in libGLdispatch.so.0 libGLX.so.0 libEGL.so.1; do
  if [ -e "/lib/x86_64-linux-gnu/$library" ]; then
    cp -L "/lib/x86_64-linux-gnu/$library" "$pack/lib/"
  else
    echo "$0: warning: no $library here; an NVIDIA driver without it will not load" >&2
  fi
done

# the validation layer (the tests assert zero messages), found by the loader through VK_LAYER_PATH
layer=/usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json
layer_library=/usr/lib/x86_64-linux-gnu/libVkLayer_khronos_validation.so
if [ -f "$layer" ] && [ -f "$layer_library" ]; then
  cp "$layer" "$pack/layers/"
  cp -L "$layer_library" "$pack/lib/"
else
  echo "$0: warning: no validation layer here ($layer); the tests that turn it on will fail" >&2
fi

cat > "$pack/run.sh" <<'EOF'
#!/bin/bash
# Runs the packed tests and probe on this machine (see tests/device/pack.sh).
here=$(cd "$(dirname "$0")" && pwd)
out=${1:-$here/out}
mkdir -p "$out"
export LD_LIBRARY_PATH=$here/lib VK_LAYER_PATH=$here/layers DISPLACE_PIPELINE_CACHE=off
# the NVIDIA driver's manifest where a container mounts it, when the usual places have none
icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
if [ -z "${VK_DRIVER_FILES:-}" ] && [ -f "$icd" ] && ! ls /usr/share/vulkan/icd.d/*.json /etc/vulkan/icd.d/*.json >/dev/null 2>&1; then
  export VK_DRIVER_FILES=$icd
fi
run=()
if ! "$here/displace_device_tests" --gtest_list_tests >/dev/null 2>&1; then
  echo "this machine's glibc is older than the build's: using the packed one"
  run=("$here/glibc/$(ls "$here/glibc" | grep ld-linux)" --library-path "$here/lib:$here/glibc")
fi
if [ "${DISPLACE_PACK_TESTS:-1}" != 0 ]; then
  "${run[@]}" "$here/displace_device_tests" > "$out/tests.txt" 2>&1
  echo "tests: exit $?"
  grep -E '^\[  (FAILED|PASSED) ' "$out/tests.txt"
fi
"${run[@]}" "$here/displace_device_probe" "$out" > "$out/probe.txt" 2>&1
echo "probe: exit $?"
grep -E '^(device|scene|frame)' "$out/probe.txt"
EOF
chmod +x "$pack/run.sh"
echo "packed into $pack ($(du -sh "$pack" | cut -f1)); on the GPU machine: bash $pack/run.sh [OUT_DIR]"
