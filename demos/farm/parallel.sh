#!/usr/bin/env bash
# Render a frame range on every core of this machine (or, with --sshloginfile, of several machines)
# with GNU parallel, one `displace sequence --shard I/N` per job. Frames are deterministic, so the
# shards together give exactly the files of one run; a job log makes the run resumable:
#   demos/farm/parallel.sh SHARDS FRAMES OUTPUT [displace sequence flags...]
#   demos/farm/parallel.sh 4 0:239 out/water_####.png --scene water --map-size 256
# Re-running the same command after an interruption re-runs only the shards that did not finish
# (--resume on the job log), and each shard skips the frames it already wrote (--resume).
set -euo pipefail
if [ $# -lt 3 ]; then
  echo "usage: $0 SHARDS FRAMES OUTPUT [displace sequence flags...]" >&2
  exit 2
fi
shards="$1"; frames="$2"; output="$3"; shift 3
displace="${DISPLACE:-$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)/build/displace}"
joblog="${JOBLOG:-$(dirname "$output")/parallel.joblog}"
mkdir -p "$(dirname "$output")"
seq 1 "$shards" | parallel --will-cite --joblog "$joblog" --resume --halt now,fail=1 \
  "$displace" sequence --frames "$frames" --output "$output" --shard "{}/$shards" --resume "$@"
