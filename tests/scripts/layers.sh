#!/usr/bin/env bash
# The layers, checked from the sources: every project include ("dir/...") of a file goes to its own
# layer or one below it, so that data and dependencies run one way and no cycle can form:
#   sim, bake (CPU)  <-  vulkan (the Vulkan base)  <-  sim/device, bake/device  <-  render  <-  pipeline  <-  demos
# sim/device may use sim and vulkan, bake/device bake and vulkan; render bake and vulkan (it samples
# what the device stages wrote through vulkan/device_maps.h, never their classes); pipeline all of
# them. "spirv/" (the build's compiled shaders) and "displace/" (cmake/include) belong to no layer.
# sim/ and bake/ outside their device/ include no Vulkan header and link no Vulkan.
#   layers.sh SOURCE_DIR
set -euo pipefail
cd "$1"

allowed() { # the layer of a path, then the include prefixes it may use
  case "$1" in
    sim/device/*) echo "sim/ vulkan/" ;;
    bake/device/*) echo "bake/ vulkan/" ;;
    sim/*) echo "sim/" ;;
    bake/*) echo "bake/" ;;
    vulkan/*) echo "vulkan/" ;;
    render/*) echo "render/ bake/ vulkan/" ;;
    pipeline/*) echo "pipeline/ render/ sim/ bake/ vulkan/" ;;
    demos/*) echo "demos/ pipeline/ render/ sim/ bake/ vulkan/" ;;
  esac
}

failures=0
checked=0
while IFS= read -r file; do
  allow="$(allowed "$file")"
  while IFS= read -r target; do
    # a name without a directory is a sibling (a shader's include from its own shaders/ directory)
    [[ -z "$target" || "$target" != */* || "$target" == spirv/* || "$target" == displace/* ]] && continue
    ok=0
    for prefix in $allow; do
      [[ "$target" == "$prefix"* ]] && ok=1
    done
    # within sim/ and bake/, the device parts are a layer above the CPU parts
    if [[ "$file" != sim/device/* && "$target" == sim/device/* && "$file" == sim/* ]]; then ok=0; fi
    if [[ "$file" != bake/device/* && "$target" == bake/device/* && "$file" == bake/* ]]; then ok=0; fi
    if [[ "$file" == render/* && ( "$target" == sim/device/* || "$target" == bake/device/* ) ]]; then ok=0; fi
    if ((ok == 0)); then
      echo "layers: $file includes $target, which is not below it" >&2
      failures=$((failures + 1))
    fi
    checked=$((checked + 1))
  done < <(sed -n 's/^[[:space:]]*#include "\([^"]*\)".*/\1/p' "$file")
done < <(find sim bake vulkan render pipeline demos \( -name '*.h' -o -name '*.cpp' -o -name '*.glsl' \) | sort)

# the CPU layers use no Vulkan at all: they build and link without it
while IFS= read -r file; do
  if grep -q '^[[:space:]]*#include <vulkan/' "$file"; then
    echo "layers: $file includes a Vulkan header; sim/ and bake/ (but their device/) are CPU only" >&2
    failures=$((failures + 1))
  fi
done < <(find sim bake \( -path sim/device -o -path bake/device \) -prune -o \( -name '*.h' -o -name '*.cpp' \) -print)
if grep -qi vulkan sim/CMakeLists.txt bake/CMakeLists.txt; then
  echo "layers: sim/ or bake/ links Vulkan (their CMakeLists.txt)" >&2
  failures=$((failures + 1))
fi

if ((failures > 0)); then
  echo "layers: $failures includes run back up a layer or bring Vulkan into a CPU layer" >&2
  exit 1
fi
echo "layers: $checked includes checked, every one runs down"
