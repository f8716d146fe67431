#!/bin/bash
# A real one-node Slurm cluster renders a still as an array job of sample chunks with farm/slurm/submit.sh,
# merges it, and the merged EXR and PNG must equal a single-process render byte for byte.
#
#   tests/farm/slurm_test.sh [NIMBUS_BINARY]      (default: $CARGO_TARGET_DIR or target, then debug/nimbus)
#
# It starts munged, slurmctld and slurmd on this machine with a generated configuration in a temporary
# folder (no cgroups: proctrack/linuxproc, task/none), and stops them when it ends. It installs nothing:
# without Debian's slurm-wlm and munge it skips with a message, unless NIMBUS_REQUIRE_SLURM=1 (as .ci/run
# sets), when a missing package or a cluster that does not start fails it.
set -euo pipefail
# Reproducible headers (a fixed capDate, no render time), so that merged and single renders compare byte for
# byte: the pixels always do, and with this the whole files do.
export SOURCE_DATE_EPOCH=0
# The daemons live in sbin, which a plain user's PATH may lack.
PATH=$PATH:/usr/sbin:/sbin

repo=$(cd "$(dirname "$0")/../.." && pwd)
nimbus=${1:-${CARGO_TARGET_DIR:-$repo/target}/debug/nimbus}
require=${NIMBUS_REQUIRE_SLURM:-0}
chunks=4
flags=(--width 64 --height 48 --spp 16 --seed 7)

skip() {
    if [ "$require" = 1 ]; then
        echo "slurm test: FAILED: $* (NIMBUS_REQUIRE_SLURM=1)" >&2
        exit 1
    fi
    echo "slurm test: SKIP: $*"
    exit 0
}

for tool in munged slurmctld slurmd sbatch scontrol sinfo; do
    command -v "$tool" >/dev/null || skip "$tool not found (apt-get install slurm-wlm munge)"
done
[ -x "$nimbus" ] || { echo "slurm test: FAILED: no nimbus binary at $nimbus (cargo build first)" >&2; exit 1; }
nimbus=$(cd "$(dirname "$nimbus")" && pwd)/$(basename "$nimbus")

start=$(date +%s)
dir=$(mktemp -d /tmp/nimbus-slurm.XXXXXX)
chmod 755 "$dir"
pids=()
cleanup() {
    status=$?
    # Stop only the daemons this script started: Slurm's by its own shutdown, then any left, newest first.
    if [ -n "${SLURM_CONF:-}" ]; then
        timeout 10 scontrol shutdown >/dev/null 2>&1 || true
        for _ in $(seq 50); do
            alive=0
            for pid in "${pids[@]:1}"; do kill -0 "$pid" 2>/dev/null && alive=1; done
            [ "$alive" = 0 ] && break
            sleep 0.2
        done
    fi
    for ((i = ${#pids[@]} - 1; i >= 0; i--)); do
        kill "${pids[i]}" 2>/dev/null || true
    done
    for pid in "${pids[@]}"; do
        wait "$pid" 2>/dev/null || true
    done
    if [ "$status" -ne 0 ]; then
        for log in "$dir"/*.log "$dir"/*.out "$dir"/out/logs/*.log; do
            [ -f "$log" ] && { echo "--- $log"; tail -n 30 "$log"; }
        done >&2
    fi
    rm -rf "$dir"
}
trap cleanup EXIT

fail_start() {
    skip "the one-node cluster did not start: $*"
}

# munge: a fresh key and a private socket, so the machine's own munge (if any) is left alone.
mkdir -p "$dir/munge" "$dir/state" "$dir/spool"
head -c 1024 /dev/urandom >"$dir/munge/munge.key"
chmod 400 "$dir/munge/munge.key"
socket=$dir/munge/munge.socket
munged --foreground --force --key-file="$dir/munge/munge.key" --socket="$socket" \
    --pid-file="$dir/munge/munged.pid" --seed-file="$dir/munge/munged.seed" \
    --log-file="$dir/munged.log" >"$dir/munged.out" 2>&1 &
pids+=($!)

# Ports from a range the machine is unlikely to use, picked from this shell's pid.
port=$((20000 + ($$ % 20000)))
host=$(hostname -s)
user=$(id -un)
node=$(slurmd -C 2>/dev/null | head -n 1 | sed 's/ RealMemory=[0-9]*//')
[[ $node == NodeName=* ]] || node="NodeName=$host CPUs=$(nproc)"
export SLURM_CONF=$dir/slurm.conf
cat >"$SLURM_CONF" <<EOF
ClusterName=nimbus-test
SlurmctldHost=$host(127.0.0.1)
SlurmUser=$user
SlurmdUser=$user
AuthType=auth/munge
AuthInfo=socket=$socket
CredType=cred/munge
SlurmctldPort=$port
SlurmdPort=$((port + 1))
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
MpiDefault=none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MinJobAge=600
$node NodeAddr=127.0.0.1 State=UNKNOWN
PartitionName=nimbus Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF

for _ in $(seq 50); do
    [ -S "$socket" ] && break
    sleep 0.1
done
[ -S "$socket" ] || fail_start "munged made no socket"
slurmctld -D -c -f "$SLURM_CONF" >"$dir/slurmctld.out" 2>&1 &
pids+=($!)
slurmd -D -f "$SLURM_CONF" >"$dir/slurmd.out" 2>&1 &
pids+=($!)

state=
for _ in $(seq 60); do
    state=$(sinfo -h -N -o %t 2>/dev/null | head -n 1 || true)
    [ "$state" = idle ] && break
    sleep 1
done
[ "$state" = idle ] || fail_start "the node is '${state:-unreachable}' after 60 s"
up=$(date +%s)
echo "slurm test: one-node cluster up in $((up - start)) s ($(sinfo -h -o '%D node, %c CPUs'))"

# The farm example itself submits the array and the merge.
out=$dir/out
ids=$(NIMBUS=$nimbus CPUS_PER_TASK=1 "$repo/farm/slurm/submit.sh" "$chunks" "$repo/assets/cloud.gltf" \
    "$out" "${flags[@]}")
echo "$ids" | sed 's/^/slurm test: /'
render_job=$(echo "$ids" | sed -n 's/^render array job: //p')
merge_job=$(echo "$ids" | sed -n 's/^merge job: //p')

job_state() {
    scontrol show job "$1" -o 2>/dev/null | tr ' ' '\n' | sed -n 's/^JobState=//p' | sort -u | tr '\n' ' '
}
for _ in $(seq 240); do
    merge_state=$(job_state "$merge_job")
    case $merge_state in
    *COMPLETED*) break ;;
    *FAILED* | *CANCELLED* | *TIMEOUT* | *NODE_FAIL* | *OUT_OF_MEMORY*)
        echo "slurm test: FAILED: merge job $merge_job is $merge_state; render array: $(job_state "$render_job")" >&2
        exit 1
        ;;
    esac
    sleep 1
done
[[ $merge_state == *COMPLETED* ]] || { echo "slurm test: FAILED: merge job still '$merge_state' after 240 s" >&2; exit 1; }
done_at=$(date +%s)
echo "slurm test: array job of $chunks chunks and merge finished in $((done_at - up)) s (render tasks: $(job_state "$render_job"))"
ls "$out/parts" | sed 's/^/slurm test:   part /'

"$nimbus" render "$repo/assets/cloud.gltf" "${flags[@]}" --threads 2 -o "$dir/single.exr" 2>"$dir/single.log"
for file in shot.exr:single.exr shot.png:single.png; do
    merged=$out/${file%%:*} single=$dir/${file##*:}
    if ! cmp "$merged" "$single"; then
        echo "slurm test: FAILED: the merged ${file%%:*} differs from the single-process render" >&2
        exit 1
    fi
done
echo "slurm test: merged EXR and PNG equal the single-process render byte for byte ($(stat -c %s "$out/shot.exr") bytes); $(($(date +%s) - start)) s in all"
# The closing line of a cargo test binary, so that .ci/run counts this test with the others.
echo "test result: ok. 1 passed; 0 failed; 0 ignored (slurm array job, merged bit for bit)"
