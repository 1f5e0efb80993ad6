#!/usr/bin/env bash
# tests/soak.sh - the frame loop for many frames, checked for leaks, validation messages and lost
# frames: `displace bench-frame` on the water scene at a small size (64 x 64 map and pixels, every
# stage still runs: the ocean's six FFTs, the cone bake with 500 texels of refinement a frame, the
# upload, the render and its readback) under the Khronos validation layer. It fails when
#   - displace exits with an error or writes anything on stderr (a validation message fails it),
#   - fewer frames come back than were asked for,
#   - resident memory (VmRSS, sampled inside the process) grows by more than MAX_GROWTH_KB from the
#     end of the warm-up to the end of the run.
#
# usage: tests/soak.sh DISPLACE_BINARY [FRAMES (default 1000)] [MAX_GROWTH_KB (default 1024)]
# ctest runs it with 1000 frames; docs/figures.md (Reliability and the test suite) has a run of 10000.
set -euo pipefail

binary="${1:?usage: tests/soak.sh DISPLACE_BINARY [FRAMES] [MAX_GROWTH_KB]}"
frames="${2:-1000}"
max_growth_kb="${3:-1024}"
warm_up=100  # frames before the first sample: the allocator's and the driver's first touches

work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

start=$(date +%s)
status=0
"$binary" bench-frame --scene water --map-size 64 --size 64x64 --frames "$frames" --warm-up "$warm_up" \
  --bake-work 500 --validate --json "$work/soak.json" >"$work/stdout.txt" 2>"$work/stderr.txt" || status=$?
seconds=$(( $(date +%s) - start ))

fail() {
  echo "soak: FAILED: $*" >&2
  exit 1
}
if [ "$status" -ne 0 ]; then
  head -c 2000 "$work/stderr.txt" >&2
  fail "displace bench-frame exited with status $status"
fi
if [ -s "$work/stderr.txt" ]; then
  head -c 2000 "$work/stderr.txt" >&2
  fail "displace wrote to stderr (validation messages?)"
fi

# one number of the JSON written by bench-frame (nlohmann's dump(2): one key a line)
# (the first match; sed reads the file itself, so no pipe can break under pipefail)
number() { sed -n "/^ *\"$1\": -\{0,1\}[0-9][0-9]*,\{0,1\}$/{s/^ *\"$1\": \(-\{0,1\}[0-9][0-9]*\),\{0,1\}$/\1/p;q;}" "$work/soak.json"; }
rendered="$(number frames_rendered)"
after="$(number after_warmup)"
end="$(number end)"
growth="$(number growth)"
most="$(number max)"
[ -n "$rendered" ] && [ -n "$growth" ] || fail "no frames_rendered or rss_kb in the JSON of bench-frame"

echo "soak: $rendered of $frames frames in ${seconds} s; resident memory ${after} kB after the warm-up of" \
     "$warm_up frames, ${end} kB at the end (${growth} kB more), at most ${most} kB"
[ "$rendered" -eq "$frames" ] || fail "$rendered of $frames frames came back"
[ "$growth" -le "$max_growth_kb" ] || fail "resident memory grew by $growth kB (more than $max_growth_kb kB)"
echo "soak: passed"
