#!/usr/bin/env bash
# tests/bench/compare.sh - the frame's stages of this tree and of another revision, side by side.
#
# usage: tests/bench/compare.sh [--quick] [--cpu-only] [--rounds N] [--frames N] [--views REGEX] [--output FILE.md] REV
#
# Builds REV (any git revision) in a worktree under build-compare/ and this tree in build/, then runs
# `displace bench-frame --serial --budget-ms 0` with both binaries for every view of a fixed set, the
# two in turn (REV, this, REV, this, ... for --rounds rounds) so that both see the same load, and
# prints a Markdown table: for each stage (sim, bake, render, frame) the median over the rounds of
# each build's p50 milliseconds, and their ratio (this / REV; above 1: this tree is slower).
# Run it before landing a change to render/, its shaders or pipeline/ (docs/figures.md keeps a table).
#
# The set: water and calm on their patch (extent patch) and to the horizon (unbounded), bricks, cliff;
# acm4, csm, relief and relaxed; maps and images of 256 and 512 a side; the CPU backend everywhere and
# the device backend (sim and cone bake in compute shaders) on the two ocean scenes with acm4 and csm.
# relaxed runs on the static scenes only: on a moving sea its bake takes seconds a frame.
# --quick: 256 only, CPU only; --cpu-only: no device backend (on lavapipe its bake takes seconds).
# A view a binary cannot run (a flag it lacks; `--extent patch` is dropped for a binary that has no
# --extent, whose water was the patch) is "-" in its column. Both binaries share one pipeline cache.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
rounds=2
frames=40
device_frames=8
quick=0
cpu_only=0
views_filter='.*'
output=""
revision=""
while [ $# -gt 0 ]; do
  case "$1" in
    --quick) quick=1; cpu_only=1 ;;
    --cpu-only) cpu_only=1 ;;
    --rounds) rounds="$2"; shift ;;
    --frames) frames="$2"; shift ;;
    --views) views_filter="$2"; shift ;;
    --output) output="$2"; shift ;;
    -h|--help) sed -n '2,19p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; exit 0 ;;
    -*) echo "compare: unknown option $1 (see --help)" >&2; exit 2 ;;
    *) revision="$1" ;;
  esac
  shift
done
if [ -z "$revision" ]; then
  echo "compare: which revision? (tests/bench/compare.sh REV; see --help)" >&2
  exit 2
fi
sha="$(git -C "$root" rev-parse --verify "$revision^{commit}")" || {
  echo "compare: '$revision' is not a revision of $root" >&2
  exit 2
}
short="$(git -C "$root" rev-parse --short "$sha")"
jobs="$(nproc 2>/dev/null || echo 2)"

# the two builds (Release, the command-line program only)
base="$root/build-compare"
tree="$base/$short"
if [ ! -d "$tree" ]; then
  mkdir -p "$base"
  git -C "$root" worktree add --detach "$tree" "$sha" >/dev/null
fi
build_one() {
  cmake -S "$1" -B "$2" -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build "$2" -j "$jobs" --target displace >/dev/null
}
echo "compare: building $short in $tree/build and this tree in build/" >&2
build_one "$tree" "$tree/build"
build_one "$root" "$root/build"
old="$tree/build/displace"
new="$root/build/displace"
cache="$base/pipeline-cache"
mkdir -p "$cache"
old_help="$("$old" bench-frame --help)"
new_help="$("$new" bench-frame --help)"

# name | scene flags
views=("water-patch|--scene water --extent patch" "water|--scene water --extent unbounded"
       "calm-patch|--scene calm --extent patch" "calm|--scene calm --extent unbounded" "bricks|--scene bricks"
       "cliff|--scene cliff")
methods=(acm4 csm relief relaxed)
sizes=(256 512)
if [ "$quick" -eq 1 ]; then sizes=(256); fi

# The flags as the binary with this help takes them, or nothing when it cannot run them.
flags_for() {
  local help="$1" flag result=()
  shift
  while [ $# -gt 0 ]; do
    flag="$1"
    if [[ "$flag" == --* ]] && ! grep -qF -- "$flag " <<<"$help"; then
      if [ "$flag" = "--extent" ] && [ "${2:-}" = "patch" ]; then
        shift 2
        continue
      fi
      return 1
    fi
    result+=("$flag")
    shift
  done
  echo "${result[@]}"
}

scratch="$(mktemp -d)"
trap 'rm -rf "$scratch"' EXIT
# One bench-frame run; prints "sim bake render frame" p50s, or "- - - -".
run_one() {
  local binary="$1" help="$2" json="$3"
  shift 3
  local flags
  if ! flags="$(flags_for "$help" "$@")"; then
    echo "- - - -"
    return
  fi
  # shellcheck disable=SC2086
  if ! "$binary" bench-frame $flags --json "$json" --pipeline-cache "$cache" >"$json.log" 2>&1; then
    echo "compare: failed: $binary bench-frame $flags (log: see below)" >&2
    tail -n 5 "$json.log" >&2
    echo "- - - -"
    return
  fi
  python3 - "$json" <<'EOF'
import json, sys
stages = json.load(open(sys.argv[1]))["stages"]
print(" ".join(f'{stages[s]["p50_ms"]:.3f}' if s in stages else "-" for s in ("sim", "bake", "render", "frame")))
EOF
}

rows="$scratch/rows"
: >"$rows"
for size in "${sizes[@]}"; do
  for view in "${views[@]}"; do
    name="${view%%|*}"
    scene="${view#*|}"
    [[ "$name" =~ $views_filter ]] || continue
    backends=(cpu)
    if [ "$cpu_only" -eq 0 ] && [[ "$name" == water* || "$name" == calm* ]]; then backends+=(device); fi
    for backend in "${backends[@]}"; do
      for method in "${methods[@]}"; do
        if [ "$backend" = device ] && [[ "$method" != acm4 && "$method" != csm ]]; then continue; fi
        if [ "$method" = relaxed ] && [[ "$name" == water* || "$name" == calm* ]]; then continue; fi
        count="$frames"
        if [ "$backend" = device ]; then count="$device_frames"; fi
        # shellcheck disable=SC2206
        args=($scene --method "$method" --map-size "$size" --size "${size}x$size" --frames "$count" --warm-up 3
              --budget-ms 0 --serial)
        if [ "$backend" = device ]; then args+=(--backend device); fi
        for round in $(seq "$rounds"); do
          echo "compare: $name $method $size $backend, round $round" >&2
          echo "$name $method $size $backend old $(run_one "$old" "$old_help" "$scratch/o.json" "${args[@]}")" >>"$rows"
          echo "$name $method $size $backend new $(run_one "$new" "$new_help" "$scratch/n.json" "${args[@]}")" >>"$rows"
        done
      done
    done
  done
done

table="$(python3 - "$rows" "$short" "$(git -C "$root" rev-parse --short HEAD)" <<'EOF'
import statistics, sys
rows, old_name, new_name = sys.argv[1], sys.argv[2], sys.argv[3]
runs, order = {}, []
for line in open(rows):
    view, method, size, backend, build, *values = line.split()
    key = (view, method, size, backend)
    if key not in runs:
        runs[key] = {"old": [], "new": []}
        order.append(key)
    runs[key][build].append(values)
def median(samples, stage):
    values = [float(s[stage]) for s in samples if s[stage] != "-"]
    return statistics.median(values) if values else None
stages = ("sim", "bake", "render", "frame")
head = "| view | method | size | backend | " + " | ".join(
    f"{s} {old_name} | {s} {new_name}+ | ratio" for s in stages) + " |"
print(f"p50 ms, median of each build's runs; ratio = {new_name}+ (this tree) / {old_name}")
print()
print(head)
print("|" + "---|" * (4 + 3 * len(stages)))
for key in order:
    cells = list(key)
    for index, _ in enumerate(stages):
        a, b = median(runs[key]["old"], index), median(runs[key]["new"], index)
        cells += [f"{a:.2f}" if a is not None else "-", f"{b:.2f}" if b is not None else "-",
                  f"{b / a:.2f}" if a is not None and b is not None and min(a, b) >= 0.05 else "-"]
    print("| " + " | ".join(cells) + " |")
EOF
)"
echo "$table"
if [ -n "$output" ]; then printf '%s\n' "$table" >"$output"; fi
