#!/usr/bin/env bash
# tests/scripts/format_check.sh - fails when a C++ file of the tree (every tracked *.cpp and *.h)
# differs from what Debian's clang-format makes of it under the root's .clang-format; lists them.
# Mend with `cmake --build build --target format` (or clang-format -i FILE).
#
# usage: tests/scripts/format_check.sh [ROOT (default: the repository)]
set -euo pipefail
root="${1:-$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)}"
cd "$root"
command -v clang-format >/dev/null || { echo "format_check: clang-format is not installed (Debian package clang-format)" >&2; exit 1; }

files=()
while IFS= read -r -d '' file; do
  files+=("$file")
done < <(git ls-files -z -- '*.cpp' '*.h')

differing=()
for file in "${files[@]}"; do
  if ! clang-format --dry-run --Werror "$file" >/dev/null 2>&1; then
    differing+=("$file")
  fi
done
if [ ${#differing[@]} -gt 0 ]; then
  printf '  %s\n' "${differing[@]}" >&2
  echo "format_check: ${#differing[@]} of ${#files[@]} files differ from clang-format ($(clang-format --version)); run: cmake --build build --target format" >&2
  exit 1
fi
echo "format_check: ${#files[@]} files as clang-format writes them"
