#!/usr/bin/env bash
# One-stop set-up for a fresh Debian machine: installs the missing Debian packages, configures and
# builds in ./build (Release), then runs what was asked:
#   bash cmake/setup.sh main    # the main job: the built-in water scene as a sequence, and its frame budget (out/)
#   bash cmake/setup.sh test    # everything CI runs: suite, then sanitize, then fuzz (15-30 minutes)
#   bash cmake/setup.sh suite   # the test suite on the Release build (ctest, about 2 minutes)
#   bash cmake/setup.sh sanitize  # the suite under ASan + UBSan (build-asan/)
#   bash cmake/setup.sh fuzz    # libFuzzer over the scene, OBJ, command-line and height-image readers (clang, build-fuzz/)
#   bash cmake/setup.sh report  # docs/report/: what accuracy costs in time, measured here (about 6 minutes)
#   bash cmake/setup.sh build   # only install + configure + build
set -euo pipefail
mode="${1:-build}"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${DISPLACE_BUILD_DIR:-$root/build}"

packages=(cmake g++ make pkg-config libtbb-dev libopenimageio-dev libfftw3-dev libgtest-dev libbenchmark-dev
          libvulkan-dev libglm-dev libtomlplusplus-dev libcli11-dev libfmt-dev nlohmann-json3-dev glslang-tools
          mesa-vulkan-drivers vulkan-validationlayers parallel libglfw3-dev xvfb python3-matplotlib)
missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing missing Debian packages: ${missing[*]}"
  sudo_cmd=()
  if [ "$(id -u)" -ne 0 ]; then sudo_cmd=(sudo); fi
  "${sudo_cmd[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

jobs="$(nproc 2>/dev/null || echo 2)"
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j "$jobs"

# The test suite on the Release build.
run_suite() {
  (cd "$build" && ctest --output-on-failure -j "$jobs")
}

# The suite under ASan + UBSan in build-asan/: any report fails it (-fno-sanitize-recover, abort).
run_sanitize() {
  # library leaks that are not ours are suppressed by library name (tests/sanitizers/lsan.supp)
  export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:strict_string_checks=1"
  export LSAN_OPTIONS="suppressions=$root/tests/sanitizers/lsan.supp:print_suppressions=0"
  export UBSAN_OPTIONS="print_stacktrace=1"
  cmake -S "$root" -B "$root/build-asan" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DDISPLACE_SANITIZE=ON \
    -DDISPLACE_BENCHMARKS=OFF >/dev/null
  cmake --build "$root/build-asan" -j "$jobs"
  # leaks are checked where no Vulkan instance is made: the loader unloads lavapipe when the
  # instance goes, and what lavapipe keeps until then can no longer be named (or suppressed)
  local leak_checked='^(sim|bake|budgeted|bilinear|app|fuzz_.*_replay)$'
  (cd "$root/build-asan" && ctest --output-on-failure -j "$jobs" -R "$leak_checked")
  (cd "$root/build-asan" && ASAN_OPTIONS="$ASAN_OPTIONS:detect_leaks=0" \
    ctest --output-on-failure -j "$jobs" -E "$leak_checked|^report\$|^soak\$")
}

# libFuzzer (clang) over the four readers in build-fuzz/, a fixed number of inputs each.
run_fuzz() {
  local fuzz_packages=(clang libclang-rt-14-dev) p
  for p in "${fuzz_packages[@]}"; do
    if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
      local sudo_cmd=()
      if [ "$(id -u)" -ne 0 ]; then sudo_cmd=(sudo); fi
      DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${fuzz_packages[@]}" >/dev/null
      break
    fi
  done
  local fuzz_build="$root/build-fuzz"
  CXX=clang++ cmake -S "$root" -B "$fuzz_build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DDISPLACE_FUZZ=ON \
    -DDISPLACE_BENCHMARKS=OFF >/dev/null
  cmake --build "$fuzz_build" -j "$jobs" --target fuzz_scene fuzz_obj fuzz_cli fuzz_image
  (cd "$fuzz_build" && ctest --output-on-failure -R '^fuzz_(scene|obj|cli|image)$')
}

# how long a part took, for the README's account of the CI run
timed() {
  local started=$SECONDS
  "$@"
  echo "setup: $1 took $(( (SECONDS - started) / 60 )) min $(( (SECONDS - started) % 60 )) s"
}

case "$mode" in
  build) ;;
  main)
    cd "$root"
    # the product: 1.5 s of the water scene as a headless sequence with an animated preview, then the
    # frame-budget table
    "$build/displace" sequence --scene water --map-size 256 --size 480x270 --frames 0:89 --bake-work 20000 \
      --output out/water/water_####.png --preview out/water.gif
    "$build/displace" bench-frame --scene water --map-size 256 --size 256x256 --frames 60 --budget-ms 33 \
      --json out/bench-frame.json
    if [ -n "${DISPLAY:-}${WAYLAND_DISPLAY:-}" ]; then
      echo "a display is here: 'build/displace play' opens the water demo in a window (keys: build/displace play --help)"
    fi ;;
  report)
    cd "$root"
    "$build/displace" report --output docs/report ;;
  suite) timed run_suite ;;
  sanitize) timed run_sanitize ;;
  fuzz) timed run_fuzz ;;
  test)
    timed run_suite
    timed run_sanitize
    timed run_fuzz ;;
  *)
    echo "setup: unknown mode '$mode' (use main, test, suite, sanitize, fuzz, report or build)" >&2
    exit 2 ;;
esac
