#!/usr/bin/env bash
# tests/scripts/setup_lib_test.sh - the checks of cmake/setup_lib.sh, each run many times under
# `set -euo pipefail` as setup.sh runs them: a check that can race (issue 29: `ldd | grep -q` failed
# 4 times in 10) fails here.
#
# usage: tests/scripts/setup_lib_test.sh PROGRAM [ROUNDS (default 200)]
#   PROGRAM: a dynamically linked program of the build (its libtbb is the library looked for)
set -euo pipefail
program="${1:?usage: setup_lib_test.sh PROGRAM [ROUNDS]}"
rounds="${2:-200}"
source "$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)/cmake/setup_lib.sh"

fail() {
  echo "setup_lib_test: FAILED: $*" >&2
  exit 1
}

# the directory the loader resolves libtbb to, read once without the function under test
tbb_path="$(ldd "$program" | awk '$1 ~ /^libtbb\.so/ {print $3}')"
[ -n "$tbb_path" ] || fail "$program loads no libtbb"
tbb_prefix="$(dirname "$tbb_path")/libtbb"

for ((round = 0; round < rounds; ++round)); do
  loads_library "$program" "$tbb_prefix" || fail "loads_library missed $tbb_prefix in round $round"
  if loads_library "$program" "/nonexistent/displace/libtbb"; then
    fail "loads_library found a library that is not loaded (round $round)"
  fi
  package_installed bash || fail "package_installed says bash is not installed (round $round)"
  if package_installed displace-no-such-package; then
    fail "package_installed says a missing package is installed (round $round)"
  fi
done

# the deb-src entries mirror the configured deb entries, one for one
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
derive_source_entries "$work/sources.list" "$work/parts"
count_matching() { # PATTERN FILE...: lines matching PATTERN in the files (0 when there are none)
  local pattern="$1" total=0 file n
  shift
  for file in "$@"; do
    [ -f "$file" ] || continue
    n="$(grep -cE "$pattern" "$file" || true)"
    total=$((total + n))
  done
  echo "$total"
}
deb_lines="$(count_matching '^[[:space:]]*deb[[:space:]]' /etc/apt/sources.list /etc/apt/sources.list.d/*.list)"
src_lines="$(count_matching '^deb-src ' "$work/sources.list")"
[ "$deb_lines" -eq "$src_lines" ] || fail "$deb_lines one-line deb entries but $src_lines deb-src entries"
deb_stanzas="$(count_matching '^Types:.*\bdeb\b' /etc/apt/sources.list.d/*.sources)"
src_stanzas="$(count_matching '^Types: deb-src$' "$work"/parts/*.sources)"
[ "$deb_stanzas" -eq "$src_stanzas" ] || fail "$deb_stanzas deb822 deb stanzas but $src_stanzas deb-src stanzas"
[ $((src_lines + src_stanzas)) -gt 0 ] || fail "no deb entry configured for apt"

echo "setup_lib_test: $rounds rounds of each check agreed; $src_lines + $src_stanzas deb-src entries derived"
