#!/usr/bin/env bash
# tests/scripts/lint_scripts.sh - fails when a script in the tree pipes a command into a reader that
# may stop early (`grep -q`, `grep -m`, `head`, `sed ...q`): under `set -o pipefail` the writer is
# then killed by SIGPIPE at random and the pipeline fails although the match was found (issue 29:
# `ldd | grep -q` failed CI 4 times in 10). Capture the output first, then match it.
#
# usage: tests/scripts/lint_scripts.sh [ROOT (default: the repository)]
set -euo pipefail
root="${1:-$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)}"

# a pipe into grep with -q or -m among its options, into head, or into sed with a q command
early_reader='\|[[:space:]]*(grep([[:space:]]+-[[:alnum:]-]+)*[[:space:]]+-[[:alpha:]]*[qm]|head([[:space:]]|$)|sed[[:space:]][^|]*[;{'"'"'"][[:space:]]*q)'

scripts=()
while IFS= read -r -d '' file; do
  scripts+=("$file")
done < <(find "$root" \( -path "$root/build*" -o -path "$root/.git" -o -path "$root/out" \) -prune -o \
           -type f \( -name '*.sh' -o -name '*.sbatch' -o -name 'CMakeLists.txt' -o -name '*.cmake' -o -path "$root/.ci/*" \) \
           -print0)

found=0
for file in "${scripts[@]}"; do
  # comments are not code
  if hits="$(grep -nE "$early_reader" "$file" | grep -vE '^[0-9]+:[[:space:]]*#')"; then
    echo "$hits" | sed "s|^|${file#"$root"/}:|" >&2
    found=1
  fi
done
if [ "$found" -ne 0 ]; then
  echo "lint_scripts: a pipe into a reader that may stop early (see above); capture the output, then match it" >&2
  exit 1
fi
echo "lint_scripts: ${#scripts[@]} scripts, no pipe into an early-exiting reader"
