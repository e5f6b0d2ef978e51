#!/usr/bin/env bash
# A real one-node Slurm cluster on this machine (Debian's slurm-wlm and munge), started and
# stopped by this script, runs scripts/slurm/submit.sh on a generated world in 4 shards,
# once writing to another directory with every shard at once and once in place with one
# shard at a time; the merged results and every chunk file must equal a single-process
# bake's, byte for byte.
#
#   tests/cluster/slurm_test.sh [BUILD_BIN_DIR]     (default: build/bin; run as root)
#
# Everything lives in a temporary directory (munge key and socket, slurm.conf, state and
# spool, logs, the world and the bakes) and on random ports; on any exit the jobs are
# cancelled, the daemons stopped, every process that carries this run's marker variable
# killed (by pid), and the directory removed. Skipped (exit 0, with the reason) only where
# the packages cannot be installed.
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
bin="$(realpath "${1:-$root/build/bin}")"

skip() { echo "SKIPPED: Slurm cluster test: $*"; exit 0; }
need=(munged slurmctld slurmd sbatch squeue scontrol sinfo)
have_all() { for t in "${need[@]}"; do PATH="$PATH:/usr/sbin" command -v "$t" >/dev/null || return 1; done; }
if ! have_all; then
  if [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null; then
    echo "installing slurm-wlm and munge"
    { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends slurm-wlm munge; } \
      || skip "slurm-wlm and munge could not be installed"
  fi
  have_all || skip "slurm-wlm and munge are not installed and cannot be (not root, or no apt-get)"
fi
[ "$(id -u)" -eq 0 ] || skip "the daemons run as root (SlurmUser=root); run as root"
export PATH="$PATH:/usr/sbin"
for exe in shadowcull bake_bench; do [ -x "$bin/$exe" ] || { echo "FAIL: no $bin/$exe (build first)"; exit 1; }; done

tmp="$(mktemp -d /tmp/shadowcull-slurm-test.XXXXXX)"
chmod 755 "$tmp"
# Every process of this run (daemons, job steps, bakes) inherits this marker: the cleanup
# kills exactly those, by pid.
export SHADOWCULL_CLUSTER_TEST="$tmp"
pids=()
cleanup() {
  local rc=$?
  set +e
  if [ -f "$tmp/slurm.conf" ]; then
    SLURM_CONF="$tmp/slurm.conf" timeout 10 scancel --quiet --user=root 2>/dev/null
    # Let the job steps end while the daemons (and munge) can still hear them.
    for _ in $(seq 1 40); do
      [ -z "$(SLURM_CONF="$tmp/slurm.conf" timeout 5 squeue -h 2>/dev/null)" ] && break
      sleep 0.25
    done
  fi
  for p in "${pids[@]}"; do kill -TERM "$p" 2>/dev/null; done
  for _ in $(seq 1 50); do
    alive=0
    for p in "${pids[@]}"; do kill -0 "$p" 2>/dev/null && alive=1; done
    [ "$alive" -eq 0 ] && break
    sleep 0.1
  done
  for p in "${pids[@]}"; do kill -KILL "$p" 2>/dev/null; done
  # Job steps and bakes that outlived the daemons: ours only, by pid: a process working in
  # this run's directory (the daemons were started there, so their job steps are too), or
  # one that carries the marker (slurmstepd rewrites its environment, the bakes do not).
  local strays
  strays="$(find /proc -mindepth 2 -maxdepth 2 -name cwd -lname "$tmp*" 2>/dev/null | cut -d/ -f3)
$(grep -lzxF "SHADOWCULL_CLUSTER_TEST=$tmp" /proc/[0-9]*/environ 2>/dev/null | cut -d/ -f3)"
  for p in $strays; do
    [ "$p" = "$$" ] && continue
    [ "$(ps -o ppid= -p "$p" 2>/dev/null | tr -d ' ')" = "$$" ] && continue  # this script's own subshells
    kill -KILL "$p" 2>/dev/null
  done
  if [ "$rc" -ne 0 ]; then
    echo "--- logs of the failed run ---"
    for f in "$tmp"/log/*.log "$tmp"/farm/logs/*.log; do [ -f "$f" ] && { echo "== $f"; tail -n 30 "$f"; }; done
  fi
  rm -rf "$tmp"
  exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

mkdir -p "$tmp/munge" "$tmp/state" "$tmp/spool" "$tmp/log"
chmod 700 "$tmp/munge"

# 1. munge, on its own socket and key.
dd if=/dev/urandom of="$tmp/munge/munge.key" bs=1024 count=1 status=none
chmod 400 "$tmp/munge/munge.key"
cd "$tmp"
munged --foreground --force --socket="$tmp/munge/munge.socket" --key-file="$tmp/munge/munge.key" \
  --pid-file="$tmp/munge/munged.pid" --log-file="$tmp/log/munged.log" --seed-file="$tmp/munge/munged.seed" \
  > "$tmp/log/munged.out" 2>&1 &
pids+=($!)
cd "$root"
for _ in $(seq 1 100); do [ -S "$tmp/munge/munge.socket" ] && break; sleep 0.1; done
[ -S "$tmp/munge/munge.socket" ] || { echo "FAIL: munged did not start"; exit 1; }

# 2. slurm.conf: one node with 2 CPUs, no accounting, no cgroups, random ports.
port=$((20000 + RANDOM % 20000))
host="$(hostname -s)"
cat > "$tmp/slurm.conf" <<CONF
ClusterName=shadowcull-test
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$port
SlurmdPort=$((port + 1))
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$tmp/munge/munge.socket
StateSaveLocation=$tmp/state
SlurmdSpoolDir=$tmp/spool
SlurmctldPidFile=$tmp/slurmctld.pid
SlurmdPidFile=$tmp/slurmd.pid
SlurmctldLogFile=$tmp/log/slurmctld.log
SlurmdLogFile=$tmp/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SwitchType=switch/none
MpiDefault=none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/backfill
ReturnToService=2
MinJobAge=600
MailProg=/bin/true
NodeName=shadowcull-node NodeHostname=$host NodeAddr=127.0.0.1 CPUs=2 State=UNKNOWN
PartitionName=bake Nodes=shadowcull-node Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF="$tmp/slurm.conf"

# 3. The daemons, in the foreground (so that their pids are ours to stop).
# Started in $tmp, so that every job step they fork works there (the cleanup finds them).
cd "$tmp"
slurmctld -D -c -i -f "$SLURM_CONF" > "$tmp/log/slurmctld.out" 2>&1 &
pids+=($!)
slurmd -D -N shadowcull-node -f "$SLURM_CONF" > "$tmp/log/slurmd.out" 2>&1 &
pids+=($!)
cd "$root"
state=""
for _ in $(seq 1 120); do
  state="$(sinfo -h -N -o %T 2>/dev/null | head -n 1 || true)"
  [ "$state" = "idle" ] && break
  sleep 0.5
done
[ "$state" = "idle" ] || { echo "FAIL: the node did not come up (state '$state')"; exit 1; }
echo "slurm up: node shadowcull-node idle (port $port)"

# 4. A generated world (benchmark world S: 3 x 3 chunks, terrain, trees, buildings, 23
# lights) and a single-process bake of it: the reference.
"$bin/bake_bench" --sizes S --gen-only --work "$tmp/gen" > "$tmp/log/gen.log" 2>&1
space="$(find "$tmp/gen" -maxdepth 1 -type d -name 'world-*' | head -n 1)"
[ -f "$space/space.xml" ] || { echo "FAIL: no world generated"; cat "$tmp/log/gen.log"; exit 1; }
bake_args="--stages raycast,geometry --samples 16"
# shellcheck disable=SC2086
"$bin/shadowcull" bake "$space" --out "$tmp/whole" --results "$tmp/whole.json" --quiet $bake_args --threads 2
echo "single-process bake done: $(ls "$tmp/whole" | grep -c '\.chunk$') chunk files"

# 5. The farm: the plan, 4 shards and the merge, through submit.sh.
out="$(SHADOWCULL="$bin/shadowcull" SHADOWCULL_OUT="$tmp/sharded" SHADOWCULL_BAKE_ARGS="$bake_args" \
  "$root/scripts/slurm/submit.sh" "$space" 4 "$tmp/farm")"
echo "$out"
bake_id="$(echo "$out" | sed -n 's/^bake array: \([0-9]*\).*/\1/p')"
merge_id="$(echo "$out" | sed -n 's/^merge: \([0-9]*\).*/\1/p')"
[ -n "$bake_id" ] && [ -n "$merge_id" ] || { echo "FAIL: submit.sh printed no job ids"; exit 1; }
job_state() { scontrol show job "$1" 2>/dev/null | sed -n 's/.*JobState=\([A-Z_]*\).*/\1/p' | head -n 1; }
merge_state=""
for _ in $(seq 1 1200); do  # 10 minutes at most: a stuck cluster fails the test, not CI
  merge_state="$(job_state "$merge_id")"
  case "$merge_state" in COMPLETED|FAILED|CANCELLED|TIMEOUT|NODE_FAIL|OUT_OF_MEMORY|DEADLINE) break ;; esac
  sleep 0.5
done
echo "merge job $merge_id: $merge_state"
[ "$merge_state" = "COMPLETED" ] || { echo "FAIL: the merge job ended $merge_state"; exit 1; }
shards_done="$(scontrol show job "$bake_id" | grep -c 'JobState=COMPLETED' || true)"
[ "$shards_done" -eq 4 ] || { echo "FAIL: $shards_done of 4 array tasks completed"; exit 1; }
# The shards read the plan the plan job wrote, not the whole space.
[ -f "$tmp/farm/plan/plan.json" ] && [ -f "$tmp/farm/plan/shard-4-of-4.json" ] || { echo "FAIL: no plan in $tmp/farm/plan"; exit 1; }
grep -q -- "--plan $tmp/farm/plan" "$tmp"/farm/logs/bake-*_1.log || { echo "FAIL: shard 1 did not bake from the plan"; cat "$tmp"/farm/logs/bake-*_1.log; exit 1; }

# 6. Byte for byte.
cmp "$tmp/whole.json" "$tmp/farm/results.json" || { echo "FAIL: merged results differ from the single bake's"; exit 1; }
n=0
for f in "$tmp"/whole/*.chunk; do
  cmp "$f" "$tmp/sharded/$(basename "$f")" || { echo "FAIL: $(basename "$f") differs"; exit 1; }
  n=$((n + 1))
done
[ "$n" -eq "$(ls "$tmp/sharded" | grep -c '\.chunk$')" ] || { echo "FAIL: the farm wrote other chunk files"; exit 1; }
[ "$n" -gt 0 ] || { echo "FAIL: no chunk files"; exit 1; }
echo "PASS: Slurm farm (4 shards + merge) equals the single-process bake: results.json and $n chunk files byte for byte"

# 7. In place, one shard at a time (the array throttled to one task: each later shard reads
# chunk files the earlier ones wrote masks into), then the merge: still one bake. The
# reference reads the same space directory, since the results name it.
inplace="$tmp/inplace"
cp -r "$space" "$inplace"
# shellcheck disable=SC2086
"$bin/shadowcull" bake "$inplace" --out "$tmp/whole-inplace" --results "$tmp/whole-inplace.json" --quiet $bake_args --threads 2
out="$(SHADOWCULL="$bin/shadowcull" SHADOWCULL_MAX_RUNNING=1 SHADOWCULL_BAKE_ARGS="$bake_args" \
  "$root/scripts/slurm/submit.sh" "$inplace" 4 "$tmp/farm-inplace")"
echo "$out"
bake_id="$(echo "$out" | sed -n 's/^bake array: \([0-9]*\).*/\1/p')"
merge_id="$(echo "$out" | sed -n 's/^merge: \([0-9]*\).*/\1/p')"
[ -n "$bake_id" ] && [ -n "$merge_id" ] || { echo "FAIL: submit.sh printed no job ids"; exit 1; }
scontrol show job "$bake_id" | grep -q 'ArrayTaskThrottle=1' || { echo "FAIL: the array is not throttled to one task"; exit 1; }
for _ in $(seq 1 1200); do
  merge_state="$(job_state "$merge_id")"
  case "$merge_state" in COMPLETED|FAILED|CANCELLED|TIMEOUT|NODE_FAIL|OUT_OF_MEMORY|DEADLINE) break ;; esac
  sleep 0.5
done
echo "in-place merge job $merge_id: $merge_state"
[ "$merge_state" = "COMPLETED" ] || { echo "FAIL: the in-place merge job ended $merge_state"; cat "$tmp"/farm-inplace/logs/merge-*.log; exit 1; }
cmp "$tmp/whole-inplace.json" "$tmp/farm-inplace/results.json" || { echo "FAIL: in-place merged results differ from the single bake's"; exit 1; }
n=0
for f in "$tmp"/whole-inplace/*.chunk; do
  cmp "$f" "$inplace/$(basename "$f")" || { echo "FAIL: in place, $(basename "$f") differs"; exit 1; }
  n=$((n + 1))
done
[ "$n" -gt 0 ] || { echo "FAIL: no chunk files"; exit 1; }
echo "PASS: in place, one shard at a time, then merged: results.json and $n chunk files equal the single bake's"
