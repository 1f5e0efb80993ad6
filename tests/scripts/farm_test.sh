#!/usr/bin/env bash
# The farm recipes on real schedulers, killed and run again (issue 47):
#   tests/scripts/farm_test.sh slurm DISPLACE SOURCE_DIR     # a one-node Slurm cluster (skips: exit 77)
#   tests/scripts/farm_test.sh parallel DISPLACE SOURCE_DIR  # GNU parallel (demos/farm/parallel.sh)
# slurm: starts munged, slurmctld and slurmd from Debian's packages as root without systemd (keys,
# sockets, state and logs in a temporary directory; the node line from `slurmd -C`, 127.0.0.1,
# proctrack/linuxproc, task/none, no accounting), runs demos/farm/slurm.sbatch as an array of 3 and
# compares the frames byte for byte with one `displace sequence` run; then runs it again, requeues
# one array task mid-run (scontrol requeue: the task is killed and runs again, --resume keeping its
# whole frames) and compares again; stops the daemons by their pids.
# parallel: runs the recipe, kills it mid-run (SIGTERM to its process group), runs the same command
# again and compares.
set -euo pipefail
mode="${1:?mode: slurm or parallel}"
displace="$(realpath "${2:?the displace binary}")"
source_dir="$(realpath "${3:?the source directory}")"
work="$(mktemp -d "${TMPDIR:-/tmp}/displace-farm.XXXXXX")"
chmod 755 "$work"
daemons=()
cleanup() {
  local pid
  for pid in "${daemons[@]}"; do kill "$pid" 2>/dev/null || true; done
  for pid in "${daemons[@]}"; do
    local waited=0
    while kill -0 "$pid" 2>/dev/null && [ "$waited" -lt 50 ]; do sleep 0.1; waited=$((waited + 1)); done
    kill -9 "$pid" 2>/dev/null || true
  done
  rm -rf "$work"
}
trap cleanup EXIT

fail() {
  echo "farm ($mode): $*" >&2
  for log in "$work"/*.log "$work"/logs/*; do
    [ -f "$log" ] && { echo "--- $log" >&2; tail -n 20 "$log" >&2; }
  done
  exit 1
}

frames=0:23
flags=(--scene water --map-size 64 --size 320x180 --pipeline-cache off)

# every frame of the clean run is in DIR, byte for byte
same_as_clean() {
  local dir="$1" file count=0
  for file in "$work/clean"/*.png; do
    cmp -s "$file" "$dir/$(basename "$file")" || fail "$dir/$(basename "$file") is not the clean run's"
    count=$((count + 1))
  done
  [ -z "$(find "$dir" -name '.*.partial-*')" ] || fail "temporaries left in $dir"
  echo "$count"
}

# waits up to $2 tenths of a second for the file $1
wait_for() {
  local waited=0
  until [ -e "$1" ]; do
    [ "$waited" -lt "$2" ] || return 1
    sleep 0.1
    waited=$((waited + 1))
  done
}

slurm() {
  if [ "$(id -u)" -ne 0 ]; then
    echo "farm/slurm: skipped: not root (the test starts Slurm's daemons as root)"
    exit 77
  fi
  local program
  for program in munged slurmctld slurmd sbatch squeue scontrol; do
    if ! command -v "$program" >/dev/null; then
      echo "farm/slurm: skipped: no $program (Debian's munge, slurmctld, slurmd and slurm-client: cmake/setup.sh installs them)"
      exit 77
    fi
  done
  mkdir -p "$work/clean"
  "$displace" sequence "${flags[@]}" --frames "$frames" --output "$work/clean/w_####.png" >/dev/null 2>&1

  # munge: its key, socket and state here (munged refuses a key others can read)
  local munge="$work/munge"
  mkdir -p "$munge"
  chmod 700 "$munge"
  head -c 1024 /dev/urandom >"$munge/munge.key"
  chmod 400 "$munge/munge.key"
  munged --force --key-file="$munge/munge.key" --socket="$munge/munge.socket" --pid-file="$munge/munged.pid" \
    --log-file="$work/munged.log" --seed-file="$munge/munged.seed" --foreground >"$work/munged.out" 2>&1 &
  daemons+=($!)
  wait_for "$munge/munge.socket" 100 || fail "munged did not come up"

  # two free ports for the daemons, a configuration with this machine as the one node
  local ports
  ports="$(python3 -c 'import socket
s = [socket.socket() for _ in range(2)]
for x in s: x.bind(("127.0.0.1", 0))
print(" ".join(str(x.getsockname()[1]) for x in s))')"
  local node hostname
  hostname="$(hostname -s)"
  node="$(slurmd -C | grep '^NodeName=')"
  node="${node/NodeName=$hostname/NodeName=$hostname NodeAddr=127.0.0.1}"
  mkdir -p "$work/state" "$work/spool" "$work/logs"
  export SLURM_CONF="$work/slurm.conf"
  cat >"$SLURM_CONF" <<EOF
ClusterName=displace-test
SlurmctldHost=$hostname(127.0.0.1)
SlurmctldPort=${ports% *}
SlurmdPort=${ports#* }
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$munge/munge.socket
CredType=cred/munge
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/slurmctld.log
SlurmdLogFile=$work/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
JobRequeue=1
MpiDefault=none
KillWait=10
$node
PartitionName=test Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF
  slurmctld -D -i -f "$SLURM_CONF" >"$work/slurmctld.out" 2>&1 &
  daemons+=($!)
  slurmd -D -f "$SLURM_CONF" >"$work/slurmd.out" 2>&1 &
  daemons+=($!)
  local waited=0
  local state=""
  until [[ "$state" =~ ^(idle|mixed) ]]; do
    state="$(sinfo -h -o '%T' 2>/dev/null || true)"
    [ "$waited" -lt 300 ] || fail "the node did not come up: $(sinfo 2>&1)"
    sleep 0.1
    waited=$((waited + 1))
  done

  echo "  a one-node cluster up in $SECONDS s"
  # the recipe as an array of 3 (one CPU a task here: the node has few)
  local job
  job="$(FRAMES="$frames" OUTPUT="$work/farm/w_####.png" DISPLACE="$displace" \
    sbatch --parsable --array=1-3 --cpus-per-task=1 --chdir="$work" --output="$work/logs/%A_%a.txt" \
    "$source_dir/demos/farm/slurm.sbatch" "${flags[@]}")"
  mkdir -p "$work/farm"
  wait_job "$job"
  [ "$(same_as_clean "$work/farm")" -eq 24 ] || fail "the array did not give the clean frames"
  echo "  array of 3: the 24 frames of one sequence run, byte for byte"

  # again, with task 2 requeued while it writes
  job="$(FRAMES="$frames" OUTPUT="$work/requeued/w_####.png" DISPLACE="$displace" \
    sbatch --parsable --array=1-3 --cpus-per-task=1 --requeue --chdir="$work" \
    --output="$work/logs/%A_%a-requeued.txt" "$source_dir/demos/farm/slurm.sbatch" "${flags[@]}")"
  mkdir -p "$work/requeued"
  # shard 2 of 3 renders frames 1, 4, 7, ...: requeue it once its second frame is there
  wait_for "$work/requeued/w_0004.png" 1200 || fail "task 2 wrote no frame"
  scontrol requeue "${job}_2" || fail "scontrol requeue ${job}_2 failed"
  # Slurm makes a requeued batch job eligible again 121 s after it left the node; here 2 s after it
  # went back to the queue: slurmd refuses ("Job credential revoked") a launch whose credential was
  # made in the same second as the revocation of the killed one (seen once with StartTime=now)
  local state="" waited=0
  until [[ "$state" == *JobState=PENDING* ]]; do
    [ "$waited" -lt 300 ] || fail "task 2 did not go back to the queue: $state"
    sleep 0.1
    waited=$((waited + 1))
    state="$(scontrol show job "${job}_2" 2>/dev/null || true)"
  done
  scontrol update JobId="${job}_2" StartTime=now+2 || fail "scontrol update ${job}_2 StartTime=now+2 failed"
  wait_job "$job"
  local restarts
  restarts="$(scontrol show job "${job}_2" 2>/dev/null | grep -o 'Restarts=[0-9]*' || true)"
  [ "$restarts" = "Restarts=1" ] || fail "task 2 was not requeued ($restarts)"
  [ "$(same_as_clean "$work/requeued")" -eq 24 ] || fail "the requeued array did not give the clean frames"
  echo "  array of 3 with task 2 killed and requeued mid-run: the same 24 frames"
}

# waits for every task of job $1 to leave the queue (10 minutes at most)
wait_job() {
  local waited=0
  while [ -n "$(squeue -h -j "$1" 2>/dev/null)" ]; do
    [ "$waited" -lt 6000 ] || fail "job $1 did not finish: $(squeue -j "$1")"
    sleep 0.1
    waited=$((waited + 1))
  done
}

parallel_recipe() {
  if ! command -v parallel >/dev/null; then
    echo "farm/parallel: skipped: no GNU parallel (cmake/setup.sh installs it)"
    exit 77
  fi
  mkdir -p "$work/clean"
  "$displace" sequence "${flags[@]}" --frames "$frames" --output "$work/clean/w_####.png" >/dev/null 2>&1
  local recipe=("$source_dir/demos/farm/parallel.sh" 3 "$frames" "$work/farm/w_####.png" "${flags[@]}")
  # in a process group of its own, so that the signal reaches parallel and its jobs as a farm's would
  DISPLACE="$displace" setsid bash "${recipe[@]}" >"$work/parallel.log" 2>&1 &
  local group=$!
  wait_for "$work/farm/w_0004.png" 1200 || fail "the recipe wrote no frame"
  kill -TERM -- "-$group"
  local status=0
  wait "$group" || status=$?
  [ "$status" -ne 0 ] || fail "the recipe finished before it was killed"
  local kept
  kept="$(find "$work/farm" -name 'w_*.png' | wc -l)"
  DISPLACE="$displace" bash "${recipe[@]}" >>"$work/parallel.log" 2>&1 || fail "the rerun failed"
  [ "$(same_as_clean "$work/farm")" -eq 24 ] || fail "the rerun did not give the clean frames"
  [ -s "$work/farm/parallel.joblog" ] || fail "the recipe kept no job log (its --resume needs one)"
  echo "  killed with $kept frames written (exit $status), run again: the 24 frames of one sequence run"
}

case "$mode" in
  slurm) slurm ;;
  parallel) parallel_recipe ;;
  *) fail "unknown mode '$mode'" ;;
esac
echo "farm ($mode): passed"
