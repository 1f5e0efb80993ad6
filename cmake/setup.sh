#!/usr/bin/env bash
# One-stop set-up for a fresh Debian machine: installs the missing Debian packages, configures and
# builds in ./build (Release), then runs what was asked:
#   bash cmake/setup.sh main    # the main job: the water scene as a seamless loop, and its frame budget (out/)
#   bash cmake/setup.sh test    # everything CI runs: format, suite, sanitize, fuzz, then tsan
#   bash cmake/setup.sh format  # every C++ file as clang-format writes it (tests/scripts/format_check.sh)
#   bash cmake/setup.sh suite   # the test suite on the Release build (ctest, about 2 minutes)
#   bash cmake/setup.sh sanitize  # the suite under ASan + UBSan (clang, build-asan/)
#   bash cmake/setup.sh tsan    # the tests of sim/, bake/, pipeline/ and the map packing under TSan, with a TBB built for it (build-tsan/)
#   bash cmake/setup.sh fuzz    # libFuzzer over the scene, OBJ, command-line and height-image readers (build-asan/)
#   bash cmake/setup.sh report  # docs/report/: what accuracy costs in time, measured here (about 6 minutes)
#   bash cmake/setup.sh build   # only install + configure + build
set -euo pipefail
mode="${1:-build}"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${DISPLACE_BUILD_DIR:-$root/build}"
source "$root/cmake/setup_lib.sh"

packages=(cmake g++ make pkg-config libtbb-dev libopenimageio-dev libfftw3-dev libgtest-dev libbenchmark-dev
          libvulkan-dev libglm-dev libtomlplusplus-dev libcli11-dev libfmt-dev nlohmann-json3-dev glslang-tools spirv-tools
          glslang-dev libvkfft-dev
          mesa-vulkan-drivers vulkan-validationlayers parallel libglfw3-dev libimgui-dev xvfb python3-matplotlib clang-format
          slurmctld slurmd slurm-client munge pybind11-dev python3-dev python3-numpy python3-openimageio)
missing=()
for p in "${packages[@]}"; do
  if ! package_installed "$p"; then
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

# how long a part took, for the README's account of the CI run
timed() {
  local started=$SECONDS
  "$@"
  echo "setup: $1 took $(( (SECONDS - started) / 60 )) min $(( (SECONDS - started) % 60 )) s"
}

# The Release build in build/, which every mode uses.
run_build() {
  cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build "$build" -j "$jobs"
}
timed run_build

# Every tracked C++ file as Debian's clang-format writes it under .clang-format.
run_format_check() {
  bash "$root/tests/scripts/format_check.sh" "$root"
}

# The test suite on the Release build.
run_suite() {
  (cd "$build" && ctest --output-on-failure -j "$jobs")
}

# The suite under ASan + UBSan in build-asan/, then libFuzzer over the four readers: one clang build
# for both (-DDISPLACE_FUZZ adds the fuzzers' coverage to the sanitizers; a second build of every
# library for the fuzzers alone cost a tenth of .ci/run). Any report fails it (-fno-sanitize-recover,
# abort).
install_clang() {
  local fuzz_packages=(clang libclang-rt-14-dev) p
  for p in "${fuzz_packages[@]}"; do
    if ! package_installed "$p"; then
      local sudo_cmd=()
      if [ "$(id -u)" -ne 0 ]; then sudo_cmd=(sudo); fi
      DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${fuzz_packages[@]}" >/dev/null
      break
    fi
  done
}
configure_sanitized() {
  install_clang
  # library leaks and undefined behaviour that are not ours are suppressed by library or file name
  # (tests/sanitizers/lsan.supp, ubsan.supp)
  export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:strict_string_checks=1"
  export LSAN_OPTIONS="suppressions=$root/tests/sanitizers/lsan.supp:print_suppressions=0"
  export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:abort_on_error=1:suppressions=$root/tests/sanitizers/ubsan.supp"
  CXX=clang++ cmake -S "$root" -B "$root/build-asan" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DDISPLACE_SANITIZE=ON \
    -DDISPLACE_FUZZ=ON -DDISPLACE_BENCHMARKS=OFF >/dev/null
}
run_sanitize() {
  configure_sanitized
  cmake --build "$root/build-asan" -j "$jobs"
  # leaks are checked where no Vulkan instance is made: the loader unloads lavapipe when the
  # instance goes, and what lavapipe keeps until then can no longer be named (or suppressed)
  local leak_checked='^((sim|bake)/.*|render/(cpu_trace|files)|demos|fuzz_.*_replay)$'
  # left out: the report (minutes of rendering, in Release already), the soak (a bound on resident
  # memory, which ASan's quarantine defeats), the fault and farm scripts (dozens of runs of
  # `displace` each, 4 minutes here under ASan; render/files runs the writer's faults under it), the
  # shader size guard and the device probe (SPIRV-Tools' work and lavapipe's, not ours), the
  # renderer's suites in one process (render_pipeline: 4.7 minutes here under ASan, mostly the CPU
  # reference traces the tests compare with; the renderer's host code runs under ASan in the
  # pipeline/* entries and the CLI tests), the sea-state figure's script (a plotting script's runs of
  # `displace sim`, whose code Cli.SimSaysWhatSeaItMade runs under ASan), the fuzzers (run_fuzz), and
  # the command-line tests that render the most frames and pictures through code the others run under
  # it (sequences by shards and loops, the frame benchmark, sweeps, frame 0 against render, the window's
  # frames, every tool's help text, and the help texts again in cli_docs), and the scripts' own
  # checks (setup_checks, scripts_lint: bash, nothing compiled): 115 s under ASan, an eighth of its
  # test time
  local cli_left_out='SequenceShardsAndResumesGiveTheSameFilesBitForBit|RenderDrawsTheFrameZeroOfTheSequence|PlayRendersThePipelinesFramesInAWindow|OutputsForToolsShareOneStyleAndTheirHelpNamesEveryKey|BenchFrameWritesTheTableAndItsJson|SequenceOfALoopSaysSoAndComesBackToFrameZero|SweepsASceneFileAndSaysWhatItsConeMapsCost|RendersConeMethodsFromMapsBakedAtALooseTolerance'
  local left_out="^report\$|^soak\$|^write/|^farm/|^render/shader_size\$|^device_probe\$|^render_pipeline\$|^sea_states_figure\$|^cli_docs\$|^setup_checks\$|^scripts_lint\$|^fuzz_(scene|obj|cli|image)\$|^Cli\.($cli_left_out)\$"
  (cd "$root/build-asan" && ctest --output-on-failure -j "$jobs" -R "$leak_checked" -E "$left_out")
  (cd "$root/build-asan" && ASAN_OPTIONS="$ASAN_OPTIONS:detect_leaks=0" \
    ctest --output-on-failure -j "$jobs" -E "$leak_checked|$left_out")
}

# libFuzzer over the scene, OBJ, command-line and height-image readers, a fixed number of inputs each
# (in build-asan/, which `sanitize` builds; built here when it is not).
run_fuzz() {
  configure_sanitized
  cmake --build "$root/build-asan" -j "$jobs" --target fuzz_scene fuzz_obj fuzz_cli fuzz_image
  (cd "$root/build-asan" && ctest --output-on-failure -j "$jobs" -R '^fuzz_(scene|obj|cli|image)$')
}

# ThreadSanitizer over the tests of the code that runs threads, in build-tsan/. Every thread here is
# a TBB worker, and TSan sees a
# task's handoff only inside an instrumented libtbb, which Debian does not ship: this builds one
# from Debian's own source of the installed libtbb-dev (fetched by apt from deb-src entries derived
# from the machine's configured deb entries, checked by apt against the signed index; Debian's
# patches touch other architectures and TBB's own tests only), once, into build-tsan/tbb/.
run_tsan() {
  local tsan_build="$root/build-tsan" tbb_root="$root/build-tsan/tbb"
  local version upstream source
  version="$(dpkg-query -W -f='${Version}' libtbb-dev)"
  source="$(dpkg-query -W -f='${source:Package}' libtbb-dev)"
  upstream="${version#*:}"
  upstream="${upstream%-*}"
  if [ ! -f "$tbb_root/install/lib/cmake/TBB/TBBConfig.cmake" ] || [ "$(cat "$tbb_root/version" 2>/dev/null)" != "$version" ]; then
    echo "setup: building libtbb $upstream with -fsanitize=thread (Debian source package $source $version)"
    rm -rf "$tbb_root"
    mkdir -p "$tbb_root"
    fetch_debian_source libtbb-dev "$version" "$tbb_root" || exit 1
    local tree candidate
    for candidate in "$tbb_root"/source/*/; do tree="${candidate%/}"; break; done
    # its compiler output (GCC warns that TSan does not model atomic_thread_fence) in a log, shown on failure
    local log="$tbb_root/build.log"
    if ! { cmake -S "$tree" -B "$tbb_root/build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DTBB_SANITIZE=thread \
             -DTBB_TEST=OFF -DTBB_STRICT=OFF -DTBBMALLOC_BUILD=OFF -DTBB_DISABLE_HWLOC_AUTOMATIC_SEARCH=ON \
             -DCMAKE_INSTALL_PREFIX="$tbb_root/install" &&
           cmake --build "$tbb_root/build" -j "$jobs" && cmake --install "$tbb_root/build"; } >"$log" 2>&1; then
      tail -n 40 "$log" >&2
      echo "setup: building the instrumented libtbb failed (log: $log)" >&2
      exit 1
    fi
    echo "$version" > "$tbb_root/version"
  fi
  cmake -S "$root" -B "$tsan_build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DDISPLACE_TSAN=ON -DDISPLACE_BENCHMARKS=OFF \
    -DTBB_DIR="$tbb_root/install/lib/cmake/TBB" >/dev/null
  # the code that runs threads of its own: sim/ and bake/ (TBB), render/'s map packing (TBB) and
  # pipeline/ (the frame's stages, the maps, the queries); the app layer starts none but through
  # these (its report, the one that does, is left out as below), and lavapipe's threads are not
  # instrumented (TSan cannot see them)
  cmake --build "$tsan_build" -j "$jobs" --target displace_sim_tests displace_bake_tests displace_device_tests
  # a run against Debian's uninstrumented libtbb would report every handoff: refuse it
  local program
  for program in "$tsan_build/tests/displace_bake_tests" "$tsan_build/tests/displace_device_tests"; do
    if ! loads_library "$program" "$tbb_root/install/lib/libtbb"; then
      echo "setup: $program does not load the instrumented libtbb from $tbb_root" >&2
      exit 1
    fi
  done
  # reports go to files (some tests capture stderr, and a report there would be lost), shown on failure
  local reports="$tsan_build/tsan-reports"
  rm -rf "$reports"
  mkdir -p "$reports"
  export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:suppressions=$root/tests/sanitizers/tsan.supp:log_path=$reports/report"
  # (the frame pipeline's, the thread pinning's and the map uploads' suites, which run in the shared
  # entry render_pipeline elsewhere: in render_pipeline/threads here, without the rest of its rendering)
  if ! (cd "$tsan_build" &&
          ctest --output-on-failure -j "$jobs" -R '^(sim|bake|pipeline)/|^render/map_pack$|^render_pipeline/threads$'); then
    cat "$reports"/report* >&2 2>/dev/null || true
    exit 1
  fi
}

case "$mode" in
  build) ;;
  main)
    cd "$root"
    # the product: the water scene to the horizon as a seamless 12 s loop (120 frames at 10 fps: frame
    # 120 would be frame 0 bit for bit) with an animated preview that loops, then the frame-budget table
    "$build/displace" sequence --scene water --map-size 256 --size 480x270 --frames 0:119 --fps 10 \
      --loop-seconds 12 --bake-work 20000 --output out/water/water_####.png --preview out/water.gif
    "$build/displace" bench-frame --scene water --map-size 256 --size 256x256 --frames 60 --budget-ms 33 \
      --json out/bench-frame.json
    if [ -n "${DISPLAY:-}${WAYLAND_DISPLAY:-}" ]; then
      echo "a display is here: 'build/displace play' opens the water demo in a window (keys: build/displace play --help)"
    fi ;;
  report)
    cd "$root"
    "$build/displace" report --output docs/report ;;
  format) timed run_format_check ;;
  suite) timed run_suite ;;
  sanitize) timed run_sanitize ;;
  fuzz) timed run_fuzz ;;
  tsan) timed run_tsan ;;
  test)
    timed run_format_check
    timed run_suite
    timed run_sanitize
    timed run_fuzz
    timed run_tsan ;;
  *)
    echo "setup: unknown mode '$mode' (use main, test, format, suite, sanitize, tsan, fuzz, report or build)" >&2
    exit 2 ;;
esac
